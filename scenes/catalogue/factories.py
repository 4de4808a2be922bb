"""Public dictionary helpers for building Mitsuba scene dictionaries: meshes with a diffuse
material (:func:`scenes.shading.materials.diffuse`), cameras (placed with
:func:`scenes.camera.look_at`), suns and grounds (the pieces every built-in scene and every
transformed scene is made of).

World up is +Y. Custom triangle meshes are ``{"type": "ro_mesh", "vertices": (V, 3),
"faces": (F, 3), "bsdf": ...}`` entries that :mod:`scenes.loader` turns into Mitsuba meshes.
"""

from __future__ import annotations

from ..camera import look_at
from ..geometry import meshes
from ..shading.materials import diffuse

__all__ = ["ground", "mesh", "sensor", "sun"]


def mesh(verts_faces, rgb) -> dict:
    """An ``ro_mesh`` entry: ``(vertices (V, 3), faces (F, 3))`` with a diffuse material."""
    v, f = verts_faces
    return {"type": "ro_mesh", "vertices": v, "faces": f, "bsdf": diffuse(rgb)}


def sensor(width, height, *, origin, target, fov, near, far, up=(0, 1, 0)) -> dict:
    """Perspective camera (horizontal ``fov`` in degrees) with a float32 box-filtered film."""
    return {
        "type": "perspective",
        "fov": float(fov),
        "fov_axis": "x",
        "near_clip": float(near),
        "far_clip": float(far),
        "to_world": look_at(origin, target, up),
        "film": {
            "type": "hdrfilm",
            "width": int(width),
            "height": int(height),
            "rfilter": {"type": "box"},
            "component_format": "float32",
        },
    }


def sun(direction, irradiance=3.0) -> dict:
    """Directional light travelling along ``direction`` with grey ``irradiance``."""
    return {
        "type": "directional",
        "direction": [float(c) for c in direction],
        "irradiance": {"type": "rgb", "value": [float(irradiance)] * 3},
    }


def ground(size: float, rgb=0.6, y: float = 0.0) -> dict:
    """A square ``size`` wide in the plane ``y``, centred on the origin."""
    h = size / 2
    return mesh(meshes.quad([[-h, y, -h], [-h, y, h], [h, y, h], [h, y, -h]]), rgb)
