"""Which samples of an ACAA prepass can tie with a group of shapes: a conservative proximity
test run before the group is traced, so the tie search traces only those samples.

A sample whose nearest surface lies at ``P`` (view depth ``z``) ties with a surface ``Q`` of
another shape only where both store the same depth: ``Q`` lies on the sample's ray within
``r(z)`` of ``P``, ``r`` the :func:`.groups.tie_distance` bound (``TIE_QUANTA`` quanta of
normalized depth over the smallest film-ray cosine, plus slack). ``Q`` lies in its shape's
bounding box, so ``P`` lies within ``r(z)`` of that box. The test here keeps every sample
with ``dist(P, box_k) <= radius(z)`` for some member ``k`` of the group, where ``radius`` is
twice ``r`` plus a float32 position error (:func:`tie_radius`): a
superset of the samples that can tie, which the tie search then traces and tests exactly.

Groups with few members test every member's box; larger groups look the members up in a
uniform grid (:class:`GroupFilter`): each cell lists the members whose box, grown by the
largest radius any of their ties can have, touches it (plus one cell of padding against
rounding), and a sample tests the boxes its cell lists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import depth as _depth
from .groups import TIE_QUANTA, TIE_SLACK, camera_key

__all__ = [
    "GroupFilter",
    "group_filters",
    "near_dr",
    "point_radius_dr",
    "radius_constants",
    "tie_radius",
]

#: Groups with at most this many members test each member's box directly (no grid).
DIRECT_MEMBERS = 8
#: Cells of a group's grid (at most).
GRID_CELLS = 1 << 18
#: Members a grid cell lists at most; a sample in a cell listing more is always kept.
CELL_LIST = 32
#: Relative error allowed for hit positions computed in float32 (the prepass's ``o + t d``
#: and the tie's alike: a few roundings of the larger of their coordinates and depth).
POSITION_ERROR = 1e-5
#: Tie radii at or beyond this fraction of the depth where the tie window becomes unbounded
#: (``c z -> 1``, see :func:`tie_radius`) count as unbounded: every such sample is kept.
UNBOUNDED_CZ = 0.5


def radius_constants(camera, fmt: str):
    """``(c, cos_min, ortho_r)`` of the tie radius: ``far(z) - z = c z^2 / (1 - c z)`` for
    a perspective camera (``1/far = 1/z - c``), ``ortho_r`` for an orthographic one."""
    kind, bits = _depth.FORMATS[fmt]
    q = 1.0 / ((1 << bits) - 1) if kind == "unorm" else 2.0**-23  # as groups.tie_distance
    n, f = camera.near, camera.far
    if camera.kind == "perspective":
        t = camera.tan_half_x
        cos_min = 1.0 / math.sqrt(1.0 + t * t + (t / camera.aspect) ** 2)
        return TIE_QUANTA * q * (f - n) / (f * n), cos_min, None
    return 0.0, 1.0, TIE_QUANTA * q * (f - n)


def tie_radius(camera, fmt: str, z, p_max, *, xp=np):
    """Tie radius (world units, ``inf`` where unbounded) of samples at view depth ``z``
    whose hit position has largest absolute coordinate ``p_max``.

    ``2 r(z) + 2 TIE_SLACK + POSITION_ERROR (|z| + p_max)``, with ``r(z) = c z'^2 / (1 - c
    z') / cos_min``, ``z' = max(z, near)`` (the depth bound of :func:`.groups.tie_distance`
    in closed form; orthographic: ``TIE_QUANTA q (f - n)``); increasing in ``z`` and
    ``p_max``. ``xp`` is the array module of ``z`` and ``p_max``: ``numpy`` (float64
    arrays: the grid's bounds) or ``drjit`` (Float: every sample of the prepass, in float32,
    where the factor 2 on ``r`` covers float32's relative error many times over).
    """
    c, cos_min, ortho_r = radius_constants(camera, fmt)
    where = np.where if xp is np else xp.select
    slack = 2.0 * TIE_SLACK + POSITION_ERROR * (xp.abs(z) + p_max)
    if ortho_r is not None:
        return 2.0 * ortho_r + slack
    zc = xp.maximum(z, camera.near)
    cz = c * zc
    bounded = cz < UNBOUNDED_CZ
    r = c * zc * zc / where(bounded, 1.0 - cz, 1.0) / cos_min
    return where(bounded, 2.0 * r + slack, xp.inf)


def point_radius_dr(dr, camera, fmt: str, z, p):
    """:func:`tie_radius` of Dr.Jit samples at view depth ``z`` (Float) and position ``p``
    (Point3f)."""
    p_max = dr.maximum(dr.maximum(dr.abs(p.x), dr.abs(p.y)), dr.abs(p.z))
    return tie_radius(camera, fmt, z, p_max, xp=dr)


@dataclass(frozen=True)
class GroupFilter:
    """Proximity test of one tie group: ``everything`` (keep every sample), the member boxes
    (``lo``, ``hi``: ``(M, 3)`` float32) and, for a large group, a grid: origin ``origin``,
    cell size ``cell``, ``dims``, and per cell the members whose grown box touches it
    (``starts`` ``(cells + 1,)`` offsets into ``members``)."""

    everything: bool
    lo: np.ndarray
    hi: np.ndarray
    origin: np.ndarray | None = None
    cell: float = 0.0
    dims: tuple = ()
    starts: np.ndarray | None = None
    members: np.ndarray | None = None
    longest: int = 0


def _grid_shape(extent: np.ndarray) -> tuple[float, np.ndarray]:
    """Cubic cell size and cell counts covering ``extent`` with at most :data:`GRID_CELLS`
    cells (shrinking the cell while the count allows; a list-length loop)."""
    cell = max(float(extent.max()), 1e-6) / GRID_CELLS ** (1.0 / 3.0)
    dims = np.maximum(1, np.ceil(extent / cell)).astype(np.int64)
    for _ in range(64):
        finer = np.maximum(1, np.ceil(extent / (cell * 0.8))).astype(np.int64)
        if int(np.prod(finer)) > GRID_CELLS:
            break
        cell, dims = cell * 0.8, finer
    return cell, dims


def _build(scene, members: list[int], fmt: str) -> GroupFilter:
    cam = scene.camera
    shapes = scene.mi_scene.shapes()
    lo = np.array([[float(c) for c in shapes[k].bbox().min] for k in members], np.float64)
    hi = np.array([[float(c) for c in shapes[k].bbox().max] for k in members], np.float64)
    lo, hi = lo.reshape(-1, 3), hi.reshape(-1, 3)
    boxes = (lo.astype(np.float32), hi.astype(np.float32))
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        return GroupFilter(True, *boxes)
    if len(members) <= DIRECT_MEMBERS:
        return GroupFilter(False, *boxes)
    corners = np.stack([np.where(np.array(m, bool), hi, lo) for m in np.ndindex(2, 2, 2)], 1)
    zfar = ((corners - cam.position) @ cam.forward).max(axis=1)
    p_max = np.abs(corners).max(axis=(1, 2))
    # a tie of member k has its sample within r0 of the box (view depth <= zfar, up to
    # rounding), so its coordinates within p_max + r0
    z_bound = np.abs(zfar) * 1.01 + 1.0
    r0 = tie_radius(cam, fmt, z_bound, p_max)
    grow = tie_radius(cam, fmt, z_bound, p_max + r0) * 1.01
    if not np.isfinite(grow).all():
        return GroupFilter(True, *boxes)
    glo, ghi = lo - grow[:, None], hi + grow[:, None]
    cell, dims = _grid_shape(ghi.max(axis=0) - glo.min(axis=0))
    dims = dims + 2  # one cell of padding on each side
    origin = glo.min(axis=0) - cell
    i0 = np.clip(np.floor((glo - origin) / cell).astype(np.int64) - 1, 0, dims - 1)
    i1 = np.clip(np.floor((ghi - origin) / cell).astype(np.int64) + 1, 0, dims - 1)
    cells, owner = [], []
    for m in range(len(members)):  # one block of cells per member (a list-length loop)
        block = np.stack(
            np.meshgrid(*(np.arange(i0[m, a], i1[m, a] + 1) for a in range(3)), indexing="ij"),
            -1,
        ).reshape(-1, 3)
        cells.append(np.ravel_multi_index(block.T, tuple(dims)))
        owner.append(np.full(len(block), m, np.int64))
    cells_all, owner_all = np.concatenate(cells), np.concatenate(owner)
    order = np.argsort(cells_all, kind="stable")
    counts = np.bincount(cells_all, minlength=int(np.prod(dims)))
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.uint32)
    return GroupFilter(
        False,
        *boxes,
        origin=origin.astype(np.float32),
        cell=float(cell),
        dims=tuple(int(d) for d in dims),
        starts=starts,
        members=owner_all[order].astype(np.uint32),
        longest=int(counts.max()),
    )


def group_filters(scene, groups: list[list[int]], fmt: str) -> list[GroupFilter]:
    """One :class:`GroupFilter` per tie group, memoized in ``scene.memo`` for the last
    (camera, format, groups): the grid's radii depend on the camera."""
    key = (fmt, camera_key(scene.camera), tuple(tuple(g) for g in groups))
    slot = scene.memo.get("acaa.group_filters")
    if slot is None or slot[0] != key:
        slot = (key, [_build(scene, g, fmt) for g in groups])
        scene.memo["acaa.group_filters"] = slot
    return slot[1]


def _dist2(dr, p, lo, hi):
    d = [dr.maximum(dr.maximum(lo[a] - p[a], p[a] - hi[a]), 0.0) for a in range(3)]
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2]


