"""NumPy triangle-mesh generators for the built-in scenes (vertices (V, 3), faces (F, 3))."""

from __future__ import annotations

import numpy as np

__all__ = ["box", "merge", "quad", "siemens_star", "tube", "blades"]


def quad(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles over four corners given in order around the quad."""
    v = np.asarray(corners, dtype=np.float64).reshape(4, 3)
    return v, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box with outward-facing triangles (24 vertices, flat faces)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float)
    c = lo + c * (hi - lo)
    # faces as corner indices, counter-clockwise seen from outside
    faces4 = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    verts = np.concatenate([c[list(f)] for f in faces4])
    base = np.arange(6, dtype=np.uint32)[:, None] * 4
    tri = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    return verts, tri.astype(np.uint32)


def merge(parts) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate several (vertices, faces) meshes into one."""
    verts, faces, offset = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(verts), np.concatenate(faces).astype(np.uint32)


def siemens_star(center, radius: float, spokes: int, *, right, up) -> tuple[np.ndarray, np.ndarray]:
    """A Siemens star: ``spokes`` filled wedges (each one triangle) in the plane (right, up)."""
    center, right, up = (np.asarray(a, float) for a in (center, right, up))
    k = np.arange(spokes)
    a0 = 2 * np.pi * k / spokes
    a1 = a0 + np.pi / spokes
    p0 = center + radius * (np.cos(a0)[:, None] * right + np.sin(a0)[:, None] * up)
    p1 = center + radius * (np.cos(a1)[:, None] * right + np.sin(a1)[:, None] * up)
    verts = np.concatenate([center[None], p0, p1])
    faces = np.stack([np.zeros(spokes), 1 + k, 1 + spokes + k], axis=1)
    return verts, faces.astype(np.uint32)


def tube(p0, p1, radius: float, *, sides: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """An open prism of ``sides`` faces around the segment p0 -> p1 (a wire)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    axis /= np.linalg.norm(axis)
    helper = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w)
    verts = np.concatenate([p0 + ring, p1 + ring])
    i = np.arange(sides)
    j = (i + 1) % sides
    faces = np.concatenate([np.stack([i, j, sides + j], 1), np.stack([i, sides + j, sides + i], 1)])
    return verts, faces.astype(np.uint32)


def blades(
    rng: np.random.Generator, n: int, *, x_range, z_range, height, width
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` grass blades: thin upright triangles, randomly placed, leaning and rotated."""
    x = rng.uniform(*x_range, n)
    z = rng.uniform(*z_range, n)
    h = rng.uniform(0.6, 1.0, n) * height
    yaw = rng.uniform(0, np.pi, n)
    lean = rng.uniform(-0.3, 0.3, (n, 2)) * h[:, None]
    side = np.stack([np.cos(yaw), np.zeros(n), np.sin(yaw)], 1) * (width / 2)
    base = np.stack([x, np.zeros(n), z], 1)
    tip = base + np.stack([lean[:, 0], h, lean[:, 1]], 1)
    verts = np.stack([base - side, base + side, tip], 1).reshape(-1, 3)
    faces = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
    return verts, faces
