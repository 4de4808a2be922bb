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

__all__ = ["PAIR_ROWS", "POLY_CHUNK", "convex_arrays", "convex_overlaps", "visible_segments"]

#: Polygons whose edges are resolved per pass (their candidate pairs are queried together).
POLY_CHUNK = 512
#: Candidate pairs a pass resolves at most: a pass of :data:`POLY_CHUNK` dense polygons
#: (thousands overlapping each) is cut into passes of fewer polygons (a deadline or a signal
#: is checked between passes).
PAIR_ROWS = 1 << 16
#: Distance (px) within which two edges count as collinear, and relative parallelism.
COLLINEAR_PX = 1e-10
PARALLEL_REL = 1e-12
#: The compiled passes, once :func:`_kernel` has built them.
_COMPILED: dict = {}


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


def _z_order(v, count):
    """The polygons sorted by the Z-order (Morton) code of their first vertex on a
    1024 x 1024 grid over their extent."""
    if len(v) == 0:
        return np.zeros(0, np.int64)
    xy = v[:, 0, :]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    q = ((xy - lo) / np.maximum(hi - lo, 1e-9) * 1023).astype(np.int64)
    code = np.zeros(len(q), np.int64)
    for bit in range(10):  # a loop over bits
        code |= ((q[:, 0] >> bit) & 1) << (2 * bit) | ((q[:, 1] >> bit) & 1) << (2 * bit + 1)
    return np.argsort(code, kind="stable")


def _kernel(name: str = "clip"):
    """A compiled pass (numba, compiled once and cached on disk): ``"clip"``
    (:func:`_clip_pairs`), ``"segments"`` (:func:`_segment_events`) or ``"overlap"``
    (:func:`_overlap_pairs`)."""
    if not _COMPILED:
        import numba

        jit = numba.njit(cache=True, nogil=True)
        _COMPILED.update(
            clip=jit(_clip_pairs), segments=jit(_segment_events), overlap=jit(_overlap_pairs)
        )
    return _COMPILED[name]


def _clip_pairs(a, b, count, first_edge, e, poly, layer, number, out_i, out_f):
    """The rows (an edge of ``a[p]``, polygon ``b[p]``) of the clipping, one at a time: the
    parameter intervals of the edge whose left and right sides lie inside ``b[p]`` (the
    operations and their order of the NumPy version this replaced, so the same bits). Rows
    whose edge box misses the polygon's box, or whose intervals are both empty, are left out.

    e : per edge ``(x0, y0, x1, y1)``.
    poly : per polygon its box ``(x0, y0, x1, y1)``, then ``(ux, uy, c)`` of each half-plane
        (:func:`_half_planes`): one row, so one polygon's data share cache lines.
    number : the polygons' numbers in the caller's order (of two twins the later yields).
    out_i, out_f : per kept row ``(edge, b)`` and ``(l_lo, l_hi, r_lo, r_hi)`` (NaN where
        empty). Returns the number of rows kept.
    """
    n = 0
    for p in range(a.shape[0]):
        pa, pb = a[p], b[p]
        la, lb = layer[pa], layer[pb]
        earlier = la == lb and number[pb] < number[pa]
        for k in range(count[pa]):
            g = first_edge[pa] + k
            x0, y0, x1, y1 = e[g, 0], e[g, 1], e[g, 2], e[g, 3]
            if (
                min(x0, x1) > poly[pb, 2]
                or max(x0, x1) < poly[pb, 0]
                or min(y0, y1) > poly[pb, 3]
                or max(y0, y1) < poly[pb, 1]
            ):
                continue
            dx, dy = x1 - x0, y1 - y0
            dlen = -1.0  # hypot(dx, dy), computed where a slope is near the bound
            bound = PARALLEL_REL * (abs(dx) + abs(dy))  # >= PARALLEL_REL * hypot(dx, dy)
            lo, hi = -np.inf, np.inf
            left_out, right_out = False, False
            for j in range(count[pb]):
                ux, uy, c = poly[pb, 4 + 3 * j], poly[pb, 5 + 3 * j], poly[pb, 6 + 3 * j]
                d0 = ux * y0 - uy * x0 - c
                slope = ux * dy - uy * dx
                parallel = False
                if abs(slope) <= bound:
                    if dlen < 0.0:
                        dlen = np.hypot(dx, dy)
                    parallel = abs(slope) <= PARALLEL_REL * dlen
                if parallel:
                    if abs(d0) <= COLLINEAR_PX:
                        if ux * dx + uy * dy > 0:
                            right_out = right_out or not earlier
                        else:
                            left_out = True
                    elif d0 <= 0:
                        left_out, right_out = True, True
                else:
                    t = -d0 / slope
                    if slope > 0:
                        lo = max(lo, t)
                    elif slope < 0:
                        hi = min(hi, t)
                    if min(max(hi, 0.0), 1.0) <= min(max(lo, 0.0), 1.0):
                        break  # empty whatever the other lines say
            lo, hi = min(max(lo, 0.0), 1.0), min(max(hi, 0.0), 1.0)
            if hi > lo and not (left_out and right_out):
                out_i[n, 0], out_i[n, 1] = g, pb
                out_f[n, 0] = np.nan if left_out else lo
                out_f[n, 1] = np.nan if left_out else hi
                out_f[n, 2] = np.nan if right_out else lo
                out_f[n, 3] = np.nan if right_out else hi
                n += 1
    return n


