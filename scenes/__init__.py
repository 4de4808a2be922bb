"""raster-oracle's world (the bottom layer: it knows nothing of techniques).

``scenes/`` holds the scene model itself at its top (cameras, lights, camera and light paths,
:class:`LoadedScene`, the loader and the resolution of a command's scene argument) and one
folder per concern. Folders import down only (backend -> shading, base; geometry -> backend;
formats -> geometry, shading, backend, base; catalogue -> formats, geometry, shading, base) and up
to the scene model at the top, never a sibling that imports them back:

- ``base/``: pure helpers every layer may import (atomic writes, records, display transform,
  array checks, numbers in text, free memory); no Mitsuba;
- ``catalogue/``: the built-in scenes and the factories they are written with;
- ``formats/``: glTF read/write, ``export`` folders, camera files;
- ``shading/``: Lambert/Phong, the glTF BRDF, the materials both read and alpha-tested
  materials (the alpha itself; the test is the backend's);
- ``geometry/``: mesh generators and tessellation, textured meshes, exact coverage, pixel
  areas, motion vectors, tangent-plane points;
- ``backend/``: the Mitsuba variant, the kernel audit and ray queries (the alpha test
  included).

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
    "LoadOptions",
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
    "LoadOptions": ".loader",
    "LoadedScene": ".loaded",
    "SceneError": ".loaded",
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
