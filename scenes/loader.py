"""Load a scene (built-in name, Mitsuba XML path or glTF file) into a :class:`LoadedScene`.

Mitsuba merges shapes with identical BSDFs when it optimizes a scene, and the merged scene's
bounding box is then wrong; scenes are therefore loaded with ``optimize=False`` (one Mitsuba
shape per scene shape, so shape ids are meaningful) and bounds are computed from the shapes'
own geometry (:meth:`LoadedScene.bounds`), never from ``scene.bbox()``. The record itself is
:mod:`scenes.loaded`; the Mitsuba dictionary and hashing helpers are
:mod:`scenes.mitsuba_dict`; the camera and lights read from the Mitsuba scene,
:mod:`scenes.mitsuba_scene`.
"""

from __future__ import annotations

import hashlib
import inspect
import json
from dataclasses import dataclass, fields, replace
from pathlib import Path

from . import backend
from .base.untrusted import LIMITS, path_problem, read_bounded
from .catalogue.builtin import BUILTIN_SCENES, SceneParamError, builtin_scene
from .formats.camera_file import CameraFileError, load_camera_file
from .formats.gltf import GltfError, gltf_scene
from .light_paths import LIGHT_PATHS, check_light_path
from .loaded import LoadedScene, SceneError
from .mitsuba_dict import hash_obj, to_mitsuba_dict, xml_dependencies
from .mitsuba_scene import camera_from_sensor, lights_of
from .object_paths import check_motion
from .paths import CAMERA_PATHS
from .shading.alpha_mitsuba import alpha_table_from_bsdfs
from .shading.phong import Specular

__all__ = ["LoadOptions", "describe", "load", "scene_names", "with_load_options"]

MAX_PIXELS = 16384 * 16384


def scene_names() -> list[str]:
    return list(BUILTIN_SCENES)


def _check_size(width, height) -> None:
    for label, v in (("width", width), ("height", height)):
        if v is not None and int(v) <= 0:
            raise SceneError(f"{label} must be a positive number of pixels, got {v}")
    if width and height and int(width) * int(height) > MAX_PIXELS:
        raise SceneError(f"resolution {width}x{height} is larger than {MAX_PIXELS} pixels")


@dataclass(frozen=True)
class LoadOptions:
    """How a scene is loaded: the one declaration of the keywords of :func:`load`,
    :func:`scenes.inputs.load_input` and the Python API's ``load_scene`` (the command line's
    scene options).

    Attributes
    ----------
    width, height : film size in pixels; default: the scene's own.
    light : index of the light to use among the scene's lights (punctual ones first, then
        area lights, each in the scene's order); None: 0, or an export folder's own light
        (:func:`scenes.inputs.load_input`).
    camera_path, frame, n_frames : a camera path of :data:`scenes.paths.CAMERA_PATHS` and the
        frame of it to view (frame 0 is the scene's own camera). Objects of a scene with
        object paths (:mod:`scenes.object_paths`) are placed for ``frame``; such a scene's
        frames keep the camera still unless a camera path is named.
    light_path : a light path of :data:`scenes.light_paths.LIGHT_PATHS`; the chosen light is
        that of ``frame`` (frame 0 is the scene's own light).
    camera_file : a camera sequence file (:mod:`scenes.formats.camera_file`): frames follow
        its cameras (camera path ``file``).
    camera : glTF scenes: index of the document's camera to view through (default: the
        scene's first camera node); see :mod:`scenes.formats.gltf`.
    """

    width: int | None = None
    height: int | None = None
    light: int | None = None
    camera_path: str | None = None
    frame: int = 0
    n_frames: int = 8
    light_path: str | None = None
    camera_file: object = None
    camera: int | None = None

    @classmethod
    def of(cls, options: dict) -> LoadOptions:
        """``options`` (keywords) as a record; :class:`SceneError` naming an unknown one."""
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise SceneError(
                f"unknown scene option {', '.join(unknown)}; the options are {', '.join(known)}"
            )
        return cls(**options)

    def given(self) -> list[str]:
        """The options that differ from their defaults."""
        default = LoadOptions()
        return [f.name for f in fields(self) if getattr(self, f.name) != getattr(default, f.name)]


def with_load_options(func):
    """Give ``func(scene, **options)`` the signature ``(scene, *, <LoadOptions' keywords>)``,
    so ``help()`` and :func:`inspect.signature` show the options :class:`LoadOptions`
    declares."""
    keywords = [
        inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default)
        for f in fields(LoadOptions)
    ]
    scene = inspect.Parameter("scene", inspect.Parameter.POSITIONAL_OR_KEYWORD)
    func.__signature__ = inspect.Signature([scene, *keywords])
    return func


