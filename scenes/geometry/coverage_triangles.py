"""The triangles of a scene for exact coverage (:mod:`scenes.geometry.exact_coverage`):
mesh faces and rectangles as they are (float64 from Mitsuba's float32 vertices), curved
shapes (sphere, cylinder, disk) tessellated with a stated chord error (``slack``) chosen from
their size on the film."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import backend
from . import meshes as _meshes

__all__ = ["CURVED_ERROR_PX", "CURVED_SEGMENTS", "MEMO_KEY", "TriangleSet", "scene_triangle_set"]

#: Tessellation of curved shapes: segments around (spheres: and half as many from pole to
#: pole), chosen per shape so that the chord error is about :data:`CURVED_ERROR_PX` pixels
#: where the shape is nearest the camera, within these bounds. The chord error is a stated
#: bound (``slack``), turned into invalid pixels.
CURVED_SEGMENTS = (12, 192)
#: Chord error (pixels) the tessellation of a curved shape aims at.
CURVED_ERROR_PX = 0.25
#: Film margin (pixels) kept around the film when clipping projected triangles.
#: Key of the triangle sets in ``LoadedScene.memo`` (one per camera and film: the
#: tessellation of curved shapes follows their size on the film).
MEMO_KEY = "exact_coverage_triangles"


@dataclass(frozen=True)
class TriangleSet:
    """World-space triangles of a scene for exact coverage.

    tris : ``(T, 3, 3)`` float64; shape : ``(T,)`` Mitsuba shape index; slack : ``(T,)``
    largest distance (world units) between the triangle and the true surface it stands
    for (0 for mesh faces and rectangles; the chord error of a tessellated curved shape).
    """

    tris: np.ndarray
    shape: np.ndarray
    slack: np.ndarray


def _curved_mesh(mi, shape, n: int):
    """Inscribed tessellation ``(verts, faces, chord_error)`` of a sphere, cylinder or disk."""
    from .tessellation import tessellate_sphere as _tessellate_sphere

    kind = shape.class_name()
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    radius = float(np.linalg.norm(m[:3, 0]))
    if kind == "Sphere":
        v, f = _tessellate_sphere(m[:3, 3], radius, n_phi=n, n_theta=n // 2)
        half = 0.5 * math.hypot(2 * math.pi / n, math.pi / (n // 2))
        return v, f, radius * (1.0 - math.cos(half))
    if kind == "Cylinder":
        v, f = _meshes.tube(m[:3, 3], m[:3, 3] + m[:3, 2], radius, sides=n)
        return v, f, radius * (1.0 - math.cos(math.pi / n))
    if kind == "Disk":
        ang = 2 * math.pi * np.arange(n) / n
        ring = np.stack([np.cos(ang), np.sin(ang), 0 * ang, 1 + 0 * ang], -1) @ m.T
        k = np.arange(n)
        f = np.stack([np.zeros(n), 1 + k, 1 + (k + 1) % n], -1).astype(np.uint32)
        return (
            np.concatenate([m[None, :3, 3], ring[:, :3]]),
            f,
            radius * (1 - math.cos(math.pi / n)),
        )
    raise ValueError(f"shape {shape.id()!r} of type {kind} has no exact-coverage geometry")


def _is_curved(mi, shape) -> bool:
    """Whether ``shape`` is tessellated here (sphere, cylinder, disk), not exact (a mesh or
    a rectangle)."""
    return not (shape.is_mesh() or shape.class_name() == "Rectangle")


def _pixels_per_unit(camera, lo, hi) -> float:
    """Film pixels per world unit at the nearest point of the box ``[lo, hi]`` (at least the
    near plane): a bound on how large a world distance there appears on the film."""
    if camera.kind != "perspective":
        return camera.width / (2.0 * camera.half_extent()[0])
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    inside = np.all((camera.position >= lo) & (camera.position <= hi))
    depth = (
        camera.near
        if inside
        else max(camera.near, float(((corners - camera.position) @ camera.forward).min()))
    )
    return camera.width / (2.0 * camera.tan_half_x) / depth


def _segments(mi, shape, camera) -> int:
    """Tessellation segments of a curved shape: chord error about :data:`CURVED_ERROR_PX`."""
    bb = shape.bbox()
    lo = np.array(bb.min, dtype=np.float64).ravel()[:3]
    hi = np.array(bb.max, dtype=np.float64).ravel()[:3]
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    r_px = float(np.linalg.norm(m[:3, 0])) * _pixels_per_unit(camera, lo, hi)
    # chord error r (1 - cos a) ~ r a^2 / 2 for a half-angle a = sqrt(2) pi / n (spheres)
    n = math.sqrt(2.0) * math.pi / math.sqrt(2.0 * CURVED_ERROR_PX / max(r_px, 1e-9))
    lo_n, hi_n = CURVED_SEGMENTS
    return int(min(max(2 * math.ceil(n / 2), lo_n), hi_n))


def scene_triangle_set(loaded) -> TriangleSet:
    """The :class:`TriangleSet` of ``loaded`` for its camera (memoised in ``loaded.memo``)."""
    cam = loaded.camera
    mi = backend.mitsuba()
    curved = any(_is_curved(mi, sh) for sh in loaded.mi_scene.shapes())
    # only a curved shape's tessellation depends on the camera
    key = (cam.to_world.tobytes(), cam.width, cam.height, cam.fov_x) if curved else "planar"
    memo = loaded.memo.setdefault(MEMO_KEY, {})
    cached = memo.get(key)
    if cached is not None:
        return cached
    from .tessellation import shape_mesh

    parts, shape_of, slack = [], [], []
    for i, sh in enumerate(loaded.mi_scene.shapes()):  # a loop over shapes, not triangles
        if not _is_curved(mi, sh):
            v, f = shape_mesh(mi, sh)
            err = 0.0
        else:
            v, f, err = _curved_mesh(mi, sh, _segments(mi, sh, cam))
        tris = np.asarray(v, dtype=np.float64)[np.asarray(f, dtype=np.int64)]
        parts.append(tris)
        shape_of.append(np.full(len(tris), i, dtype=np.int64))
        slack.append(np.full(len(tris), err))
    out = TriangleSet(
        np.concatenate(parts) if parts else np.zeros((0, 3, 3)),
        np.concatenate(shape_of) if parts else np.zeros(0, np.int64),
        np.concatenate(slack) if parts else np.zeros(0),
    )
    memo[key] = out
    return out
