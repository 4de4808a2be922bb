"""Per-pixel work on a multisample prepass, on the Dr.Jit side (no NumPy round trip).

Lanes hold the samples of consecutive pixels, ``N`` lanes a pixel. Pixel-wide quantities are
block reductions (:func:`drjit.block_reduce` over ``N`` lanes) gathered back to each lane;
"the value of sample ``j`` of my pixel" is a gather at ``pixel * N + j``. The loops below run
over the ``N`` sample slots while the kernel is being traced (at most 16 rounds), never over
pixels or data.

- :func:`first_of_key`: for every sample, the first sample of its pixel with the same
  (shape, primitive): its fragment's representative (MSAA/AGAA grouping);
- :func:`store_normal`: a unit normal as stored in a G-buffer format and read back;
- :func:`aggregate_of`: AGAA's clustering (see :mod:`.agaa`), identical in rule to the NumPy
  reference :func:`.agaa.cluster`.
"""

from __future__ import annotations

__all__ = ["aggregate_of", "first_of_key", "fragments_of", "store_normal"]


def _slot(dr, tp, arr, local, n: int, j):
    """Value of sample ``j`` (int or per-lane UInt32) of each lane's pixel."""
    return dr.gather(tp, arr, local * n + j)


def _bcast(dr, mode, tp, x, local, n: int, op):
    """Block reduction of ``x`` over each pixel's ``n`` lanes, back on every lane."""
    return dr.gather(tp, dr.block_reduce(op, x, n, mode=mode), local)


def first_of_key(mi, dr, valid, shape, prim, local, n: int):
    """UInt32 slot of the first sample of the pixel with the same key (``n`` for sky)."""
    first = dr.full(mi.UInt32, n, dr.width(valid))
    for j in range(n):
        same = (
            _slot(dr, mi.Bool, valid, local, n, j)
            & (_slot(dr, mi.UInt32, prim, local, n, j) == prim)
            & (_slot(dr, mi.Int32, shape, local, n, j) == shape)
        )
        first = dr.select(same & (first == n), j, first)
    return dr.select(valid, first, n)


def store_normal(mi, dr, nrm, fmt: str):
    """``nrm`` (Vector3f) written in ``fmt`` (rgba16f, rgb10a2, oct16) and read back."""
    if fmt == "rgba16f":
        return mi.Vector3f(*(mi.Float(mi.Float16(c)) for c in (nrm.x, nrm.y, nrm.z)))
    if fmt == "rgb10a2":
        q = [dr.floor(dr.clip(c * 0.5 + 0.5, 0.0, 1.0) * 1023.0 + 0.5) for c in nrm]
        return mi.Vector3f(*(c * (2.0 / 1023.0) - 1.0 for c in q))
    # octahedral, 2 x 16-bit SNORM
    l1 = dr.abs(nrm.x) + dr.abs(nrm.y) + dr.abs(nrm.z)
    l1 = dr.select(l1 > 0, l1, 1.0)
    x, y, z = nrm.x / l1, nrm.y / l1, nrm.z / l1
    sx, sy = dr.select(x >= 0, 1.0, -1.0), dr.select(y >= 0, 1.0, -1.0)
    u = dr.select(z < 0, (1.0 - dr.abs(y)) * sx, x)
    v = dr.select(z < 0, (1.0 - dr.abs(x)) * sy, y)
    u = dr.round(dr.clip(u, -1.0, 1.0) * 32767.0) / 32767.0
    v = dr.round(dr.clip(v, -1.0, 1.0) * 32767.0) / 32767.0
    zz = 1.0 - dr.abs(u) - dr.abs(v)
    t = dr.maximum(-zz, 0.0)
    u = u - dr.select(u >= 0, t, -t)
    v = v - dr.select(v >= 0, t, -t)
    return dr.normalize(mi.Vector3f(u, v, zz))


