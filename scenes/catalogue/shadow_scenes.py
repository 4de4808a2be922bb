"""Built-in shadow scenes: plate, city, thin, star, curved, spot and point.

Each is a factory ``factory(width, height) -> dict`` returning a Mitsuba scene dictionary made
with :mod:`scenes.catalogue.factories`; :mod:`scenes.catalogue.builtin` catalogues them.
"""

from __future__ import annotations

import numpy as np

from ..camera import look_at
from ..geometry import meshes
from ..shading.materials import diffuse
from .factories import ground, mesh, sensor, sun

__all__ = ["curved", "city", "plate", "point", "spot", "star", "thin"]


def plate(width: int, height: int) -> dict:
    """A square plate 1.5 above a ground plane, sun from the side: one clean hard shadow."""
    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 6, 7), target=(0.8, 0, 0), fov=50, near=0.1, far=100
        ),
        "sun": sun((0.55, -1.0, 0.2)),
        "ground": ground(30.0, 0.6),
        "plate": mesh(
            meshes.quad([[-1, 1.5, -1], [-1, 1.5, 1], [1, 1.5, 1], [1, 1.5, -1]]), (0.7, 0.3, 0.2)
        ),
    }


def city(width: int, height: int) -> dict:
    """A city of 196 boxes on a 4 km ground plane at street level; far/near = 2e4."""
    rng = np.random.default_rng(7)
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0.5, 4.0, -2.0), target=(14, 10, 300), fov=70, near=0.1, far=2000
        ),
        "sun": sun((-0.3, -1.0, 0.3)),
        "ground": ground(4000.0, 0.5),
    }
    xs = np.arange(-7, 7) * 24.0 + 12.0
    zs = np.arange(0, 14) * 30.0 + 15.0
    for i, x in enumerate(xs):
        for j, z in enumerate(zs):
            w, d = rng.uniform(6, 14, 2)
            h = rng.uniform(4, 45)
            lo, hi = (x - w / 2, 0, z - d / 2), (x + w / 2, h, z + d / 2)
            albedo = rng.uniform(0.3, 0.8, 3)
            scene[f"building_{i:02d}_{j:02d}"] = mesh(meshes.box(lo, hi), albedo)
    return scene


def thin(width: int, height: int) -> dict:
    """Fence slats, wires 0.05-3 px wide at several depths and grass: many surfaces a pixel."""
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 1.2, -6), target=(0, 1.0, 10), fov=60, near=0.05, far=200
        ),
        "sun": sun((0.3, -0.7, 0.6)),
        "ground": ground(200.0, 0.45),
    }
    slats = [
        meshes.box((x - 0.02, 0, 2.0), (x + 0.02, 1.6, 2.04)) for x in np.arange(-4, 4.01, 0.18)
    ]
    scene["fence"] = mesh(meshes.merge(slats), (0.8, 0.75, 0.6))
    scene["fence_rail"] = mesh(meshes.box((-4.1, 1.2, 1.96), (4.1, 1.26, 1.98)), (0.7, 0.6, 0.5))
    # Wires: width in pixels = 2 r / (depth * 2 tan(fov/2) / width_px); at the default 320 px
    # width and fov 60 deg one pixel spans 0.0036 * depth.
    px_per_unit = width / (2 * np.tan(np.radians(30)))
    for k, (depth, px) in enumerate([(4, 3.0), (8, 1.0), (15, 0.3), (30, 0.1), (45, 0.05)]):
        r = px * (depth + 6.0) / px_per_unit / 2  # view depth: the camera stands at z = -6
        y = 2.2 + 0.35 * k
        scene[f"wire_{k}"] = mesh(
            meshes.tube((-40, y, depth), (40, y + 0.3, depth), r), (0.15, 0.15, 0.15)
        )
    rng = np.random.default_rng(11)
    scene["grass"] = mesh(
        meshes.blades(rng, 3000, x_range=(-4, 4), z_range=(-2, 6), height=0.35, width=0.012),
        (0.25, 0.55, 0.2),
    )
    return scene