def _segments_of(a, b=None, *, b_in=False, groups=None):
    """Per group, the elementary intervals where the union of the intervals ``a`` holds and
    that of ``b`` does not (``b_in``: does); ``a``, ``b`` and the result are
    ``(group, lo, hi)``, groups ``0 .. groups - 1`` (default: one more than the largest).
    Exact: events sorted per group, running counts (:func:`_segment_events`); the result is
    sorted by group, then position."""
    z = np.zeros(0)
    ga, alo, ahi = a
    gb, blo, bhi = b if b is not None else (np.zeros(0, np.int64), z, z)
    ga, gb = np.ascontiguousarray(ga, np.int64), np.ascontiguousarray(gb, np.int64)
    if groups is None:
        groups = int(max(ga.max(initial=-1), gb.max(initial=-1))) + 1
    n = 2 * (len(ga) + len(gb))
    out_g, out_x = np.empty(n, np.int64), np.empty((n, 2))
    f = [np.ascontiguousarray(x, np.float64) for x in (alo, ahi, blo, bhi)]
    m = _kernel("segments")(ga, f[0], f[1], gb, f[2], f[3], bool(b_in), groups, out_g, out_x)
    return out_g[:m], out_x[:m, 0].copy(), out_x[:m, 1].copy()


def _segment_events(ga, alo, ahi, gb, blo, bhi, b_in, groups, out_g, out_x):
    """:func:`_segments_of`, compiled: the interval ends as events (+1 / -1 for ``a`` and for
    ``b``) put in their groups by a counting sort, sorted by position within a group, and
    swept with running counts; a piece between consecutive distinct positions is kept where
    ``a``'s count is positive and ``b``'s is zero (``b_in``: positive). The order of equal
    positions changes no count between distinct ones. Returns the number of pieces."""
    start = np.zeros(groups + 1, np.int64)
    for i in range(ga.shape[0]):
        start[ga[i] + 1] += 2
    for i in range(gb.shape[0]):
        start[gb[i] + 1] += 2
    for k in range(groups):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    n = start[groups]
    pos, da, db = np.empty(n), np.zeros(n, np.int64), np.zeros(n, np.int64)
    for i in range(ga.shape[0]):
        k = fill[ga[i]]
        pos[k], pos[k + 1], da[k], da[k + 1] = alo[i], ahi[i], 1, -1
        fill[ga[i]] = k + 2
    for i in range(gb.shape[0]):
        k = fill[gb[i]]
        pos[k], pos[k + 1], db[k], db[k + 1] = blo[i], bhi[i], 1, -1
        fill[gb[i]] = k + 2
    m = 0
    for grp in range(groups):
        s0, s1 = start[grp], start[grp + 1]
        if s1 == s0:
            continue
        o = np.argsort(pos[s0:s1]) + s0
        ca, cb = 0, 0
        for q in range(s1 - s0 - 1):
            i, j = o[q], o[q + 1]
            ca += da[i]
            cb += db[i]
            want = ca > 0 and (cb > 0 if b_in else cb <= 0)
            if want and pos[j] > pos[i]:
                out_g[m], out_x[m, 0], out_x[m, 1] = grp, pos[i], pos[j]
                m += 1
    return m