def near_dr(mi, dr, filt: GroupFilter, p, radius, active=True):
    """Bool: the ``active`` points ``p`` (Point3f) within ``radius`` (Float) of a member's
    box."""
    n = dr.width(p.x)
    if filt.everything:
        return dr.full(mi.Bool, True, n) & active
    r2 = radius * radius
    if filt.starts is None:
        near = dr.full(mi.Bool, False, n)
        for m in range(len(filt.lo)):  # a few members (list-length rounds)
            near |= _dist2(dr, p, filt.lo[m].tolist(), filt.hi[m].tolist()) <= r2
        return near & active
    u = [(p[a] - float(filt.origin[a])) * (1.0 / filt.cell) for a in range(3)]
    inside = dr.full(mi.Bool, True, n) & active
    for a in range(3):
        inside &= (u[a] >= 0.0) & (u[a] < float(filt.dims[a]))
    idx = [mi.UInt32(dr.select(inside, u[a], 0.0)) for a in range(3)]
    cell = (idx[0] * filt.dims[1] + idx[1]) * filt.dims[2] + idx[2]
    starts = mi.UInt32(filt.starts)
    first = dr.gather(mi.UInt32, starts, cell, inside)
    count = dr.gather(mi.UInt32, starts, cell + 1, inside) - first
    near = inside & (count > CELL_LIST)
    members = mi.UInt32(filt.members)
    lo = [mi.Float(np.ascontiguousarray(filt.lo[:, a])) for a in range(3)]
    hi = [mi.Float(np.ascontiguousarray(filt.hi[:, a])) for a in range(3)]
    for j in range(min(filt.longest, CELL_LIST)):  # list-length rounds
        act = inside & (count > j)
        k = dr.gather(mi.UInt32, members, first + j, act)
        blo = [dr.gather(mi.Float, lo[a], k, act) for a in range(3)]
        bhi = [dr.gather(mi.Float, hi[a], k, act) for a in range(3)]
        near |= act & (_dist2(dr, p, blo, bhi) <= r2)
    return near
