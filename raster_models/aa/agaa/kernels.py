"""AGAA's frame on the Dr.Jit side: prepass, aggregates, material accumulation and shading
chained per launch, with only per-pixel results copied back to NumPy.

Per launch of at most :data:`LAUNCH_CHUNKS` x :data:`..trace.CHUNK` samples (whole pixels):

1. the samples' nearest surfaces (:func:`..trace.prepass_dr`), then, one lane a pixel, its
   fragment representatives and aggregates (:func:`.pixels.pixel_prepass`);
2. the fragments (representative lanes, :func:`drjit.compress`) and their attributes
   (:func:`..trace.attributes_dr`, zero where the ray misses);
3. one lane a pixel: every aggregate's weighted material sums over its (fragment,
   aggregate) pairs, in sample-slot order, and its float32 averages; each existing
   aggregate shaded once (:func:`..trace.shade_dr`, filtered normal) with its *filtered
   visibility* (:func:`filtered_visibility`): the mean over the aggregate's samples of the
   light visibility at each sample's own surface point (the oracle's exact shadow ray from
   the hit, with its mesh offset, :func:`..trace.sample_visibility_dr`; or a shadow
   technique's ``visibility`` there, the launch's sample points copied to NumPy once); the
   pixel's coverage-weighted colour, summed in float64 and rounded to float32 once.

Why filtered visibility: AGAA pre-filters every shading input of an aggregate over its
samples and shades the aggregate once, and its authors filter the shadowing too ("Shadowing
must be filtered; account for aggregate depth extent; avoids temporal issues when a sample's
cluster changes": Crassin et al., AGAA, I3D 2015, and the NVIDIA HQ rasterization slides,
Wyman 2015). One shadow ray from the aggregate's mean position tests a point that lies on no
surface when the aggregate spans a crease or a depth step (``stripes``: behind the strips, so
every K = 1 pixel was black); the samples' own points lie on their surfaces.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ....scenes import backend
from ....scenes.backend.raycast import shape_table
from .. import pixel_dr as _pixel_dr
from .. import trace as _trace
from . import pixels as _agaa_pixels

__all__ = ["CHANNELS", "LAUNCH_CHUNKS", "filtered_visibility", "render"]

#: Attribute channels summed per aggregate (the averages are stored per aggregate in this
#: order, then its shadow-ray offset and its sample count).
CHANNELS = ("albedo", "normal", "position", "to_eye", "geo_normal")
#: The further channels of a glTF scene ((metallic, roughness, 0) and emissive), averaged
#: like the albedo (the base colour there) and stored after :data:`CHANNELS`.
PBR_CHANNELS = ("material", "emissive")


def _channels(scene) -> tuple[str, ...]:
    return CHANNELS + (PBR_CHANNELS if scene.pbr is not None else ())


#: Prepass samples a launch, in :data:`..trace.CHUNK` s (``1 << 23``): every launch
#: generates its kernels' code again (the intersection and BSDF calls of every shape), so
#: fewer, larger launches save time; peak memory at 1920x1080 x 8 samples is about 1.1 GiB,
#: under the oracle's own bound (``oracle.reference.render``'s ``SAMPLES_PER_CHUNK``: about
#: 1.5 GiB).
LAUNCH_CHUNKS = 4


def render(
    scene,
    offsets,
    *,
    k: int,
    threshold: float,
    depth_weight: float,
    fmt: str,
    visibility: Callable[[dict], np.ndarray] | None = None,
):
    """AGAA's frame.

    Parameters
    ----------
    offsets : ``(N, 2)`` standard sample positions in the pixel (y down).
    k, threshold, depth_weight, fmt : the clustering (:class:`.model.AgaaParams`).
    visibility : None for the oracle's exact shadow ray from every sample's own surface
        point, or a function of the samples' surface points (a dict of ``(S, 3)`` float32
        ``position``, ``normal``, ``geo_normal`` and ``(S,)`` ``valid``, float64 view
        ``depth``) returning their light visibility in [0, 1] (a shadow technique,
        :func:`..common.shadow_visibility`). Either way each aggregate is shaded with the
        mean over its samples (:func:`filtered_visibility`).

    Returns
    -------
    dict of per-pixel NumPy arrays (row-major, ``(P,)``): ``color`` ``(P, 3)`` float32
    linear radiance, ``covered`` (samples hitting a surface), ``aggregates`` and
    ``surfaces`` (fragments), and ``shadow_rays`` (int: one per sample given a shadow test,
    0 with ``visibility``).
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
            scene, scene.mi_scene, table, ox, oy, local + start, n, normals=True, group=False
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
        vis_s, shadow = _sample_visibility(mi, dr, scene, local + start, ox, oy, n, visibility)
        rays += shadow
        f_vis = filtered_visibility(mi, dr, vis_s, agg, k)
        rgb32 = _shade_resolve(mi, dr, scene, store, exists, n, f_vis)
        sl = slice(p0, p1)
        color[sl] = _trace.to_numpy(rgb32).T
        counts["aggregates"][sl] = _trace.to_numpy(n_agg)
        counts["surfaces"][sl] = _trace.to_numpy(surfaces)
        counts["covered"][sl] = _trace.to_numpy(covered)
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
    for key in _channels(scene):
        table_f += [dr.select(hit, c, 0.0) for c in attrs[key]]
    offset_f = dr.select(hit, attrs["offset"], 0.0)
    dr.eval(table_f, offset_f)
    return table_f, offset_f