def visible_segments(v, count, layer, tag, pairs, *, check=None):
    """Directed boundary segments ``(x0, y0, x1, y1, tag)`` of the visible regions.

    v, count : :func:`convex_arrays` of the polygons; layer, tag : ``(N,)`` int.
    pairs : a callable ``pairs(idx) -> (a, b)``: the candidate polygons ``b`` (bounding
        boxes overlapping) of each polygon ``a`` in ``idx``, ``a != b``, both ways.
    check : called between chunks (lets a signal handler run).
    """
    # polygons renumbered along a Z curve: a chunk's candidates are near each other in memory
    order = _z_order(v, count)
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    v, count, layer, tag = v[order], count[order], np.asarray(layer)[order], tag[order]
    p0, p1, owner = _edges(v, count)
    first_edge = np.cumsum(count) - count
    layer_tag = dict(zip(layer.tolist(), tag.tolist(), strict=True))  # one shape a layer
    e = np.ascontiguousarray(np.concatenate([p0, p1], axis=1))  # (E, 4)
    count, first_edge = count.astype(np.int64), first_edge.astype(np.int64)
    layer = np.asarray(layer, np.int64)
    lo_xy = np.where(np.arange(v.shape[1])[None, :, None] < count[:, None, None], v, np.inf)
    hi_xy = np.where(np.arange(v.shape[1])[None, :, None] < count[:, None, None], v, -np.inf)
    box = [lo_xy.min(axis=1), hi_xy.max(axis=1)]
    hp = np.stack(_half_planes(v, count), axis=-1).reshape(len(count), -1)  # (N, 3K)
    poly = np.ascontiguousarray(np.concatenate([*box, hp], axis=1))
    geo = (p0, p1, owner, first_edge, e, poly, count, layer, tag, layer_tag, order)
    out = []
    n = len(count)
    start, step = 0, POLY_CHUNK
    while start < n:
        if check is not None:
            check()
        idx = np.arange(start, min(n, start + step))
        a, b = pairs(order[idx])
        if len(a) > PAIR_ROWS and len(idx) > 1:  # dense: fewer polygons a pass
            step = max(1, len(idx) * PAIR_ROWS // len(a))
            continue
        out.append(_chunk(inv[a], inv[b], idx, geo))
        start += len(idx)
    if not out:
        z = np.zeros(0)
        return z, z, z, z, np.zeros(0, np.int64)
    return tuple(np.concatenate(parts) for parts in zip(*out, strict=True))


def _chunk(a, b, idx, geo):
    """:func:`visible_segments` for the edges of the polygons ``idx`` (candidates ``b`` of
    each ``a``)."""
    p0, p1, owner, first_edge, e, poly, count, layer, tag, layer_tag, order = geo
    # one row per (edge of a, polygon b) whose boxes overlap and whose clip is not empty
    rows = int(count[a].sum())
    out_i, out_f = np.empty((rows, 2), np.int64), np.empty((rows, 4))
    a, b = np.ascontiguousarray(a, np.int64), np.ascontiguousarray(b, np.int64)
    m = _kernel("clip")(a, b, count, first_edge, e, poly, layer, order, out_i, out_f)
    edge, bb = out_i[:m, 0], out_i[:m, 1]
    l_lo, l_hi, r_lo, r_hi = out_f[:m].T
    la, lb = layer[owner[edge]], layer[bb]
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
    full = (np.arange(ne), np.zeros(ne), np.ones(ne))
    g, lo, hi = _segments_of(full, (drop_g, drop_lo, drop_hi), groups=ne)
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
            hit = _segments_of(remaining, cover, b_in=True, groups=ne)
            if len(hit[0]):
                t = np.full(len(hit[0]), layer_tag[m])
                segs.append(_emit(hit[0] + e_first, hit[1], hit[2], p0, p1, t, reverse=True))
            remaining = _segments_of(remaining, cover, groups=ne)
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


def convex_overlaps(v, count, a, b):
    """The overlaps of the convex polygons ``a[p]`` and ``b[p]`` (:func:`convex_arrays`):
    their vertices ``(M, 2)``, the pair each belongs to ``(M,)`` and each pair's area
    ``(P,)`` (``a[p]`` clipped by the half-planes of ``b[p]``, Sutherland-Hodgman)."""
    hp = np.stack(_half_planes(v, count), axis=-1).reshape(len(count), -1)
    a, b = np.ascontiguousarray(a, np.int64), np.ascontiguousarray(b, np.int64)
    cap = int((count[a] + count[b]).sum())
    xy, owner, area = np.empty((cap, 2)), np.empty(cap, np.int64), np.empty(len(a))
    v = np.ascontiguousarray(v, np.float64)
    k = v.shape[1]
    work = np.empty((2, 2 * k + 2, 2))
    m = _kernel("overlap")(a, b, np.asarray(count, np.int64), v, hp, xy, owner, area, work)
    return xy[:m], owner[:m], area


def _overlap_pairs(a, b, count, v, hp, xy, owner, area, work):
    """:func:`convex_overlaps`, compiled: per pair the polygon ``a`` clipped in turn by each
    half-plane of ``b`` (kept where the signed distance is >= 0), into ``work``; writes the
    vertices and areas, returns the number of vertices."""
    m = 0
    for p in range(a.shape[0]):
        pa, pb = a[p], b[p]
        n = count[pa]
        cur = 0
        for i in range(n):
            work[0, i, 0], work[0, i, 1] = v[pa, i, 0], v[pa, i, 1]
        for j in range(count[pb]):
            ux, uy, c = hp[pb, 3 * j], hp[pb, 3 * j + 1], hp[pb, 3 * j + 2]
            nxt, k = 1 - cur, 0
            for i in range(n):
                x0, y0 = work[cur, i, 0], work[cur, i, 1]
                i1 = i + 1 if i + 1 < n else 0
                x1, y1 = work[cur, i1, 0], work[cur, i1, 1]
                d0, d1 = ux * y0 - uy * x0 - c, ux * y1 - uy * x1 - c
                if d0 >= 0:
                    work[nxt, k, 0], work[nxt, k, 1] = x0, y0
                    k += 1
                if (d0 >= 0) != (d1 >= 0):
                    t = d0 / (d0 - d1)
                    work[nxt, k, 0], work[nxt, k, 1] = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
                    k += 1
            cur, n = nxt, k
            if n == 0:
                break
        s = 0.0
        for i in range(n):
            i1 = i + 1 if i + 1 < n else 0
            s += work[cur, i, 0] * work[cur, i1, 1] - work[cur, i1, 0] * work[cur, i, 1]
            xy[m, 0], xy[m, 1], owner[m] = work[cur, i, 0], work[cur, i, 1], p
            m += 1
        area[p] = 0.5 * abs(s)
    return m
