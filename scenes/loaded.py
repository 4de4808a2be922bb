"""The scene model's record: :class:`LoadedScene` (a loaded scene with its camera, chosen
light, frame and provenance) and :class:`SceneError`, the one-line error of every scene input.

:func:`scenes.loader.load` builds a :class:`LoadedScene`; its methods move it along camera,
light and object paths (:meth:`LoadedScene.with_frame`) without loading it again.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import backend
from .camera import Camera
from .light_paths import path_light
from .lights import Light
from .mitsuba_dict import to_mitsuba_dict
from .object_paths import object_transform
from .paths import path_camera
from .shading.phong import Specular

__all__ = ["LoadedScene", "SceneError"]


class SceneError(ValueError):
    """A scene that cannot be loaded or used (one clear line for the user)."""


@dataclass
class LoadedScene:
    """A loaded scene with its camera, chosen light and provenance.

    Attributes
    ----------
    mi_scene : the Mitsuba scene (loaded with the active variant, unoptimized).
    camera : the camera of the requested frame (float64, see :mod:`scenes.camera`).
    light : the chosen light; ``lights`` lists every usable light of the scene.
    shape_names : Mitsuba shape ids, index = the ``id`` channel value.
    content_hash : SHA-256 of the scene's content (XML and referenced files, or the built-in
        dictionary) plus the resolution.
    """

    name: str
    source: str
    description: str
    mi_scene: object
    camera: Camera
    base_camera: Camera
    lights: list[Light]
    light_index: int
    shape_names: list[str]
    content_hash: str
    specular: Specular = field(default_factory=Specular)
    camera_path: str | None = None
    frame: int = 0
    n_frames: int = 1
    light_path: str | None = None
    base_lights: list[Light] = field(default_factory=list)
    mesh_data: dict = field(default_factory=dict, repr=False)
    #: glTF materials (:class:`scenes.shading.materials.PbrMaterials`): the scene is
    #: shaded with the glTF BRDF of :mod:`scenes.shading.pbr`; None: the Lambert/Blinn-Phong
    #: of scenes.shading.phong.
    pbr: object = field(default=None, repr=False, compare=False)
    #: Alpha-tested shapes (glTF MASK, Mitsuba mask BSDFs):
    #: :class:`scenes.shading.alpha.AlphaTable`, or None when every shape is opaque. The
    #: intersection engine (:mod:`scenes.backend.alpha_hit`) cuts them out for every ray.
    alpha: object = field(default=None, repr=False, compare=False)
    #: Per-scene memo caches of derived data (shape tables, occluder triangles, tie groups),
    #: keyed by their owner's name. A declared field, so ``dataclasses.replace`` carries it:
    #: only data that depends on the scene's geometry (not its camera or light) belongs here.
    memo: dict = field(default_factory=dict, repr=False, compare=False)
    #: Object paths (:mod:`scenes.object_paths`): shape id -> spec; empty for a still scene.
    object_motion: dict = field(default_factory=dict, repr=False)
    #: A camera sequence from a file (``--camera-file``; frame k = entry k, frame -1 = entry
    #: 0) or None; its file is named in ``camera_file``.
    camera_sequence: tuple | None = field(default=None, repr=False)
    camera_file: str | None = None
    #: The built-in dictionary the moving shapes are rebuilt from, and the rebuilt Mitsuba
    #: scenes by frame (shared by every frame of this scene).
    scene_dict: dict | None = field(default=None, repr=False, compare=False)
    frame_scenes: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def default_camera_path(self) -> str:
        """The camera path frames follow when none is named: ``file`` for a camera file,
        ``static`` when objects move, else ``dolly``."""
        if self.camera_sequence is not None:
            return "file"
        return "static" if self.object_motion else "dolly"

    def shape_transform(self, name: str, frame: int | None = None) -> np.ndarray:
        """``(4, 4)`` transform of shape ``name`` at ``frame`` (default: this scene's frame)
        relative to frame 0; the identity for a shape that does not move."""
        spec = self.object_motion.get(name)
        if spec is None:
            return np.eye(4)
        return object_transform(spec, self.frame if frame is None else frame)

    def previous(self):
        """This scene one frame earlier (frame -1 for frame 0): the camera, light and objects
        of the previous frame. A scene without camera path, light path or moving objects is
        its own previous frame."""
        if self.camera_path is None and self.light_path is None and not self.object_motion:
            return self
        return self.with_frame(self.frame - 1, n_frames=self.n_frames)

    @property
    def light(self) -> Light:
        return self.lights[self.light_index]

    @property
    def width(self) -> int:
        return self.camera.width

    @property
    def height(self) -> int:
        return self.camera.height

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space (lo, hi) of every shape, from the shapes' own bounding boxes."""
        los, his = [], []
        for sh in self.mi_scene.shapes():
            bb = sh.bbox()
            los.append(np.array(bb.min, dtype=np.float64).ravel()[:3])
            his.append(np.array(bb.max, dtype=np.float64).ravel()[:3])
        return np.min(los, axis=0), np.max(his, axis=0)

    def with_frame(self, frame: int, *, path: str | None = None, n_frames: int | None = None):
        """The same scene seen from frame ``frame`` of a camera path (and, with a light path,
        lit by that frame's light; a light path alone keeps the scene's own camera)."""
        n = n_frames or self.n_frames or 8
        if path is None and self.camera_path is None and self.light_path is not None:
            moved = replace(self, frame=frame, n_frames=n)
        else:
            path = path or self.camera_path or self.default_camera_path
            if path == "file":
                if self.camera_sequence is None:
                    raise SceneError("camera path 'file' needs a camera file (--camera-file)")
                if frame >= len(self.camera_sequence):
                    raise SceneError(
                        f"frame {frame} is past the camera file's {len(self.camera_sequence)} "
                        "frames"
                    )
                cam = self.camera_sequence[max(int(frame), 0)]
            else:
                cam = path_camera(self.base_camera, path, frame, n, scene=self)
            moved = replace(self, camera=cam, camera_path=path, frame=frame, n_frames=n)
        if self.light_path is not None:
            moved = moved.with_light_frame(frame, path=self.light_path, n_frames=n)
        if self.object_motion:
            moved = moved._with_objects_at(frame)
        return moved

    def _with_objects_at(self, frame: int):
        """The same scene with its moving shapes where their paths put them at ``frame``."""
        if frame not in self.frame_scenes:
            mi = backend.mitsuba()
            raw = dict(self.scene_dict)
            for name, spec in self.object_motion.items():
                m = object_transform(spec, frame)
                entry = dict(raw[name])
                v = np.asarray(entry["vertices"], dtype=np.float64)
                entry["vertices"] = v @ m[:3, :3].T + m[:3, 3]
                raw[name] = entry
            meshes: dict = {}
            mi_scene = mi.load_dict(to_mitsuba_dict(mi, raw, meshes), optimize=False)
            self.frame_scenes[frame] = (mi_scene, meshes)
        mi_scene, meshes = self.frame_scenes[frame]
        # derived geometry (memo) belongs to one placement of the shapes
        return replace(self, mi_scene=mi_scene, mesh_data=meshes, memo={})

    def with_light_frame(self, frame: int, *, path: str, n_frames: int | None = None):
        """The same scene lit by frame ``frame`` of light path ``path`` (see
        :mod:`scenes.light_paths`); the chosen light moves, the others stay.

        Raises
        ------
        SceneError
            Unknown path, or a path that does not fit the chosen light's kind.
        """
        base = list(self.base_lights or self.lights)
        try:
            moved = path_light(base[self.light_index], path, frame, scene=self)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        lights = list(base)
        lights[self.light_index] = moved
        n = n_frames or self.n_frames or 8
        return replace(
            self, lights=lights, base_lights=base, light_path=path, frame=frame, n_frames=n
        )

    @property
    def shading_model(self) -> str:
        """The shading model of the colour truth (recorded in provenance)."""
        if self.pbr is not None:
            from .shading.pbr import SHADING_MODEL

            return SHADING_MODEL
        if self.specular.ks > 0.0:
            return "lambert + normalized Blinn-Phong (scenes.shading)"
        return "lambert (scenes.shading)"

    def provenance(self) -> dict:
        return {
            "name": self.name,
            "shading_model": self.shading_model,
            "source": self.source,
            "content_hash": self.content_hash,
            "light_index": self.light_index,
            "light": self.light.to_json(),
            "resolution": [self.width, self.height],
            "camera_path": self.camera_path,
            "light_path": self.light_path,
            "frame": self.frame,
            "n_frames": self.n_frames,
            "object_paths": {k: dict(v) for k, v in self.object_motion.items()} or None,
            "camera_file": self.camera_file,
        }
