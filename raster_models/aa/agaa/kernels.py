"""AGAA's frame on the Dr.Jit side: prepass, aggregates, material accumulation and shading
chained per launch, with only per-pixel results copied back to NumPy.

Per launch of at most :data:`LAUNCH_CHUNKS` x :data:`._trace.CHUNK` samples (whole pixels):

1. the samples' nearest surfaces (:func:`._trace.prepass_dr`), then, one lane a pixel, its
   fragment representatives and aggregates (:func:`._agaa_pixels.pixel_prepass`);
2. the fragments (representative lanes, :func:`drjit.compress`) and their attributes
   (:func:`._trace.attributes_dr`, zero where the ray misses, as
   :func:`._trace.fragment_attributes`);
3. one lane a pixel: every aggregate's weighted material sums over its (fragment,
   aggregate) pairs and its averages; each existing aggregate shaded once
   (:func:`._trace.shade_dr`, filtered normal, exact shadow ray); the pixel's
   coverage-weighted colour.

The arithmetic is that of the NumPy path of :func:`.agaa.run` (shadow techniques), operation
for operation, so the bytes are the same: the pairs of an aggregate are summed in float32 in
the order of ``np.add.reduceat`` (:func:`add_reduceat_order`), the averages divided and
normalized in float32 (a norm as ``np.linalg.norm``: ``sqrt((x^2 + y^2) + z^2)``), the
colour summed in float64 from 0 in slot order (``np.bincount``) and rounded to float32 once.
"""

from __future__ import annotations

import numpy as np

from scenes import backend
from scenes.raycast import shape_table

from .. import trace as _trace
from . import pixels as _agaa_pixels

__all__ = ["CHANNELS", "LAUNCH_CHUNKS", "add_reduceat_order", "render"]

#: Attribute channels summed per aggregate, in the NumPy path's table order (the averages
#: are stored per aggregate in this order, then its shadow-ray offset and its sample count).
CHANNELS = ("albedo", "normal", "position", "to_eye", "geo_normal")
#: Prepass samples a launch, in :data:`._trace.CHUNK` s (``1 << 23``): every launch
#: generates its kernels' code again (the intersection and BSDF calls of every shape), so
#: fewer, larger launches save time; peak memory at 1920x1080 x 8 samples is about 1.1 GiB
#: (the NumPy path's: 1.45 GiB), under the oracle's own bound (``oracle.reference.render``'s
#: ``SAMPLES_PER_CHUNK``: about 1.5 GiB).
LAUNCH_CHUNKS = 4
#: ``pairwise_sum`` of NumPy's float add: sums of fewer terms than this run left to right.
_PW_UNROLL = 8


def add_reduceat_order(dr, rows, active, at, n_rows: int):
    """Sum of ``rows`` in the order of ``np.add.reduceat`` on one segment.

    ``rows`` is a list of ``n_rows`` candidate rows (lists of arrays); ``active[i]`` says
    whether row ``i`` is in the segment and ``at[i]`` its position there (the segment is the
    active rows in list order). ``reduceat`` adds to the first row the ``pairwise_sum`` of
    the rest: left to right below :data:`_PW_UNROLL` terms, else the tree of eight partial
    sums ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))`` followed by the remaining
    terms left to right (at most 15 terms here, so one block). Returns ``(sum, count)``;
    the sum is undefined where ``count`` is 0.
    """
    width = len(rows[0])
    first = list(rows[0])
    rest = list(rows[0])
    tree = [list(rows[0]) for _ in range(_PW_UNROLL)]
    tail = [list(rows[0]) for _ in range(max(0, n_rows - 1 - _PW_UNROLL))]
    for i in range(n_rows):
        act, m, row = active[i], at[i], rows[i]
        is_first = act & (m == 0)
        is_second = act & (m == 1)
        later = act & (m >= 2)
        for c in range(width):
            first[c] = dr.select(is_first, row[c], first[c])
            rest[c] = dr.select(is_second, row[c], dr.select(later, rest[c] + row[c], rest[c]))
        if n_rows - 1 >= _PW_UNROLL:
            for j in range(_PW_UNROLL):
                hit = act & (m == j + 1)
                tree[j] = [dr.select(hit, row[c], tree[j][c]) for c in range(width)]
            for j in range(len(tail)):
                hit = act & (m == _PW_UNROLL + 1 + j)
                tail[j] = [dr.select(hit, row[c], tail[j][c]) for c in range(width)]
    count = at[-1] + dr.select(active[-1], 1, 0)
    n_rest = count - 1
    if n_rows - 1 >= _PW_UNROLL:
        t = tree
        blocked = [
            ((t[0][c] + t[1][c]) + (t[2][c] + t[3][c]))
            + ((t[4][c] + t[5][c]) + (t[6][c] + t[7][c]))
            for c in range(width)
        ]
        for j in range(len(tail)):
            more = n_rest > _PW_UNROLL + j
            blocked = [dr.select(more, blocked[c] + tail[j][c], blocked[c]) for c in range(width)]
        big = n_rest >= _PW_UNROLL
        rest = [dr.select(big, blocked[c], rest[c]) for c in range(width)]
    one = count <= 1
    return [dr.select(one, first[c], first[c] + rest[c]) for c in range(width)], count