def _argmax_slot(mi, dr, mode, d, local, n: int):
    """Lowest slot holding the pixel's maximum of ``d`` (``-inf`` on sky lanes)."""
    top = _bcast(dr, mode, mi.Float, d, local, n, dr.ReduceOp.Max)
    seed = dr.full(mi.UInt32, n - 1, dr.width(d))
    for j in reversed(range(n)):
        seed = dr.select(_slot(dr, mi.Float, d, local, n, j) == top, j, seed)
    return seed, top


def aggregate_of(mi, dr, valid, z, nrm, local, n: int, k: int, threshold, weight):
    """Int32 aggregate of every sample (0 or 1; -1 sky): AGAA's published clustering."""
    mode = "evaluated"
    vf = dr.select(valid, 1.0, 0.0)
    z = z * vf
    cnt = dr.maximum(_bcast(dr, mode, mi.Float, vf, local, n, dr.ReduceOp.Add), 1.0)
    z_mean = _bcast(dr, mode, mi.Float, z, local, n, dr.ReduceOp.Add) / cnt
    z_mean = dr.select(z_mean > 0, z_mean, 1.0)
    n_mean = mi.Vector3f(
        *(_bcast(dr, mode, mi.Float, c * vf, local, n, dr.ReduceOp.Add) / cnt for c in nrm)
    )

    def dist(z_b, n_b):
        return weight * dr.abs(z - z_b) / z_mean + (1.0 - dr.dot(nrm, n_b))

    low = -dr.inf
    d_mean = dr.select(valid, dist(z_mean, n_mean), low)
    seed1, _ = _argmax_slot(mi, dr, mode, d_mean, local, n)
    at1 = local * n + seed1
    z1 = dr.gather(mi.Float, z, at1)
    n1 = dr.gather(mi.Vector3f, nrm, at1)
    d1 = dist(z1, n1)
    seed2, top2 = _argmax_slot(mi, dr, mode, dr.select(valid, d1, low), local, n)
    at2 = local * n + seed2
    d2 = dist(dr.gather(mi.Float, z, at2), dr.gather(mi.Vector3f, nrm, at2))
    split = (top2 > threshold) if k >= 2 else dr.full(mi.Bool, False, dr.width(z))
    agg = dr.select(split & (d2 < d1), 1, 0)
    return dr.select(valid, mi.Int32(agg), -1)


def fragments_of(mi, dr, valid, first, local, n: int, s, offset: int, agg=None) -> dict:
    """Fragment bookkeeping of every sample from its representative slot ``first``.

    Returns Dr.Jit arrays: ``rep`` (the sample is its fragment's representative), ``of``
    (Int32 fragment id, numbered over all pixels in lane order from ``offset``; -1 sky),
    ``count`` (samples of the sample's fragment) and, with ``agg``, ``pair_rep`` and
    ``pair_count``: the same for (fragment, aggregate) pairs.
    """
    rep = valid & (first == s)
    fid = dr.prefix_sum(dr.select(rep, mi.UInt32(1), mi.UInt32(0))) + offset
    fid = dr.gather(mi.UInt32, fid, local * n + dr.select(valid, first, 0))
    out = {"rep": rep, "of": dr.select(valid, mi.Int32(fid), -1)}
    count = dr.zeros(mi.UInt32, dr.width(valid))
    if agg is not None:
        pair_count = dr.zeros(mi.UInt32, dr.width(valid))
        pair_first = dr.full(mi.UInt32, n, dr.width(valid))
    for j in range(n):
        same = _slot(dr, mi.Bool, valid, local, n, j) & (
            _slot(dr, mi.UInt32, first, local, n, j) == first
        )
        count += dr.select(same, mi.UInt32(1), mi.UInt32(0))
        if agg is not None:
            pair = same & (_slot(dr, mi.Int32, agg, local, n, j) == agg)
            pair_count += dr.select(pair, mi.UInt32(1), mi.UInt32(0))
            pair_first = dr.select(pair & (pair_first == n), j, pair_first)
    out["count"] = dr.select(valid, count, 0)
    if agg is not None:
        out["pair_rep"] = valid & (pair_first == s)
        out["pair_count"] = dr.select(valid, pair_count, 0)
    return out
