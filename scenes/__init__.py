"""raster-oracle's world: scenes, cameras, lights, the shading model, camera paths, export,
the Mitsuba backend and ray queries (the bottom layer: it knows nothing of techniques)."""

from .builtin import BUILTIN_SCENES, DEFAULT_SCENES, SceneParamError, builtin_scene
from .camera import Camera
from .lights import Light
from .loader import LoadedScene, SceneError, load, scene_names
from .paths import CAMERA_PATHS
from .shading import Specular, shade

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