def star(width: int, height: int) -> dict:
    """A 36-spoke Siemens star and near-axis edges (0.5-3 deg off axis) against the sky."""
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 0, -10), target=(0, 0, 0), fov=40, near=0.1, far=100
        ),
        "sun": sun((0.2, -0.3, 1.0)),
        "star": mesh(
            meshes.siemens_star((-1.3, 0, 0), 1.5, 36, right=(-1, 0, 0), up=(0, 1, 0)), 0.8
        ),
    }
    for k, deg in enumerate([0.5, 1.0, 2.0, 3.0]):
        a = np.radians(deg)
        x0, y0 = 1.0 + 0.5 * k, -1.4
        c, s = np.cos(a), np.sin(a)
        w, h = 0.35, 2.8
        corners = np.array([[0, 0], [w, 0], [w, h], [0, h]]) @ np.array([[c, s], [-s, c]])
        pts = np.column_stack([x0 + corners[:, 0], y0 + corners[:, 1], np.zeros(4)])
        scene[f"edge_{k}"] = mesh(meshes.quad(pts), (0.9, 0.5, 0.2))
    return scene


def curved(width: int, height: int) -> dict:
    """A sphere casting onto a large curved receiver (a big sphere), sun at 40 deg."""
    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 4, 8), target=(0, 0.5, 0), fov=45, near=0.1, far=200
        ),
        "sun": sun((0.5, -0.8, -0.3)),
        "receiver": {
            "type": "sphere",
            "center": [0, -20, 0],
            "radius": 20.0,
            "bsdf": diffuse(0.6),
        },
        "caster": {
            "type": "sphere",
            "center": [0, 1.5, 0],
            "radius": 0.8,
            "bsdf": diffuse((0.3, 0.4, 0.8)),
        },
        "torus_like": {
            "type": "cylinder",
            "p0": [-2.5, 0.6, 1.0],
            "p1": [-0.8, 0.9, -1.5],
            "radius": 0.25,
            "bsdf": diffuse((0.8, 0.7, 0.2)),
        },
    }


def _props(seed: int):
    rng = np.random.default_rng(seed)
    parts = {}
    for k in range(6):
        x, z = rng.uniform(-3, 3, 2)
        s = rng.uniform(0.3, 0.8)
        h = rng.uniform(0.4, 2.0)
        parts[f"box_{k}"] = mesh(
            meshes.box((x - s, 0, z - s), (x + s, h, z + s)), rng.uniform(0.3, 0.8, 3)
        )
    return parts


def spot(width: int, height: int) -> dict:
    """Boxes and a plate lit by a spot light (cutoff 35 deg, beam 25 deg)."""
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 7, 9), target=(0, 0, 0), fov=50, near=0.1, far=100
        ),
        "spot": {
            "type": "spot",
            "to_world": look_at((2, 8, 1), (0, 0, 0), (0, 0, 1)),
            "intensity": {"type": "rgb", "value": [120.0] * 3},
            "cutoff_angle": 35.0,
            "beam_width": 25.0,
        },
        "ground": ground(40.0, 0.6),
        **_props(3),
    }
    return scene


def point(width: int, height: int) -> dict:
    """Boxes and a sphere around a point light 3 units above the ground."""
    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 8, 9), target=(0, 0, 0), fov=55, near=0.1, far=100
        ),
        "lamp": {
            "type": "point",
            "position": [0.5, 3.0, 0.2],
            "intensity": {"type": "rgb", "value": [40.0] * 3},
        },
        "ground": ground(40.0, 0.6),
        "ball": {
            "type": "sphere",
            "center": [-1.5, 0.7, 1.0],
            "radius": 0.7,
            "bsdf": diffuse((0.8, 0.3, 0.3)),
        },
        **_props(5),
    }
