"""AGAA's per-pixel prepass work with one Dr.Jit lane a pixel (its samples in registers).

A lane reads its pixel's ``N`` samples once (:func:`..pixel_dr.slots`) and the rest runs on
registers: the fragment representatives (:func:`..pixel_dr.first_of_key`), the normals as
stored in the G-buffer format (:func:`..pixel_dr.store_normal`) and AGAA's clustering
(:func:`cluster_pixels`, the rule of :mod:`.model`), whose pixel means are pairwise sums
over the slots (:func:`pairwise_sum`).
"""

from __future__ import annotations

from .. import pixel_dr as _pixel_dr

__all__ = ["cluster_pixels", "pairwise_sum", "pixel_prepass"]


def pixel_prepass(mi, dr, samples, n: int, k: int, threshold, weight, fmt: str):
    """Fragment keys and aggregates of every pixel of a launch, one lane a pixel.

    ``samples`` is ``(valid, depth, prim, shape, normal)`` of the launch's samples, ``n``
    lanes a pixel (:func:`..trace.prepass_dr` with ``normals``). Returns lists over the
    sample slots of per-pixel UInt32 ``first`` (:func:`..pixel_dr.first_of_key`) and Int32
    aggregate (:func:`cluster_pixels` on the normals stored in ``fmt``), and the UInt32 mask
    of the fragment representatives (bit ``j``: slot ``j`` is the first of its fragment);
    unevaluated.
    """
    valid, depth, prim, shape, nrm = samples
    v = _pixel_dr.slots(mi, dr, mi.Bool, valid, n)
    first = _pixel_dr.first_of_key(
        mi,
        dr,
        v,
        _pixel_dr.slots(mi, dr, mi.Int32, shape, n),
        _pixel_dr.slots(mi, dr, mi.UInt32, prim, n),
    )
    stored = [
        _pixel_dr.store_normal(mi, dr, x, fmt) for x in _pixel_dr.slots(mi, dr, mi.Vector3f, nrm, n)
    ]
    z = _pixel_dr.slots(mi, dr, mi.Float, depth, n)
    agg = cluster_pixels(mi, dr, v, z, stored, k, threshold, weight)
    rep_bits = mi.UInt32(0)
    for j in range(n):
        rep_bits |= dr.select(v[j] & (first[j] == j), mi.UInt32(1 << j), 0)
    return first, agg, rep_bits


def pairwise_sum(xs: list):
    """Sum of one pixel's ``N`` values ``xs`` (a list over the slots) as a tree of halves,
    ``(x0 + x4) + (x2 + x6)`` ... for ``N = 8`` (a power of two), the value itself for
    ``N = 1``: a GPU's parallel reduction, with the error of a pairwise sum."""
    while len(xs) > 1:
        h = len(xs) // 2
        xs = [xs[i] + xs[i + h] for i in range(h)]
    return xs[0]


def cluster_pixels(mi, dr, valid, z, nrm, k: int, threshold, weight):
    """Aggregate (0 or 1; -1 sky, Int32) of each sample slot by AGAA's clustering
    (:mod:`.model`); ``valid``, ``z`` (view depth), ``nrm`` (stored normal, Vector3f) are
    lists over the pixel's slots. Distances are float32, the G-buffer's precision."""
    n = len(valid)
    vf = [dr.select(v, 1.0, 0.0) for v in valid]
    z = [z[j] * vf[j] for j in range(n)]
    cnt = dr.maximum(pairwise_sum(vf), 1.0)
    z_mean = pairwise_sum(z) / cnt
    z_mean = dr.select(z_mean > 0, z_mean, 1.0)
    n_mean = mi.Vector3f(
        *(pairwise_sum([nrm[j][c] * vf[j] for j in range(n)]) / cnt for c in range(3))
    )

    def dist(z_b, n_b):
        return [
            weight * dr.abs(z[j] - z_b) / z_mean + (1.0 - dr.dot(nrm[j], n_b)) for j in range(n)
        ]

    def argmax(d):
        top = d[0]
        for j in range(1, n):
            top = dr.maximum(top, d[j])
        seed = mi.UInt32(n - 1)
        for j in reversed(range(n)):
            seed = dr.select(d[j] == top, j, seed)
        return seed, top

    def at(values, slot, tp):
        out = tp(values[n - 1])
        for j in range(n - 1):
            out = dr.select(slot == j, values[j], out)
        return out

    low = -dr.inf
    d_mean = [dr.select(valid[j], dm, low) for j, dm in enumerate(dist(z_mean, n_mean))]
    seed1, _ = argmax(d_mean)
    d1 = dist(at(z, seed1, mi.Float), at(nrm, seed1, mi.Vector3f))
    seed2, top2 = argmax([dr.select(valid[j], d1[j], low) for j in range(n)])
    d2 = dist(at(z, seed2, mi.Float), at(nrm, seed2, mi.Vector3f))
    split = (top2 > threshold) if k >= 2 else mi.Bool(False)
    return [
        dr.select(valid[j], mi.Int32(dr.select(split & (d2[j] < d1[j]), 1, 0)), -1)
        for j in range(n)
    ]