@with_load_options
def load(scene: str | Path, **options) -> LoadedScene:
    """Load a built-in scene by name, a Mitsuba XML file or a glTF 2.0 file.

    Parameters
    ----------
    scene : built-in name (see :func:`scene_names`; with parameters such as
        ``meadow:n=100000``, see :func:`scenes.catalogue.builtin.builtin_scene`) or path to
        a Mitsuba XML file. A :class:`scenes.catalogue.builtin.BuiltinScene` (e.g. a
        built-in scene's factory wrapped by a
        transformation, as ``oracle.studies.extremes.run`` does) loads like a built-in one.
    options : the keywords of :class:`LoadOptions` (size, light, frame of a camera or light
        path, camera file, glTF camera).

    Raises
    ------
    SceneError
        Unknown name, missing or malformed file, no sensor, no usable light, bad sizes, an
        unknown light path or one that does not fit the chosen light, an unknown option.
    """
    o = LoadOptions.of(options)
    light = int(o.light or 0)
    _check_size(o.width, o.height)
    _check_sequence(o.light_path, o.camera_path, o.camera_file, o.frame, o.n_frames)
    mi = backend.mitsuba()
    meshes: dict = {}
    src = _open(mi, scene, meshes, width=o.width, height=o.height, camera=o.camera)
    mi_scene, name, digest, gl = src.mi_scene, src.name, src.digest, src.gltf
    sensors = mi_scene.sensors()
    if not sensors:
        raise SceneError(f"scene {name!r} has no sensor (camera)")
    cam = camera_from_sensor(mi, sensors[0], o.width, o.height)
    if o.width and o.height:
        cam = cam.with_resolution(o.width, o.height)
    digest.update(f"res:{cam.width}x{cam.height}".encode())
    lights = lights_of(mi, mi_scene, name, gl, light)
    loaded = LoadedScene(
        name=name,
        source=src.source,
        description=src.description,
        mi_scene=mi_scene,
        camera=cam,
        base_camera=cam,
        lights=lights,
        light_index=light,
        shape_names=[s.id() for s in mi_scene.shapes()],
        content_hash=digest.hexdigest(),
        specular=src.specular,
        mesh_data=meshes,
        object_motion=src.motion,
        scene_dict=src.scene_dict,
        pbr=None if gl is None else gl.pbr([s.id() for s in mi_scene.shapes()]),
        alpha=_alpha(mi, mi_scene, gl),
    )
    frame, n_frames = int(o.frame), int(o.n_frames)
    loaded = _placed(loaded, o.camera_file, o.camera_path, frame, n_frames)
    if o.light_path is not None:
        try:
            check_light_path(o.light_path, loaded.light)
        except ValueError as exc:
            raise SceneError(f"scene {name!r}: {exc}") from None
        loaded = loaded.with_light_frame(frame, path=o.light_path, n_frames=n_frames)
    return loaded


def _alpha(mi, mi_scene, gl):
    """The alpha-tested shapes of the scene: glTF MASK materials, or Mitsuba ``mask`` BSDFs
    (alpha test at 0.5; :mod:`scenes.shading.alpha_mitsuba`); None when there are none."""
    if gl is not None:
        return gl.alpha([s.id() for s in mi_scene.shapes()])
    return alpha_table_from_bsdfs(mi, mi_scene)


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
            mi_scene = mi.load_dict(to_mitsuba_dict(mi, gl.raw, meshes), optimize=False)
        except Exception as exc:
            raise SceneError(f"glTF scene {name!r} failed to load: {exc}") from exc
    elif builtin is not None:
        w, h = int(width or builtin.width), int(height or builtin.height)
        raw = builtin.factory(w, h)
        digest = hashlib.sha256(b"builtin:" + name.encode())
        hash_obj(digest, raw)
        # a scene-wide Blinn-Phong lobe (the catalogue's glossy); hashed above with the rest
        specular = Specular(**raw.pop("ro_specular", {}))
        motion, scene_dict = _motion_of(raw, name), dict(raw)
        try:
            mi_scene = mi.load_dict(to_mitsuba_dict(mi, raw, meshes), optimize=False)
        except Exception as exc:  # Mitsuba raises RuntimeError subclasses
            raise SceneError(f"built-in scene {name!r} failed to load: {exc}") from exc
        source, description = "builtin", builtin.description
    else:
        path = Path(name)
        problem = path_problem(path)
        if problem is not None or (path.suffix.lower() != ".xml" and not path.exists()):
            raise SceneError(
                f"unknown scene {name[:80]!r}: not a built-in scene ({', '.join(BUILTIN_SCENES)}), "
                "a Mitsuba XML file nor a glTF file (.gltf, .glb)"
            )
        if not path.is_file():
            raise SceneError(f"scene file not found: {path}")
        digest = hashlib.sha256(b"xml:")
        for dep in xml_dependencies(path, error=SceneError):  # inside its folder, bounded
            data = read_bounded(
                dep, limit=LIMITS["scene_bytes"], what="scene file", error=SceneError
            )
            digest.update(dep.name.encode() + data)
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