def _aggregates(mi, dr, first, agg, rep_bits, frag_base, table_f, offset_f, k):
    """Per pixel lane and aggregate index: the averaged attributes (:data:`CHANNELS`), the
    shadow-ray offset and the samples held (``store[a]``, a list of Float), and whether the
    aggregate exists. Each (fragment, aggregate) pair, taken at its first sample slot, adds
    its fragment's attributes times the samples it owns, in slot order."""
    n = len(first)
    sums = {a: [mi.Float(0.0) for _ in table_f] for a in range(k)}
    offset_max = {a: mi.Float(0.0) for a in range(k)}  # offsets are positive
    weights = {a: mi.Float(0.0) for a in range(k)}  # samples each aggregate holds
    for j in range(n):
        same = [(first[i] == first[j]) & (agg[i] == agg[j]) for i in range(n)]
        pair_rep = first[j] < n
        for i in range(j):
            pair_rep &= ~same[i]
        pair_count = sum(dr.select(same[i] & (first[i] < n), mi.UInt32(1), 0) for i in range(n))
        below = (mi.UInt32(1) << first[j]) - 1
        f = frag_base + dr.popcnt(rep_bits & below)
        wt = mi.Float(pair_count)
        row = [dr.gather(mi.Float, c, f, pair_rep) * wt for c in table_f]
        off = dr.gather(mi.Float, offset_f, f, pair_rep)
        for a in range(k):
            on = pair_rep & (agg[j] == a)
            sums[a] = [dr.select(on, s + r, s) for s, r in zip(sums[a], row, strict=True)]
            offset_max[a] = dr.select(on, dr.maximum(offset_max[a], off), offset_max[a])
            weights[a] = weights[a] + dr.select(on, wt, 0.0)
    store = [_averages(dr, sums[a], weights[a], offset_max[a]) for a in range(k)]
    return store, [weights[a] > 0.0 for a in range(k)]


def _averages(dr, sums, weight, offset):
    """An aggregate's stored record from its weighted sums: the averages in
    :data:`CHANNELS` order (geometric normal and eye direction normalized, the shading
    normal not), its shadow-ray offset and the samples it holds."""
    means = [c / weight for c in sums]
    keys = CHANNELS + PBR_CHANNELS[: len(sums) // 3 - len(CHANNELS)]  # a glTF scene's too
    m = {key: means[3 * i : 3 * i + 3] for i, key in enumerate(keys)}
    g = m["geo_normal"]
    g_len = dr.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    g_safe = dr.maximum(g_len, 1e-30)
    m["geo_normal"] = [dr.select(g_len > 1e-6, g[c] / g_safe, m["normal"][c]) for c in range(3)]
    e = m["to_eye"]
    e_len = dr.maximum(dr.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]), 1e-30)
    m["to_eye"] = [c / e_len for c in e]
    return [c for key in keys for c in m[key]] + [offset, weight]


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


#: Record fields of an aggregate (:func:`_averages`) the shading reads, as slices.
_RECORD = {
    "albedo": slice(0, 3),
    "normal": slice(3, 6),
    "position": slice(6, 9),
    "to_eye": slice(9, 12),
    "geo_normal": slice(12, 15),
    "material": slice(15, 18),  # glTF scenes only
    "emissive": slice(18, 21),
}


