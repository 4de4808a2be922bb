"""Built-in scenes of real size: ``meadow`` (N grass blades) and ``city-foliage`` (a city
block: large buildings among N small leaves).

Both take their size as scene parameters (``meadow:n=1000000``, ``city-foliage:n=200000:
seed=3``; see :func:`scenes.catalogue.builtin.builtin_scene`); every mesh is built with NumPy in one
pass (no loop over triangles), so a million blades take well under a second. The blades
and the leaves are each one mesh (one Mitsuba shape), as an engine would export a level's
grass: the shape ids stay few whatever N is.
"""

from __future__ import annotations

import numpy as np

from ..geometry import meshes
from .factories import ground, mesh, sensor, sun

__all__ = ["CITY_FOLIAGE_N", "MEADOW_N", "city_foliage", "grass_blades", "leaves", "meadow"]

#: Default blade count of ``meadow`` and leaf count of ``city-foliage`` (small: tests and the
#: catalogue's default resolution; ``meadow:n=1000000`` for content of real size).
MEADOW_N = 5000
CITY_FOLIAGE_N = 5000


def grass_blades(rng: np.random.Generator, n: int, *, half: float = 10.0):
    """``n`` one-triangle grass blades over ``[-half, half]^2`` on the ground ``y = 0``:
    0.02 wide at the base, 0.3-0.6 tall, random yaw and a random lean of up to 0.35 of
    the height. ``(vertices (3n, 3), faces (n, 3))``."""
    x = rng.uniform(-half, half, n)
    z = rng.uniform(-half, half, n)
    h = rng.uniform(0.3, 0.6, n)
    yaw = rng.uniform(0.0, np.pi, n)
    lean = rng.uniform(-0.35, 0.35, (n, 2)) * h[:, None]
    side = np.stack([np.cos(yaw), np.zeros(n), np.sin(yaw)], 1) * 0.01
    base = np.stack([x, np.zeros(n), z], 1)
    tip = base + np.stack([lean[:, 0], h, lean[:, 1]], 1)
    verts = np.stack([base - side, base + side, tip], 1).reshape(-1, 3)
    return verts, np.arange(3 * n, dtype=np.uint32).reshape(n, 3)


def meadow(width: int, height: int, *, n: int = MEADOW_N, seed: int = 1) -> dict:
    """A 24 x 24 ground quad and ``n`` grass blades over 20 x 20, one sun; the camera 14
    back and 4 up looks at the meadow's centre."""
    rng = np.random.default_rng([int(seed), 35])
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 4, -14), target=(0, 0, 0), fov=50, near=0.1, far=100
        ),
        "sun": sun((0.4, -0.8, 0.45)),
        "ground": ground(24.0, 0.45),
    }
    if n > 0:
        scene["grass"] = mesh(grass_blades(rng, int(n)), (0.25, 0.55, 0.2))
    return scene


def leaves(rng: np.random.Generator, n: int, centres: np.ndarray, radius: np.ndarray):
    """``n`` leaves (one triangle each, 0.08-0.16 across, random orientation) spread over
    spherical crowns (``centres (K, 3)``, ``radius (K,)``), crowns chosen at random.
    ``(vertices (3n, 3), faces (n, 3), crown (n,))``."""
    crown = rng.integers(0, len(centres), n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = radius[crown] * np.cbrt(rng.uniform(0.0, 1.0, n))
    p = centres[crown] + d * r[:, None]
    size = rng.uniform(0.08, 0.16, n)
    # two random unit directions spanning the leaf's plane
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(u, rng.normal(size=(n, 3)))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    a = p + u * size[:, None]
    b = p - 0.5 * u * size[:, None] + w * (0.8 * size[:, None])
    c = p - 0.5 * u * size[:, None] - w * (0.8 * size[:, None])
    verts = np.stack([a, b, c], 1).reshape(-1, 3)
    return verts, np.arange(3 * n, dtype=np.uint32).reshape(n, 3), crown


def _standing_box(lo, hi):
    """An axis-aligned box without its bottom face (it stands on the ground: no coplanar
    tie with it)."""
    v, f = meshes.box(lo, hi)
    return v, np.delete(f, [2, 8], axis=0)  # the two triangles of the face y = lo


def city_foliage(width: int, height: int, *, n: int = CITY_FOLIAGE_N, seed: int = 1) -> dict:
    """A city block: twelve buildings 6-30 tall around a street lined with sixteen trees
    whose crowns hold ``n`` leaves in all (large shadow casters among small ones). Each
    tree (trunk and leaves) is one mesh; buildings, trees and the ground are separated by
    planes, so the shapes have one depth order (exact coverage's layered path)."""
    rng = np.random.default_rng([int(seed), 36])
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(-6, 7, -30), target=(2, 5, 10), fov=60, near=0.1, far=300
        ),
        "sun": sun((-0.45, -0.8, 0.35)),
        "ground": ground(160.0, 0.5),
    }
    k = np.arange(6)
    for side, x in (("west", -16.0), ("east", 16.0)):
        for j, z in enumerate(k * 14.0 - 10.0):
            w, d = rng.uniform(7, 11), rng.uniform(8, 12)
            h = rng.uniform(6, 30)
            lo, hi = (x - w / 2, 0, z - d / 2), (x + w / 2, h, z + d / 2)
            scene[f"building_{side}_{j}"] = mesh(_standing_box(lo, hi), rng.uniform(0.3, 0.8, 3))
    tz = np.arange(8) * 9.0 - 8.0
    tx = np.array([-7.0, 7.0])
    base = np.stack(np.meshgrid(tx, tz, indexing="ij"), -1).reshape(-1, 2)
    trunk_h = rng.uniform(3.0, 4.5, len(base))
    radius = rng.uniform(1.8, 2.6, len(base))
    centres = np.column_stack([base[:, 0], trunk_h + 0.6 * radius, base[:, 1]])
    lv, lf, crown = leaves(rng, int(n), centres, radius)
    tri = lv[lf]
    for t, ((x, z), th) in enumerate(zip(base, trunk_h, strict=True)):  # 16 trees
        trunk = _standing_box((x - 0.2, 0, z - 0.2), (x + 0.2, th, z + 0.2))
        mine = tri[crown == t].reshape(-1, 3)
        crown_mesh = (mine, np.arange(len(mine), dtype=np.uint32).reshape(-1, 3))
        scene[f"tree_{t:02d}"] = mesh(meshes.merge([trunk, crown_mesh]), (0.2, 0.45, 0.15))
    return scene
