"""Scene inputs, resolved once: a built-in name, a scene file or an ``export`` folder.

Every command and the Python API take a scene as text (``SCENE``); this module says what it
stands for. A folder is an ``export`` folder (its ``scene.xml`` or ``scene.glb``, its
``lights.json``'s chosen light, its name for records and its ``export.json``: the size,
camera path and frame it was exported for). A file is loaded by its suffix
(:data:`SCENE_FILE_SUFFIXES`: the one place a new scene format registers). Anything else is
a built-in scene name.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path

from .base.untrusted import path_problem, read_json
from .formats.export import EXPORT_SCENE_FILES, export_scene_file
from .loaded import LoadedScene, SceneError
from .loader import LoadOptions, load, with_load_options

__all__ = [
    "EXPORT_RECORD",
    "EXPORT_SCHEMA",
    "EXPORT_SCHEMAS",
    "SCENE_FILE_SUFFIXES",
    "SceneInput",
    "load_input",
    "named_input",
    "nearest_export",
    "read_export_record",
    "resolve_input",
]

#: Scene files by suffix -> the format's name. :func:`scenes.load` reads them (a new format
#: adds its suffix here and its loader beside the others).
SCENE_FILE_SUFFIXES = {".xml": "Mitsuba XML", ".gltf": "glTF 2.0", ".glb": "glTF 2.0 binary"}
#: The file of an export folder that records what it was exported for.
EXPORT_RECORD = "export.json"
#: ``schema`` of :data:`EXPORT_RECORD`: version 2 points at ``camera.json``'s ``sequence``;
#: version 1 (exports of earlier releases) held the sequence fields itself.
EXPORT_SCHEMA = "raster-oracle/export/2"
EXPORT_SCHEMAS = ("raster-oracle/export/1", EXPORT_SCHEMA)


@dataclass(frozen=True)
class SceneInput:
    """What a ``SCENE`` text stands for.

    ``scene``: what :func:`scenes.load` takes (a built-in name or a file); ``folder``: the
    export folder (None: not an export); ``light``: the export's chosen light; ``name``: the
    name records use (an export's folder name); ``export``: its ``export.json`` record with
    the sequence fields of its ``camera.json`` (``width``, ``height``, ``camera_path``,
    ``frame``, ``n_frames``, ``light_path``; None for an export written before it existed)."""

    scene: str
    folder: Path | None = None
    light: int | None = None
    name: str | None = None
    export: dict | None = None


def read_export_record(folder: Path) -> dict | None:
    """An export folder's :data:`EXPORT_RECORD` (None when absent); :class:`SceneError` for
    one that is not an export record."""
    path = Path(folder) / EXPORT_RECORD
    if not path.exists() and not path.is_symlink():
        return None  # absent (anything else there is read, or refused, as untrusted input)
    record = read_json(path, what="export record", error=SceneError)
    if not isinstance(record, dict) or record.get("schema") not in EXPORT_SCHEMAS:
        raise SceneError(f"{path} is not an export record (schema {EXPORT_SCHEMA!r})")
    if record["schema"] == EXPORT_SCHEMA:
        record = {**record, **_sequence_fields(Path(folder) / "camera.json")}
    return record


def _sequence_fields(path: Path) -> dict:
    """``camera_path``, ``light_path``, ``frame`` and ``n_frames`` of an export from its
    ``camera.json``'s ``sequence`` (frame 0 and no count when neither path moves)."""
    try:
        seq = read_json(path, what="export camera record")["sequence"]
        camera_path, light_path = seq["camera_path"], seq["light_path"]
        moving = camera_path is not None or light_path is not None
        return {
            "camera_path": camera_path,
            "light_path": light_path,
            "frame": int(seq["frame"]) if moving else 0,
            "n_frames": int(seq["n_frames"]) if moving else None,
        }
    except (OSError, ValueError, KeyError, TypeError):
        raise SceneError(f"{path} has no readable sequence record") from None


def _chosen_light(folder: Path) -> int | None:
    try:
        chosen = read_json(folder / "lights.json", what="export lights")["chosen"]
        return chosen if isinstance(chosen, int) and not isinstance(chosen, bool) else None
    except (OSError, ValueError, KeyError, TypeError):
        return None


def resolve_input(scene) -> SceneInput:
    """Resolve ``scene`` (text or path): an export folder or its ``scene.xml``, a scene file
    of a known suffix, or a built-in name (checked when loaded)."""
    path = Path(scene)
    if path_problem(path) is not None:  # no file has this name: a built-in's, or unknown
        return SceneInput(scene=str(scene))
    if path.is_dir():
        found = export_scene_file(path)
        if found is None:
            raise SceneError(
                f"scene folder {scene} has no {' or '.join(EXPORT_SCENE_FILES)}: give a "
                f"built-in scene, a scene file ({', '.join(SCENE_FILE_SUFFIXES)}) or a folder "
                "written by `export`"
            )
        path = found
    elif path.name not in EXPORT_SCENE_FILES or not path.is_file():
        return SceneInput(scene=str(scene))
    folder = path.parent
    is_export = (folder / "camera.json").is_file()
    return SceneInput(
        scene=str(path),
        folder=folder if is_export else None,
        light=_chosen_light(folder),
        name=folder.resolve().name if is_export else None,
        export=read_export_record(folder) if is_export else None,
    )


@with_load_options
def load_input(scene, **options) -> LoadedScene:
    """Load what ``scene`` stands for (:func:`resolve_input`) with :func:`scenes.load`'s
    options (:class:`scenes.loader.LoadOptions`); an export loads at its exported size with
    its light (unless ``light`` names one), named after its folder.

    An export made along a camera path from its first frame keeps that path
    (``loaded.camera_path``), so its later frames can be scored without naming it again.
    """
    o = LoadOptions.of(options)
    found = resolve_input(scene)
    rec = found.export or {}
    light = o.light if o.light is not None else (found.light or 0)
    loaded = load(found.scene, **asdict(replace(o, light=light)))
    if found.name is not None:
        loaded = replace(loaded, name=found.name)
    if o.camera_path is None and rec.get("camera_path") and int(rec.get("frame") or 0) == 0:
        loaded = replace(
            loaded, camera_path=rec["camera_path"], n_frames=int(rec.get("n_frames") or 8)
        )
    return loaded


def named_input(name: str, *, exports=None) -> str:
    """The scene a name stands for in a folder of engine images: the export folder
    ``exports/name`` when it is one, else the built-in scene ``name``; :class:`SceneError`
    naming the built-in scenes otherwise."""
    from .catalogue.builtin import BUILTIN_SCENES, SceneParamError, builtin_scene

    if exports is not None and export_scene_file(Path(exports) / name) is not None:
        return str(Path(exports) / name)
    try:
        if builtin_scene(name) is not None:
            return name
    except SceneParamError as exc:
        raise SceneError(str(exc)) from None
    where = f" nor an export in {exports}" if exports is not None else ""
    raise SceneError(
        f"{name!r} is not a built-in scene{where}; name the files after a scene "
        f"({', '.join(BUILTIN_SCENES)}) or pass --exports"
    )


def nearest_export(start, size: tuple[int, int]) -> Path | None:
    """The nearest export folder (``scene.xml`` + ``camera.json``) of ``size`` (width,
    height) in ``start``'s folder or one of its three nearest parents: where an engine
    usually renders."""
    folder = Path(start).resolve().parent
    for _ in range(4):
        cam = folder / "camera.json"
        if cam.is_file() and export_scene_file(folder) is not None:
            try:
                rec = read_json(cam, what="export camera record")
                if (int(rec["width"]), int(rec["height"])) == tuple(size):
                    return folder
            except (OSError, ValueError, KeyError, TypeError):
                pass
        if folder.parent == folder:
            break
        folder = folder.parent
    return None
