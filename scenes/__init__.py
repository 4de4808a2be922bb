"""raster-oracle's world (the bottom layer: it knows nothing of techniques).

``scenes/`` holds the scene model itself at its top (cameras, lights, camera and light paths,
the loader and :class:`LoadedScene`) and one folder per concern:

- ``base/``: pure helpers every layer may import (atomic writes, records, display transform,
  array checks); no Mitsuba;
- ``catalogue/``: the built-in scenes, meshes and factories;
- ``formats/``: glTF read/write, ``export`` folders, camera files, input resolution;
- ``shading/``: Lambert/Phong and the glTF BRDF;
- ``geometry/``: exact coverage, pixel areas, motion vectors, tangent-plane points;
- ``backend/``: the Mitsuba variant, the kernel audit and ray queries.

Importing this package costs nothing: the public names below load their modules (and Mitsuba)
on first use.
"""

from __future__ import annotations

import importlib

__all__ = [
    "BUILTIN_SCENES",
    "CAMERA_PATHS",
    "Camera",
    "DEFAULT_SCENES",
    "Light",
    "LoadedScene",
    "SceneError",
    "SceneParamError",
    "Specular",
    "builtin_scene",
    "load",
    "scene_names",
    "shade",
]

_WHERE = {
    "BUILTIN_SCENES": ".catalogue.builtin",
    "DEFAULT_SCENES": ".catalogue.builtin",
    "SceneParamError": ".catalogue.builtin",
    "builtin_scene": ".catalogue.builtin",
    "Camera": ".camera",
    "Light": ".lights",
    "LoadedScene": ".loader",
    "SceneError": ".loader",
    "load": ".loader",
    "scene_names": ".loader",
    "CAMERA_PATHS": ".paths",
    "Specular": ".shading.phong",
    "shade": ".shading.phong",
}


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_WHERE[name], __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