def _norm(dr, v):
    """``np.linalg.norm`` of a float32 3-vector, operation for operation."""
    return dr.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])


def render(scene, offsets, *, k: int, threshold: float, depth_weight: float, fmt: str):
    """AGAA's frame with exact shadow rays.

    Returns a dict of per-pixel NumPy arrays (row-major, ``(P,)``): ``color`` ``(P, 3)``
    float32 linear radiance, ``covered`` (samples hitting a surface), ``aggregates`` and
    ``surfaces`` (fragments), and ``shadow_rays`` (int).
    """
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    offs = np.asarray(offsets, dtype=np.float32).reshape(-1, 2)
    n = len(offs)
    n_pix = cam.width * cam.height
    color = np.empty((n_pix, 3), np.float32)
    counts = {key: np.empty(n_pix, np.int64) for key in ("covered", "aggregates", "surfaces")}
    rays = 0
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    table = shape_table(mi, dr, scene)
    per_launch = max(1, LAUNCH_CHUNKS * _trace.CHUNK // n)
    for p0 in range(0, n_pix, per_launch):
        p1 = min(n_pix, p0 + per_launch)
        start = dr.opaque(mi.UInt32, p0)  # one kernel for every launch, not one per p0
        local = dr.arange(mi.UInt32, p1 - p0)
        valid, depth, prim, shape, nrm, _ = _trace.prepass_dr(
            scene,
            scene.mi_scene,
            table,
            ox,
            oy,
            local + start,
            n,
            normals=True,
            group=False,
            cluster=None,
        )
        first, agg, rep_bits = _agaa_pixels.pixel_prepass(
            mi, dr, (valid, depth, prim, shape, nrm), n, k, threshold, depth_weight, fmt
        )
        surfaces = dr.popcnt(rep_bits)
        covered = sum(dr.select(f < n, mi.UInt32(1), 0) for f in first)
        dr.eval(first, agg, rep_bits, surfaces, covered)

        table_f, offset_f = _fragment_table(mi, dr, scene, rep_bits, start, ox, oy, n)
        frag_base = dr.prefix_sum(surfaces)  # fragment ids in lane order, as compress gives
        store, exists = _aggregate_store(
            mi, dr, first, agg, rep_bits, frag_base, table_f, offset_f, k
        )
        n_agg = sum(dr.select(e, 1, 0) for e in exists)
        rgb32, shadow = _shade_resolve(mi, dr, scene, store, exists, p1 - p0, n)
        rays += shadow
        sl = slice(p0, p1)
        color[sl] = _trace._np(rgb32).T
        counts["aggregates"][sl] = _trace._np(n_agg)
        counts["surfaces"][sl] = _trace._np(surfaces)
        counts["covered"][sl] = _trace._np(covered)
    return {"color": color, **counts, "shadow_rays": rays}


def _fragment_table(mi, dr, scene, rep_bits, start, ox, oy, n):
    """Attributes of the launch's fragments (its representative samples in lane order),
    zero where the ray misses; ``(table, offset)``, the table in :data:`CHANNELS` order."""
    w = scene.camera.width
    idx = dr.arange(mi.UInt32, dr.width(rep_bits) * n)
    pix = idx // n
    slot = idx - pix * n
    lanes = dr.compress(((dr.gather(mi.UInt32, rep_bits, pix) >> slot) & 1) != 0)
    if dr.width(lanes) == 0:  # no surface in the launch: one dummy row, never gathered
        lanes = dr.zeros(mi.UInt32, 1)
    f_pix = lanes // n + start
    slot = lanes - (lanes // n) * n
    px, py = mi.Float(f_pix % w), mi.Float(f_pix // w)
    sx = px + dr.gather(mi.Float, ox, slot)
    sy = py + dr.gather(mi.Float, oy, slot)
    attrs = _trace.attributes_dr(scene, scene.mi_scene, sx, sy, px + 0.5, py + 0.5)
    hit = attrs["valid"]
    table_f = []
    for key in CHANNELS:
        table_f += [dr.select(hit, c, 0.0) for c in attrs[key]]
    offset_f = dr.select(hit, attrs["offset"], 0.0)
    dr.eval(table_f, offset_f)
    return table_f, offset_f


def _aggregates(mi, dr, first, agg, rep_bits, frag_base, table_f, offset_f, k):
    """Per pixel lane and aggregate index: the averaged attributes (:data:`CHANNELS`), the
    shadow-ray offset and the samples held (``store[a]``, a list of Float), and whether the
    aggregate exists. Each (fragment, aggregate) pair adds its fragment's attributes times
    the samples it owns, as :func:`._pixel_dr.fragments_of` pairs them."""
    n = len(first)
    rows, act = [], {a: [] for a in range(k)}
    at = {a: [] for a in range(k)}
    seen = {a: mi.UInt32(0) for a in range(k)}
    offset_max = {a: mi.Float(0.0) for a in range(k)}
    weights = {a: mi.Float(0.0) for a in range(k)}  # samples each aggregate holds
    for j in range(n):
        valid_j = first[j] < n
        same = [(first[i] == first[j]) & (agg[i] == agg[j]) for i in range(n)]
        pair_rep = valid_j
        for i in range(j):
            pair_rep &= ~same[i]
        pair_count = sum(dr.select(same[i] & (first[i] < n), mi.UInt32(1), 0) for i in range(n))
        below = (mi.UInt32(1) << first[j]) - 1
        f = frag_base + dr.popcnt(rep_bits & below)
        wt = mi.Float(pair_count)
        row = [dr.gather(mi.Float, c, f, pair_rep) * wt for c in table_f]
        off = dr.gather(mi.Float, offset_f, f, pair_rep)
        rows.append(row)
        for a in range(k):
            on = pair_rep & (agg[j] == a)
            act[a].append(on)
            at[a].append(seen[a])
            offset_max[a] = dr.select(
                on, dr.select(seen[a] == 0, off, dr.maximum(offset_max[a], off)), offset_max[a]
            )
            seen[a] = seen[a] + dr.select(on, 1, 0)
            weights[a] = weights[a] + dr.select(on, wt, 0.0)
    store, exists = [], []
    for a in range(k):
        sums, count = add_reduceat_order(dr, rows, act[a], at[a], n)
        store.append(_averages(dr, sums, weights[a], offset_max[a]))
        exists.append(count > 0)
    return store, exists


def _averages(dr, sums, weight, offset):
    """An aggregate's stored record from its weighted sums: the averages in
    :data:`CHANNELS` order (geometric normal and eye direction normalized, the shading
    normal not), its shadow-ray offset and the samples it holds."""
    means = [c / weight for c in sums]
    m = {key: means[3 * i : 3 * i + 3] for i, key in enumerate(CHANNELS)}
    g = m["geo_normal"]
    g_len = _norm(dr, g)
    g_safe = dr.maximum(g_len, 1e-30)
    m["geo_normal"] = [dr.select(g_len > 1e-6, g[c] / g_safe, m["normal"][c]) for c in range(3)]
    e = m["to_eye"]
    e_len = dr.maximum(_norm(dr, e), 1e-30)
    m["to_eye"] = [c / e_len for c in e]
    return [c for key in CHANNELS for c in m[key]] + [offset, weight]


def _aggregate_store(mi, dr, first, agg, rep_bits, frag_base, table_f, offset_f, k):
    """:func:`_aggregates` for every pixel of the launch, evaluated. Most pixels hold
    one (fragment, aggregate) pair per aggregate (one surface an aggregate): their sum is
    that fragment's row times its samples, two gathers of the fragment table a pixel
    instead of one per sample slot; the other pixels take the general path, compacted, and
    are scattered over them."""
    n = len(first)
    store, exists, simple = [], [], mi.Bool(True)
    for a in range(k):
        lead = mi.UInt32(n)  # the aggregate's first sample (agg is -1 on sky)
        for j in reversed(range(n)):
            lead = dr.select(agg[j] == a, j, lead)
        key = mi.UInt32(n)  # its fragment's first sample
        for j in range(n):
            key = dr.select(lead == j, first[j], key)
        held = mi.UInt32(0)
        for j in range(n):
            in_a = agg[j] == a
            simple &= ~in_a | (first[j] == key)
            held += dr.select(in_a, 1, 0)
        on = lead < n
        f = frag_base + dr.popcnt(rep_bits & ((mi.UInt32(1) << key) - 1))
        weight = mi.Float(held)
        sums = [dr.gather(mi.Float, c, f, on) * weight for c in table_f]
        store.append(_averages(dr, sums, weight, dr.gather(mi.Float, offset_f, f, on)))
        exists.append(on)
    dr.eval(store, exists, simple)
    idx = dr.compress(~simple)
    if dr.width(idx):

        def sub(x):
            return dr.gather(type(x), x, idx)

        s_store, s_exists = _aggregates(
            mi,
            dr,
            [sub(x) for x in first],
            [sub(x) for x in agg],
            sub(rep_bits),
            sub(frag_base),
            table_f,
            offset_f,
            k,
        )
        for a in range(k):
            for dst, val in zip(store[a], s_store[a], strict=True):
                dr.scatter(dst, val, idx)
            dr.scatter(exists[a], s_exists[a], idx)
        dr.eval(store, exists)
    return store, exists


def _shade_resolve(mi, dr, scene, store, exists, n_lanes, n):
    """Shading, once per aggregate (exact shadow ray from its average position), then the
    resolve: float64 from 0, aggregates in slot order, as ``np.bincount``. Returns the
    pixels' Color3f (evaluated) and the shadow rays cast."""
    acc = mi.Vector3d(0.0)
    rays = 0
    for a in range(len(store)):
        idx = dr.compress(exists[a])
        if not dr.width(idx):
            continue
        c = [dr.gather(mi.Float, s, idx) for s in store[a]]
        rgb, cand = _trace.shade_dr(
            scene,
            dr.full(mi.Bool, True, dr.width(idx)),
            mi.Point3f(*c[6:9]),
            mi.Vector3f(*c[3:6]),
            mi.Vector3f(*c[12:15]),
            mi.Color3f(*c[0:3]),
            mi.Vector3f(*c[9:12]),
            offset=c[15],
            filtered_normal=True,
        )
        count = dr.count(cand)
        dr.eval(rgb, count)
        rays += int(count[0])
        rgb_pix = dr.zeros(mi.Color3f, n_lanes)
        dr.scatter(rgb_pix, rgb, idx)
        share = mi.Float64(store[a][-1]) / n
        acc = dr.select(exists[a], acc + mi.Vector3d(rgb_pix) * share, acc)
    # 0 + x is +0 for x = -0 in bincount's accumulator
    acc = dr.select(acc == 0.0, 0.0, acc)
    rgb32 = mi.Color3f(acc)
    dr.eval(rgb32)
    return rgb32, rays
