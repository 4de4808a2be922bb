"""Load a scene (built-in name or Mitsuba XML path) into a :class:`LoadedScene`.

Mitsuba merges shapes with identical BSDFs when it optimizes a scene, and the merged scene's
bounding box is then wrong; scenes are therefore loaded with ``optimize=False`` (one Mitsuba
shape per scene shape, so shape ids are meaningful) and bounds are computed here from the
shapes' own geometry, never from ``scene.bbox()``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from . import backend
from .camera import Camera
from .catalogue.builtin import BUILTIN_SCENES, SceneParamError, builtin_scene
from .formats.camera_file import CameraFileError, load_camera_file
from .formats.gltf import GltfError, gltf_scene
from .light_paths import LIGHT_PATHS, check_light_path, path_light
from .lights import AREA_SHAPES, Light
from .object_paths import check_motion, object_transform
from .paths import CAMERA_PATHS, path_camera
from .shading.phong import Specular

__all__ = ["LoadedScene", "SceneError", "load", "scene_names"]

MAX_PIXELS = 16384 * 16384


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
    #: glTF materials (:class:`scenes.formats.gltf_materials.PbrMaterials`): the scene is
    #: shaded with the glTF BRDF of :mod:`scenes.shading.pbr`; None: the Lambert/Blinn-Phong
    #: of scenes.shading.phong.
    pbr: object = field(default=None, repr=False, compare=False)
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
            mi_scene = mi.load_dict(_to_mitsuba_dict(mi, raw, meshes), optimize=False)
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


def scene_names() -> list[str]:
    return list(BUILTIN_SCENES)


def _hash_obj(h, obj) -> None:
    if isinstance(obj, dict):
        for k in sorted(obj):
            h.update(f"<{k}>".encode())
            _hash_obj(h, obj[k])
    elif isinstance(obj, list | tuple):
        for v in obj:
            _hash_obj(h, v)
    elif isinstance(obj, np.ndarray):
        h.update(str(obj.dtype).encode() + str(obj.shape).encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    else:
        h.update(repr(obj).encode())


def _to_mitsuba_dict(mi, d: dict, meshes: dict) -> dict:
    """Replace ``ro_mesh`` entries by Mitsuba meshes and matrices by transforms."""
    out = {}
    for key, value in d.items():
        if isinstance(value, dict) and value.get("type") == "ro_mesh":
            v = np.asarray(value["vertices"], dtype=np.float32)
            f = np.asarray(value["faces"], dtype=np.uint32)
            # optional per-vertex data (glTF meshes, scenes.formats.gltf): normals, uv, tangents
            nrm, uv, tan = (value.get(k) for k in ("normals", "texcoords", "tangents"))
            mesh = mi.Mesh(
                key,
                vertex_count=len(v),
                face_count=len(f),
                has_vertex_normals=nrm is not None,
                has_vertex_texcoords=uv is not None,
            )
            params = mi.traverse(mesh)
            params["vertex_positions"] = mi.Float(v.ravel())
            params["faces"] = mi.UInt32(f.ravel())
            if nrm is not None:
                params["vertex_normals"] = mi.Float(np.asarray(nrm, np.float32).ravel())
            if uv is not None:
                params["vertex_texcoords"] = mi.Float(np.asarray(uv, np.float32).ravel())
            if tan is not None:
                tan = np.asarray(tan, np.float32)
                mesh.add_attribute("vertex_tangent", 3, mi.Float(tan[:, :3].ravel()))
                mesh.add_attribute("vertex_tangent_w", 1, mi.Float(tan[:, 3].ravel()))
            params.update()
            bsdf = mi.load_dict(value["bsdf"])
            mesh.set_bsdf(bsdf)
            meshes[key] = (v, f)
            out[key] = mesh
        elif isinstance(value, dict):
            out[key] = _to_mitsuba_dict(mi, value, meshes)
        elif isinstance(value, np.ndarray) and value.shape == (4, 4):
            out[key] = mi.ScalarTransform4f(value.tolist())
        else:
            out[key] = value
    return out


_PARAM = re.compile(r"\$(\w+)")


def _xml_dependencies(
    path: Path, seen: set | None = None, *, root: Path | None = None, params: dict | None = None
) -> list[Path]:
    """The XML file and every file it references, recursively, as Mitsuba resolves them.

    The XML is parsed (any quoting or attribute order); ``$name`` references are replaced by
    the ``<default name=... value=...>`` values (included files see the includer's defaults);
    references are the ``filename`` attribute of any element (``<include>``, spectra) and the
    ``value`` of every ``<string>`` property (``filename`` of meshes and bitmaps, ...), resolved
    against the referencing file's folder and then the scene's folder. Only existing files count:
    a missing one makes Mitsuba's own load fail.
    """
    seen = set() if seen is None else seen
    path = path.resolve()
    root = path.parent if root is None else root
    params = {} if params is None else params
    if path in seen:
        return []
    seen.add(path)
    files = [path]
    try:
        tree = ElementTree.parse(path)
    except (OSError, ElementTree.ParseError):
        return files  # Mitsuba's own load reports the error
    elements = list(tree.getroot().iter())
    for el in elements:
        if el.tag == "default" and "name" in el.attrib and "value" in el.attrib:
            params.setdefault(el.attrib["name"], el.attrib["value"])

    def subst(text: str) -> str:
        return _PARAM.sub(lambda m: params.get(m.group(1), m.group(0)), text)

    for el in elements:
        refs = []
        if "filename" in el.attrib:
            refs.append(el.attrib["filename"])
        if el.tag == "string" and "value" in el.attrib:
            refs.append(el.attrib["value"])
        for ref in refs:
            ref = subst(ref)
            if not ref:
                continue
            for base in (path.parent, root):
                dep = (base / ref).resolve()
                if dep.is_file():
                    if dep.suffix.lower() == ".xml":
                        files.extend(_xml_dependencies(dep, seen, root=root, params=params))
                    elif dep not in seen:
                        seen.add(dep)
                        files.append(dep)
                    break
    return files


def _camera_from_sensor(mi, sensor, width, height) -> Camera:
    params = mi.traverse(sensor)
    keys = set(params.keys())
    size = [int(c) for c in params["film.size"]]
    w = int(width or size[0])
    h = int(height or size[1])
    to_world = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    near, far = float(params["near_clip"]), float(params["far_clip"])
    if "x_fov" in keys:
        fov = float(np.ravel(params["x_fov"])[0])
        for k in ("principal_point_offset_x", "principal_point_offset_y"):
            if k in keys and abs(float(np.ravel(params[k])[0])) > 0:
                raise SceneError(f"sensor {k} is not supported (must be 0)")
        return Camera("perspective", to_world, w, h, near, far, fov)
    if sensor.class_name() == "OrthographicCamera":
        return Camera("orthographic", to_world, w, h, near, far)
    raise SceneError(
        f"sensor type {sensor.class_name()} is not supported; use a perspective or "
        "orthographic sensor"
    )


def _light_from_emitter(mi, emitter, name: str) -> Light | None:
    kind = emitter.class_name()
    p = mi.traverse(emitter)

    def rgb(key):
        return tuple(float(c) for c in np.broadcast_to(np.array(p[key]).ravel(), (3,)))

    def matrix():
        return np.array(p["to_world"].matrix, dtype=np.float64).reshape(4, 4)

    if kind == "DirectionalEmitter":
        d = matrix()[:3, 2]
        norm = float(np.linalg.norm(d))
        if not (np.isfinite(d).all() and norm > 1e-12):
            raise SceneError(
                f"directional light {name!r} has no direction (got {tuple(d.tolist())}); "
                "give a non-zero direction"
            )
        return Light(
            "directional", rgb("irradiance.value"), tuple(d / np.linalg.norm(d)), name=name
        )
    if kind == "PointLight":
        pos = tuple(float(c) for c in np.array(p["position"]).ravel()[:3])
        return Light("point", rgb("intensity.value"), position=pos, name=name)
    if kind == "SpotLight":
        m = matrix()
        if not (np.isfinite(m).all() and np.linalg.norm(m[:3, 2]) > 1e-12):
            raise SceneError(f"spot light {name!r} has no valid direction (to_world is degenerate)")
        d = m[:3, 2] / np.linalg.norm(m[:3, 2])
        return Light(
            "spot",
            rgb("intensity.value"),
            tuple(d),
            tuple(m[:3, 3]),
            cutoff_angle=float(np.ravel(p["cutoff_angle"])[0]),
            beam_width=float(np.ravel(p["beam_width"])[0]),
            name=name,
        )
    if kind == "AreaLight":
        return _area_light(mi, emitter, rgb("radiance.value"), name)
    return None


#: Relative tolerance of an area light's shape checks (orthogonal axes, round disk, sphere).
_AREA_TOLERANCE = 1e-4


def _area_light(mi, emitter, radiance, name: str) -> Light | None:
    """An area light (:mod:`scenes.lights`) from a Mitsuba ``area`` emitter on a rectangle,
    disk or sphere; None on any other shape (not a usable light, as other emitters);
    :class:`SceneError` for a sheared rectangle, an elliptical disk or a non-uniformly scaled
    sphere."""
    shape = emitter.get_shape()
    name = shape.id() or name  # the shape's id names the light (its emitter has none of its own)
    kind = shape.class_name().lower()
    if kind not in AREA_SHAPES:
        return None
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    u, v, w, centre = m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3]
    lu, lv, lw = (float(np.linalg.norm(a)) for a in (u, v, w))
    tol = _AREA_TOLERANCE * max(lu, lv, 1e-30)
    if not (np.isfinite(m).all() and lu > 0 and lv > 0 and abs(float(u @ v)) <= tol * max(lu, lv)):
        raise SceneError(
            f"area light {name!r}: its {kind}'s to_world must scale and rotate without shear "
            "(orthogonal, non-zero axes)"
        )
    rgb = np.asarray(radiance, dtype=np.float64)
    if kind == "sphere":
        if abs(lu - lv) > tol or abs(lu - lw) > tol:
            raise SceneError(f"area light {name!r}: a sphere light must be scaled uniformly")
        r = lu
        return Light(
            "point",
            tuple(float(c) for c in rgb * math.pi * r * r),
            position=tuple(float(c) for c in centre),
            name=name,
            area="sphere",
            radius=r,
            radiance=tuple(float(c) for c in rgb),
        )
    # Mitsuba's planar shapes face the transformed local +Z normal (the inverse transpose)
    n = np.linalg.inv(m[:3, :3]).T @ np.array([0.0, 0.0, 1.0])
    n = n / np.linalg.norm(n)
    if float(np.cross(u, v) @ n) < 0.0:  # a mirroring to_world: keep u x v along the normal
        v = -v
    if kind == "disk" and abs(lu - lv) > tol:
        raise SceneError(f"area light {name!r}: a disk light must be round (equal axes)")
    area = 4.0 * lu * lv if kind == "rectangle" else math.pi * lu * lu
    return Light(
        "point",
        tuple(float(c) for c in rgb * area),
        direction=tuple(float(c) for c in n),
        position=tuple(float(c) for c in centre),
        name=name,
        area=kind,
        axes=(tuple(float(c) for c in u), tuple(float(c) for c in v)),
        radius=lu if kind == "disk" else 0.0,
        radiance=tuple(float(c) for c in rgb),
    )


def _check_size(width, height) -> None:
    for label, v in (("width", width), ("height", height)):
        if v is not None and int(v) <= 0:
            raise SceneError(f"{label} must be a positive number of pixels, got {v}")
    if width and height and int(width) * int(height) > MAX_PIXELS:
        raise SceneError(f"resolution {width}x{height} is larger than {MAX_PIXELS} pixels")


def load(
    scene: str | Path,
    *,
    width: int | None = None,
    height: int | None = None,
    light: int = 0,
    camera_path: str | None = None,
    frame: int = 0,
    n_frames: int = 8,
    light_path: str | None = None,
    camera_file=None,
    camera: int | None = None,
) -> LoadedScene:
    """Load a built-in scene by name, a Mitsuba XML file or a glTF 2.0 file.

    Parameters
    ----------
    scene : built-in name (see :func:`scene_names`; with parameters such as
        ``meadow:n=100000``, see :func:`scenes.catalogue.builtin.builtin_scene`) or path to
        a Mitsuba XML file. A :class:`scenes.catalogue.builtin.BuiltinScene` (e.g. a
        built-in scene's factory wrapped by a
        transformation, as ``oracle.studies.extremes.run`` does) loads like a built-in one.
    width, height : film size in pixels; default: the scene's own.
    light : index of the light to use among the scene's lights (punctual ones first, then
        area lights, each in the scene's order).
    camera_path, frame, n_frames : a camera path of :data:`scenes.paths.CAMERA_PATHS` and the
        frame of it to view (frame 0 is the scene's own camera).
    light_path : a light path of :data:`scenes.light_paths.LIGHT_PATHS`; the chosen light is
        that of ``frame`` (frame 0 is the scene's own light).
    camera_file : a camera sequence file (:mod:`scenes.formats.camera_file`): frames follow its
        cameras (camera path ``file``).

    Objects of a scene with object paths (:mod:`scenes.object_paths`) are placed for
    ``frame``; such a scene's frames keep the camera still unless a camera path is named.
    camera : glTF scenes: index of the document's camera to view through (default: the
        scene's first camera node); see :mod:`scenes.formats.gltf`.

    Raises
    ------
    SceneError
        Unknown name, missing or malformed file, no sensor, no usable light, bad sizes, an
        unknown light path or one that does not fit the chosen light.
    """
    _check_size(width, height)
    _check_sequence(light_path, camera_path, camera_file, frame, n_frames)
    mi = backend.mitsuba()
    meshes: dict = {}
    src = _open(mi, scene, meshes, width=width, height=height, camera=camera)
    mi_scene, name, digest, gl = src.mi_scene, src.name, src.digest, src.gltf
    sensors = mi_scene.sensors()
    if not sensors:
        raise SceneError(f"scene {name!r} has no sensor (camera)")
    cam = _camera_from_sensor(mi, sensors[0], width, height)
    if width and height:
        cam = cam.with_resolution(width, height)
    digest.update(f"res:{cam.width}x{cam.height}".encode())
    lights = _lights_of(mi, mi_scene, name, gl, light)
    loaded = LoadedScene(
        name=name,
        source=src.source,
        description=src.description,
        mi_scene=mi_scene,
        camera=cam,
        base_camera=cam,
        lights=lights,
        light_index=int(light),
        shape_names=[s.id() for s in mi_scene.shapes()],
        content_hash=digest.hexdigest(),
        specular=src.specular,
        mesh_data=meshes,
        object_motion=src.motion,
        scene_dict=src.scene_dict,
        pbr=None if gl is None else gl.pbr([s.id() for s in mi_scene.shapes()]),
    )
    loaded = _placed(loaded, camera_file, camera_path, int(frame), int(n_frames))
    if light_path is not None:
        try:
            check_light_path(light_path, loaded.light)
        except ValueError as exc:
            raise SceneError(f"scene {name!r}: {exc}") from None
        loaded = loaded.with_light_frame(int(frame), path=light_path, n_frames=int(n_frames))
    return loaded


@dataclass
class _Source:
    """What :func:`_open` read: the Mitsuba scene and the record :func:`load` keeps of it."""

    mi_scene: object
    name: str
    digest: object  # hashlib sha256, still open: the film size is added by load()
    source: str
    description: str
    specular: Specular
    motion: dict
    scene_dict: dict | None
    gltf: object = None  # scenes.formats.gltf's scene record for glTF input, else None


def _open(mi, scene, meshes: dict, *, width, height, camera) -> _Source:
    """The Mitsuba scene of a glTF file or built-in glTF scene, a built-in scene or a Mitsuba
    XML file; the meshes given to Mitsuba are kept in ``meshes``."""
    builtin = _builtin(scene)  # a built-in name, with its parameters (meadow:n=1000)
    name = builtin.name if builtin is not None else str(scene)
    try:  # a glTF file or built-in glTF scene (scenes.formats.gltf), else None
        gl = gltf_scene(builtin or scene, BUILTIN_SCENES, width=width, height=height, camera=camera)
    except GltfError as exc:
        raise SceneError(str(exc)) from None
    if gl is not None:
        digest, source, description, name = gl.digest, gl.source, gl.description, gl.name
        specular = Specular()
        motion, scene_dict = {}, None
        try:
            mi_scene = mi.load_dict(_to_mitsuba_dict(mi, gl.raw, meshes), optimize=False)
        except Exception as exc:
            raise SceneError(f"glTF scene {name!r} failed to load: {exc}") from exc
    elif builtin is not None:
        w, h = int(width or builtin.width), int(height or builtin.height)
        raw = builtin.factory(w, h)
        digest = hashlib.sha256(b"builtin:" + name.encode())
        _hash_obj(digest, raw)
        # a scene-wide Blinn-Phong lobe (the catalogue's glossy); hashed above with the rest
        specular = Specular(**raw.pop("ro_specular", {}))
        motion, scene_dict = _motion_of(raw, name), dict(raw)
        try:
            mi_scene = mi.load_dict(_to_mitsuba_dict(mi, raw, meshes), optimize=False)
        except Exception as exc:  # Mitsuba raises RuntimeError subclasses
            raise SceneError(f"built-in scene {name!r} failed to load: {exc}") from exc
        source, description = "builtin", builtin.description
    else:
        path = Path(name)
        if path.suffix.lower() != ".xml" and not path.exists():
            raise SceneError(
                f"unknown scene {name!r}: not a built-in scene ({', '.join(BUILTIN_SCENES)}), "
                "a Mitsuba XML file nor a glTF file (.gltf, .glb)"
            )
        if not path.is_file():
            raise SceneError(f"scene file not found: {path}")
        digest = hashlib.sha256(b"xml:")
        for dep in _xml_dependencies(path):
            digest.update(dep.name.encode() + dep.read_bytes())
        try:
            mi_scene = mi.load_file(str(path), optimize=False)
        except Exception as exc:
            msg = str(exc).strip().splitlines()
            raise SceneError(f"cannot load {path}: {msg[-1] if msg else exc}") from exc
        source, description = str(path.resolve()), f"Mitsuba scene {path.name}"
        specular = Specular()
        motion, scene_dict = {}, None
        name = path.stem
    return _Source(
        mi_scene, name, digest, source, description, specular, motion, scene_dict, gltf=gl
    )


def _emitter_kind(emitter) -> str:
    """An emitter's class for messages (an area light with its shape's)."""
    shape = emitter.get_shape() if emitter.class_name() == "AreaLight" else None
    return emitter.class_name() + (f" on a {shape.class_name()}" if shape is not None else "")


def _lights_of(mi, mi_scene, name: str, gl, light: int) -> list[Light]:
    """The scene's usable lights (glTF: with the KHR_lights_punctual attenuation);
    :class:`SceneError` when there is none or ``light`` is out of range."""
    emitters = mi_scene.emitters()
    lights = []
    for i, e in enumerate(emitters):
        lt = _light_from_emitter(mi, e, e.id() or f"emitter_{i}")
        if lt is not None:
            lights.append(lt)
    if gl is not None:
        lights = gl.lights(lights)
    # area lights after the punctual ones: a scene's punctual lights keep the indices they
    # had before area lights were read
    lights = [lt for lt in lights if not lt.is_area] + [lt for lt in lights if lt.is_area]
    if not lights:
        kinds = ", ".join(_emitter_kind(e) for e in emitters) or "none"
        raise SceneError(
            f"scene {name!r} has no usable light (directional, point, spot or an area light "
            f"on a rectangle, disk or sphere); found: {kinds}"
        )
    if not 0 <= int(light) < len(lights):
        raise SceneError(
            f"light index {light} out of range: scene {name!r} has {len(lights)} usable "
            f"light(s) (0..{len(lights) - 1})"
        )
    return lights


def _builtin(scene):
    """The :class:`scenes.catalogue.builtin.BuiltinScene` ``scene`` names (None: not a
    built-in one); :class:`SceneError` for a bad scene parameter."""
    try:
        return builtin_scene(scene)
    except SceneParamError as exc:
        raise SceneError(str(exc)) from None


def _check_sequence(light_path, camera_path, camera_file, frame, n_frames) -> None:
    """:class:`SceneError` for an unknown light or camera path, a ``file`` path without a
    camera file, or a frame outside ``[0, n_frames)``."""
    if light_path is not None and light_path not in LIGHT_PATHS:
        raise SceneError(
            f"unknown light path {light_path!r}; choose one of {', '.join(LIGHT_PATHS)}"
        )
    if camera_path == "file" and camera_file is None:
        raise SceneError("camera path 'file' needs a camera file (--camera-file)")
    if camera_path is not None and camera_path not in (*CAMERA_PATHS, "file"):
        raise SceneError(
            f"unknown camera path {camera_path!r}; choose one of {', '.join(CAMERA_PATHS)}"
        )
    if not 0 <= int(frame) < max(int(n_frames), 1):
        raise SceneError(f"frame must be in [0, {n_frames}), got {frame}")


def _motion_of(raw: dict, name: str) -> dict:
    """The object paths a built-in dictionary declares (``"ro_motion"``, taken out of it)."""
    motion = raw.pop("ro_motion", {})
    try:
        check_motion(motion)
    except ValueError as exc:
        raise SceneError(f"built-in scene {name!r}: {exc}") from None
    return motion


def _placed(loaded: LoadedScene, camera_file, camera_path, frame: int, n_frames: int):
    """``loaded`` with its camera file's sequence, at ``frame`` of its camera path (or of its
    objects' paths)."""
    if camera_file is not None:
        try:
            sequence = load_camera_file(camera_file, loaded.camera)
        except CameraFileError as exc:
            raise SceneError(str(exc)) from None
        loaded = replace(loaded, camera_sequence=sequence, camera_file=str(camera_file))
        camera_path = camera_path or "file"
    if camera_path is not None or loaded.object_motion:
        loaded = loaded.with_frame(frame, path=camera_path, n_frames=n_frames)
    return loaded


def describe(loaded: LoadedScene) -> str:
    """One-line JSON summary (used by the CLI)."""
    return json.dumps(loaded.provenance())
