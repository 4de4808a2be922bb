"""Visible boundaries of layered convex polygons without polygon booleans: the fast path of
:mod:`scenes.geometry.exact_coverage`.

Input: convex film polygons, each with a *layer* (its shape's rank in a depth order that
holds wherever two shapes overlap: a shape of lower layer is in front) and a *tag* (its
shape). The visible region of a shape is where the nearest polygon covering a point is one
of its own; its area inside each pixel follows from Green's theorem over its boundary
(:mod:`scenes.geometry.pixel_area`). That boundary is made of pieces of the polygons' own edges:

- a piece of an edge of polygon ``A`` (layer ``j``, interior on its left) is dropped where a
  polygon of a nearer layer covers its left side (hidden), or a polygon of layer ``<= j``
  covers its right side (inside the union of its layer, or hidden);
- what is left bounds ``A``'s shape on its left (``+``, tag of ``A``) and, on its right, the
  nearest layer ``m > j`` covering that side, if any (``-``, tag of ``m``: the same piece
  reversed).

Each test is a clip of a segment against a convex polygon's half-planes: a parameter
interval along the edge; collinear edges decide by the side their polygon's interior lies
on (two identical polygons of one layer: the later one yields to the earlier). Interval
unions and differences per edge use sorted events and running counts (exact, linear).
Everything is vectorised over chunks of polygon pairs; memory stays bounded by the chunk.

The result equals the polygon-boolean path (visible polygons, unions, differences) up to
float64 rounding of the crossing points (about 1e-13 px).
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["POLY_CHUNK", "ROW_CHUNK", "convex_arrays", "visible_segments"]

#: Polygons whose edges are resolved per pass (their candidate pairs are queried together).
POLY_CHUNK = 512
#: Rows (an edge against a candidate polygon) per NumPy pass of the clipping.
ROW_CHUNK = 131_072
#: Distance (px) within which two edges count as collinear, and relative parallelism.
COLLINEAR_PX = 1e-10
PARALLEL_REL = 1e-12


def convex_arrays(polys) -> tuple[np.ndarray, np.ndarray]:
    """Padded counter-clockwise vertices ``(N, K, 2)`` and vertex counts ``(N,)`` of convex
    shapely polygons (interior on the left of each edge, in the given coordinates)."""
    ring = shapely.get_exterior_ring(np.asarray(polys, dtype=object))
    xy, owner = shapely.get_coordinates(ring, return_index=True)
    n = len(polys)
    total = np.bincount(owner, minlength=n)
    count = np.maximum(total - 1, 0)  # rings repeat their first vertex
    start = np.cumsum(total) - total
    k = np.arange(len(xy)) - np.repeat(start, total)
    keep = k < np.repeat(count, total)
    kmax = int(count.max()) if n else 0
    v = np.zeros((n, max(kmax, 1), 2))
    v[owner[keep], k[keep]] = xy[keep]
    kk = np.arange(v.shape[1])[None, :]
    nxt = np.take_along_axis(v, ((kk + 1) % np.maximum(count[:, None], 1))[..., None], 1)
    cross = v[..., 0] * nxt[..., 1] - nxt[..., 0] * v[..., 1]
    flip = np.where(kk < count[:, None], cross, 0.0).sum(axis=1) < 0
    if flip.any():
        c = np.maximum(count[flip, None], 1)
        rev = (c - 1 - kk) % c
        v[flip] = np.take_along_axis(v[flip], rev[..., None], 1)
    return v, count


def _edges(v, count):
    """Directed edges of the polygons: start ``(E, 2)``, end ``(E, 2)``, owner ``(E,)``."""
    n, kmax = v.shape[:2]
    owner = np.repeat(np.arange(n), count)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    p0 = v[owner, k]
    p1 = v[owner, (k + 1) % count[owner]]
    return p0, p1, owner


def _half_planes(v, count):
    """Per polygon and edge the unit direction ``(ux, uy)`` and offset ``c`` of its line:
    ``ux y - uy x - c`` is the signed distance (px) of ``(x, y)``, > 0 inside. Padding
    edges read 1 everywhere (no constraint)."""
    kk = np.arange(v.shape[1])[None, :]
    valid = kk < count[:, None]
    nxt = np.take_along_axis(v, ((kk + 1) % np.maximum(count[:, None], 1))[..., None], 1)
    u = nxt - v
    length = np.hypot(u[..., 0], u[..., 1])
    ok = valid & (length > 0)
    ux = np.where(ok, u[..., 0] / np.where(ok, length, 1.0), 0.0)
    uy = np.where(ok, u[..., 1] / np.where(ok, length, 1.0), 0.0)
    c = np.where(ok, ux * v[..., 1] - uy * v[..., 0], -1.0)
    return ux, uy, c


def _clip_rows(p0, d, hp, bb, same_layer_earlier):
    """Parameter intervals of the segments ``p0 + s d`` (``s`` in [0, 1]) whose left and
    right sides lie inside polygon ``bb`` (half-planes ``hp``): ``(l_lo, l_hi, r_lo,
    r_hi)``, NaN where empty."""
    ux, uy, c = (x[bb] for x in hp)
    d0 = ux * p0[:, 1, None] - uy * p0[:, 0, None] - c
    slope = ux * d[:, 1, None] - uy * d[:, 0, None]
    dlen = np.hypot(d[:, 0], d[:, 1])[:, None]
    parallel = np.abs(slope) <= PARALLEL_REL * dlen
    collinear = parallel & (np.abs(d0) <= COLLINEAR_PX)
    same_dir = (ux * d[:, 0, None] + uy * d[:, 1, None]) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -d0 / slope
    lo = np.where(~parallel & (slope > 0), t, -np.inf).max(axis=1)
    hi = np.where(~parallel & (slope < 0), t, np.inf).min(axis=1)
    out_par = parallel & ~collinear & (d0 <= 0)
    # collinear: the left side is inside when both run the same way, the right side when
    # they run opposite ways; same-way twins of one layer: the earlier polygon keeps it
    left_out = np.any((collinear & ~same_dir) | out_par, axis=1)
    right_out = np.any((collinear & same_dir & ~same_layer_earlier[:, None]) | out_par, axis=1)
    lo, hi = np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)
    some = hi > lo
    left, right = some & ~left_out, some & ~right_out
    return (
        np.where(left, lo, np.nan),
        np.where(left, hi, np.nan),
        np.where(right, lo, np.nan),
        np.where(right, hi, np.nan),
    )


def _segments_of(a, b=None, *, b_in=False):
    """Per group, the elementary intervals where the union of the intervals ``a`` holds and
    that of ``b`` does not (``b_in``: does); ``a``, ``b`` and the result are
    ``(group, lo, hi)``. Exact: events sorted per group, running counts (each group's events
    sum to zero)."""
    ga, alo, ahi = a
    gb, blo, bhi = b if b is not None else (np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    na, nb = len(ga), len(gb)
    g = np.concatenate([ga, ga, gb, gb]).astype(np.int64)
    pos = np.concatenate([alo, ahi, blo, bhi])
    da = np.concatenate([np.ones(na), -np.ones(na), np.zeros(2 * nb)])
    db = np.concatenate([np.zeros(2 * na), np.ones(nb), -np.ones(nb)])
    order = np.lexsort((pos, g))
    g, pos = g[order], pos[order]
    ca, cb = np.cumsum(da[order]), np.cumsum(db[order])
    nxt_same = np.concatenate([g[1:] == g[:-1], [False]])
    pos_next = np.concatenate([pos[1:], [0.0]])
    want = (ca > 0.5) & ((cb > 0.5) if b_in else (cb < 0.5))
    keep = nxt_same & want & (pos_next > pos)
    return g[keep], pos[keep], pos_next[keep]


def visible_segments(v, count, layer, tag, pairs, *, check=None):
    """Directed boundary segments ``(x0, y0, x1, y1, tag)`` of the visible regions.

    v, count : :func:`convex_arrays` of the polygons; layer, tag : ``(N,)`` int.
    pairs : a callable ``pairs(idx) -> (a, b)``: the candidate polygons ``b`` (bounding
        boxes overlapping) of each polygon ``a`` in ``idx``, ``a != b``, both ways.
    check : called between chunks (lets a signal handler run).
    """
    p0, p1, owner = _edges(v, count)
    first_edge = np.cumsum(count) - count
    layer_tag = dict(zip(layer.tolist(), tag.tolist(), strict=True))  # one shape a layer
    hp = _half_planes(v, count)
    lo_xy = np.where(np.arange(v.shape[1])[None, :, None] < count[:, None, None], v, np.inf)
    hi_xy = np.where(np.arange(v.shape[1])[None, :, None] < count[:, None, None], v, -np.inf)
    box = np.concatenate([lo_xy.min(axis=1), hi_xy.max(axis=1)], axis=1)  # (N, 4)
    geo = (p0, p1, owner, first_edge, hp, box, count, layer, tag, layer_tag)
    out = []
    n = len(count)
    for start in range(0, n, POLY_CHUNK):
        if check is not None:
            check()
        idx = np.arange(start, min(n, start + POLY_CHUNK))
        a, b = pairs(idx)
        out.append(_chunk(a, b, idx, geo))
    if not out:
        z = np.zeros(0)
        return z, z, z, z, np.zeros(0, np.int64)
    return tuple(np.concatenate(parts) for parts in zip(*out, strict=True))


def _chunk(a, b, idx, geo):
    """:func:`visible_segments` for the edges of the polygons ``idx`` (candidates ``b`` of
    each ``a``)."""
    p0, p1, owner, first_edge, hp, box, count, layer, tag, layer_tag = geo
    # one row per (edge of a, polygon b) whose bounding boxes overlap
    ca = count[a]
    row_pair = np.repeat(np.arange(len(a)), ca)
    k = np.arange(len(row_pair)) - np.repeat(np.cumsum(ca) - ca, ca)
    edge = first_edge[a[row_pair]] + k
    bb = b[row_pair]
    e0, e1 = p0[edge], p1[edge]
    bx = box[bb]
    near = (
        (np.minimum(e0[:, 0], e1[:, 0]) <= bx[:, 2])
        & (np.maximum(e0[:, 0], e1[:, 0]) >= bx[:, 0])
        & (np.minimum(e0[:, 1], e1[:, 1]) <= bx[:, 3])
        & (np.maximum(e0[:, 1], e1[:, 1]) >= bx[:, 1])
    )
    edge, bb, e0, e1 = edge[near], bb[near], e0[near], e1[near]
    la, lb = layer[owner[edge]], layer[bb]
    earlier = (lb == la) & (bb < owner[edge])
    l_lo, l_hi, r_lo, r_hi = (np.full(len(edge), np.nan) for _ in range(4))
    kb = count[bb]
    for k in np.unique(kb):  # rows by the candidate's vertex count: no padding work
        rows = np.flatnonzero(kb == k)
        hp_k = tuple(x[:, :k] for x in hp)
        for lo in range(0, len(rows), ROW_CHUNK):
            r = rows[lo : lo + ROW_CHUNK]
            out = _clip_rows(e0[r], e1[r] - e0[r], hp_k, bb[r], earlier[r])
            l_lo[r], l_hi[r], r_lo[r], r_hi[r] = out
    # edges of this chunk, numbered locally
    e_first = first_edge[idx[0]]
    e_all = np.arange(e_first, first_edge[idx[-1]] + count[idx[-1]])
    local = edge - e_first
    # dropped: left side under a nearer layer, right side under a nearer or the same layer
    lh = (lb < la) & ~np.isnan(l_lo)
    rh = (lb <= la) & ~np.isnan(r_lo)
    drop_g = np.concatenate([local[lh], local[rh]])
    drop_lo = np.concatenate([l_lo[lh], r_lo[rh]])
    drop_hi = np.concatenate([l_hi[lh], r_hi[rh]])
    ne = len(e_all)
    g, lo, hi = _segments_of((np.arange(ne), np.zeros(ne), np.ones(ne)), (drop_g, drop_lo, drop_hi))
    segs = [_emit(g + e_first, lo, hi, p0, p1, tag[owner[g + e_first]], reverse=False)]
    del l_lo, l_hi
    # the far side: the nearest farther layer covering the right side of what is left
    far = (lb > la) & ~np.isnan(r_lo)
    if far.any():
        fg, flo, fhi, fl = local[far], r_lo[far], r_hi[far], lb[far]
        remaining = (g, lo, hi)
        for m in np.unique(fl):  # a loop over layers present, not over triangles
            sel = fl == m
            cover = (fg[sel], flo[sel], fhi[sel])
            hit = _segments_of(remaining, cover, b_in=True)
            if len(hit[0]):
                t = np.full(len(hit[0]), layer_tag[m])
                segs.append(_emit(hit[0] + e_first, hit[1], hit[2], p0, p1, t, reverse=True))
            remaining = _segments_of(remaining, cover)
            if not len(remaining[0]):
                break
    return tuple(np.concatenate(parts) for parts in zip(*segs, strict=True))


def _emit(edge, lo, hi, p0, p1, t, *, reverse):
    """Segments ``p(lo) -> p(hi)`` along ``edge`` (reversed: ``p(hi) -> p(lo)``)."""
    d = p1[edge] - p0[edge]
    a = p0[edge] + lo[:, None] * d
    b = p0[edge] + hi[:, None] * d
    # the ends exactly at the edge's own vertices where the interval reaches them
    a = np.where((lo == 0.0)[:, None], p0[edge], a)
    b = np.where((hi == 1.0)[:, None], p1[edge], b)
    if reverse:
        a, b = b, a
    return a[:, 0], a[:, 1], b[:, 0], b[:, 1], np.asarray(t, np.int64)
