"""AGAA's per-pixel prepass work with one Dr.Jit lane a pixel (its samples in registers).

:mod:`._pixel_dr` does the same work with one lane a *sample*: every pixel-wide quantity is
a block reduction gathered back to ``N`` lanes and every "sample ``j`` of my pixel" a
gather, ``O(N^2)`` memory reads a pixel. Here a lane reads its pixel's ``N`` samples once
and the rest runs on registers. The rules and the float32 operations are those of
:func:`._pixel_dr.first_of_key` and :func:`._pixel_dr.aggregate_of`, in their order:
the pixel sums of :func:`drjit.block_reduce` (``mode="evaluated"``) are pairwise sums of
halves (``(x0 + x4) + (x2 + x6)`` ... for ``N = 8``; a zero sum is +0) for ``N >= 2`` and the
sample itself for ``N = 1``, which :func:`block_sum` repeats; tested equal sample for sample.
"""

from __future__ import annotations

__all__ = ["block_sum", "cluster_pixels", "first_of_key", "pixel_prepass"]


def pixel_prepass(mi, dr, samples, n: int, k: int, threshold, weight, fmt: str):
    """Fragment keys and aggregates of every pixel of a launch, one lane a pixel.

    ``samples`` is ``(valid, depth, prim, shape, normal)`` of the launch's samples, ``n``
    lanes a pixel (:func:`._trace.prepass_dr` with ``normals``). Returns lists over the
    sample slots of per-pixel UInt32 ``first`` (:func:`first_of_key`) and Int32 aggregate
    (:func:`cluster_pixels` on the normals stored in ``fmt``), and the UInt32 mask of the
    fragment representatives (bit ``j``: slot ``j`` is the first of its fragment);
    unevaluated.
    """
    from ..pixel_dr import store_normal

    valid, depth, prim, shape, nrm = samples
    local = dr.arange(mi.UInt32, dr.width(valid) // n)
    lane = [local * n + j for j in range(n)]
    v = [dr.gather(mi.Bool, valid, at) for at in lane]
    first = first_of_key(
        mi,
        dr,
        v,
        [dr.gather(mi.Int32, shape, at) for at in lane],
        [dr.gather(mi.UInt32, prim, at) for at in lane],
    )
    stored = [store_normal(mi, dr, dr.gather(mi.Vector3f, nrm, at), fmt) for at in lane]
    z = [dr.gather(mi.Float, depth, at) for at in lane]
    agg = cluster_pixels(mi, dr, v, z, stored, k, threshold, weight)
    rep_bits = mi.UInt32(0)
    for j in range(n):
        rep_bits |= dr.select(v[j] & (first[j] == j), mi.UInt32(1 << j), 0)
    return first, agg, rep_bits


def block_sum(dr, xs):
    """``drjit.block_reduce(Add, x, N)`` of one pixel's ``N`` values ``xs`` (a list):
    pairwise sums of halves, +0 for a zero sum (``N >= 2``)."""
    if len(xs) == 1:
        return xs[0]
    while len(xs) > 1:
        h = len(xs) // 2
        xs = [xs[i] + xs[i + h] for i in range(h)]
    return dr.select(xs[0] == 0.0, 0.0, xs[0])


def first_of_key(mi, dr, valid, shape, prim):
    """Per sample slot ``j``: the first slot of the pixel with the same (shape, primitive),
    ``N`` for sky (:func:`._pixel_dr.first_of_key`); the arguments are lists over slots."""
    n = len(valid)
    first = []
    for i in range(n):
        f = mi.UInt32(n)
        for j in range(i + 1):  # slot i itself matches when valid: no later slot can be first
            same = valid[j] & (prim[j] == prim[i]) & (shape[j] == shape[i])
            f = dr.select(same & (f == n), j, f)
        first.append(dr.select(valid[i], f, n))
    return first


def cluster_pixels(mi, dr, valid, z, nrm, k: int, threshold, weight):
    """Aggregate (0 or 1; -1 sky, Int32) of each sample slot by AGAA's clustering, as
    :func:`._pixel_dr.aggregate_of`; ``valid``, ``z`` (view depth), ``nrm`` (stored normal,
    Vector3f) are lists over the pixel's slots."""
    n = len(valid)
    vf = [dr.select(v, 1.0, 0.0) for v in valid]
    z = [z[j] * vf[j] for j in range(n)]
    cnt = dr.maximum(block_sum(dr, vf), 1.0)
    z_mean = block_sum(dr, z) / cnt
    z_mean = dr.select(z_mean > 0, z_mean, 1.0)
    n_mean = mi.Vector3f(
        *(block_sum(dr, [nrm[j][c] * vf[j] for j in range(n)]) / cnt for c in range(3))
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