def _sample_visibility(mi, dr, scene, pix, ox, oy, n, visibility):
    """Light visibility (Float, one lane a sample, 0 on sky) at the surface point of every
    sample of the pixels ``pix`` (UInt32), evaluated, and the shadow rays cast: the
    oracle's exact ray from each hit (:func:`..trace.sample_visibility_dr`), or
    ``visibility`` (see :func:`render`) of the points copied to NumPy once."""
    w = scene.camera.width
    idx = dr.arange(mi.UInt32, dr.width(pix) * n)
    local = idx // n
    s = idx - local * n
    p = dr.gather(mi.UInt32, pix, local)
    x = mi.Float(p % w) + dr.gather(mi.Float, ox, s)
    y = mi.Float(p // w) + dr.gather(mi.Float, oy, s)
    if visibility is None:
        vis, tested = _trace.sample_visibility_dr(scene, x, y)
        count = dr.count(tested)
        dr.eval(vis, count)
        return vis, int(count[0])
    pts = _trace.sample_points_dr(scene, x, y)
    dr.eval(*pts.values())
    attrs = {key: _trace.to_numpy(v).T for key, v in pts.items() if key != "depth"}
    attrs["valid"] = _trace.to_numpy(pts["valid"]).astype(bool)
    attrs["depth"] = _trace.to_numpy(pts["depth"]).astype(np.float64)
    vis = np.where(attrs["valid"], np.asarray(visibility(attrs), np.float32), 0.0)
    return mi.Float(vis.astype(np.float32)), 0


def filtered_visibility(mi, dr, vis, agg, k: int) -> list:
    """Each aggregate's filtered visibility (a Float per aggregate index, one lane a pixel):
    the mean of the sample visibilities ``vis`` (one lane a sample) over the samples it
    holds (``agg``: the per-slot aggregates of :func:`.pixels.pixel_prepass`), summed in
    slot order in float32; 0 where the aggregate holds no sample."""
    n = len(agg)
    slots = _pixel_dr.slots(mi, dr, mi.Float, vis, n)
    out = []
    for a in range(k):
        total, held = mi.Float(0.0), mi.Float(0.0)
        for j in range(n):  # sample slots (at most 16 rounds)
            on = agg[j] == a
            total = total + dr.select(on, slots[j], 0.0)
            held = held + dr.select(on, 1.0, 0.0)
        out.append(total / dr.maximum(held, 1.0))
    return out


def _shade_resolve(mi, dr, scene, store, exists, n, f_vis):
    """Shading, once per aggregate with its filtered visibility ``f_vis`` (a Float per
    aggregate index, one lane a pixel), then the resolve: the coverage-weighted colours
    summed in float64 in aggregate order. Returns the pixels' Color3f (evaluated)."""
    n_lanes = dr.width(exists[0])
    idx = [dr.compress(e) for e in exists]
    acc = mi.Vector3d(0.0)
    for a, st in enumerate(store):
        if not dr.width(idx[a]):
            continue
        c = [dr.gather(mi.Float, v, idx[a]) for v in st]
        pbr = {}
        if scene.pbr is not None:
            pbr = {
                "material": mi.Vector3f(*c[_RECORD["material"]]),
                "emissive": mi.Color3f(*c[_RECORD["emissive"]]),
            }
        rgb, _ = _trace.shade_dr(
            scene,
            dr.full(mi.Bool, True, dr.width(idx[a])),
            mi.Point3f(*c[_RECORD["position"]]),
            mi.Vector3f(*c[_RECORD["normal"]]),
            mi.Vector3f(*c[_RECORD["geo_normal"]]),
            mi.Color3f(*c[_RECORD["albedo"]]),
            mi.Vector3f(*c[_RECORD["to_eye"]]),
            visibility=dr.gather(mi.Float, f_vis[a], idx[a]),
            filtered_normal=True,
            **pbr,
        )
        dr.eval(rgb)
        rgb_pix = dr.zeros(mi.Color3f, n_lanes)
        dr.scatter(rgb_pix, rgb, idx[a])
        share = mi.Float64(store[a][-1]) / n
        acc = dr.select(exists[a], acc + mi.Vector3d(rgb_pix) * share, acc)
    rgb32 = mi.Color3f(acc)
    dr.eval(rgb32)
    return rgb32
