"""NumPy references of the IZB Dr.Jit kernels: the orthographic 32-sample list build
(:class:`raster_models.izb.build.Ortho32Build`) and the join's sample-triangle tests
(:class:`raster_models.izb.kernel.PairTester`).

The same steps as the kernels, in float64, in the same order, without fused multiply-adds.
Build: ``spread = |ldx| amax + |ldy| bmax``, the one-texel box of half-size
:func:`~raster_models.izb.build.one_texel_reach`, the points ``(lc + ldx a) + ldy b`` and
their texels; the kernels must give the same texel ids, receivers and bound bits
(:data:`BUILD_TOLERANCE`). Tests: plane values ``((n0 p0 + n1 p1) + n2 p2) + c`` and
``(base + da a) + db b``, bounds over the 32 points deciding most pairs; the kernels must give
the same flags and masks (:data:`PAIR_TOLERANCE`).
"""

from __future__ import annotations

import numpy as np
from raster_oracle.raster_models.izb.build import one_texel_reach, texel
from raster_oracle.raster_models.izb.kernel import DeadPairs, band_floor

__all__ = [
    "BUILD_CHUNK",
    "BUILD_TOLERANCE",
    "PAIR_CHUNK",
    "PAIR_TOLERANCE",
    "flags_single",
    "join",
    "masks_32",
    "one_texel",
    "ortho32_bounds",
    "ortho32_nodes",
    "pair_tests",
    "spread",
]

#: The build's results are compared exactly: integer texel ids and receiver indices, and
#: bounds that are a min / max of float64 values computed by the same operations in the
#: same order (no rounding difference is possible).
BUILD_TOLERANCE = 0.0

#: Receivers per chunk of the reference (bounds its memory; the result does not depend on
#: it).
BUILD_CHUNK = 1 << 16

#: The tests' results are compared exactly: flags and bit masks of comparisons of float64
#: plane values computed by the same operations in the same order.
PAIR_TOLERANCE = 0

#: Pairs per chunk of the reference join (bounds its memory: ``(pairs, 4, 32)`` float64
#: working arrays for the pairs that straddle a plane; the result does not depend on it).
PAIR_CHUNK = 1 << 18

#: All 32 bits of an FTIZB mask.
FULL = 0xFFFFFFFF


def spread(ldx: np.ndarray, ldy: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(M, 3)`` half-size of the box around each receiver's 32 points."""
    return np.abs(ldx) * np.abs(a).max() + np.abs(ldy) * np.abs(b).max()


def one_texel(lc: np.ndarray, sp: np.ndarray, box, r: int):
    """Receivers whose 32 points all fall in one texel, and that texel (``j R + i``): the
    texels of the slackened box's corners bound those of the points."""
    ends = []
    for q in range(2):  # x, y
        x, w = lc[:, q], sp[:, q]
        reach = one_texel_reach(x, w)
        ends.append((x - reach, x + reach))
    i0, j0 = texel(ends[0][0], ends[1][1], box, r)
    i1, j1 = texel(ends[0][1], ends[1][0], box, r)
    return (i0 == i1) & (j0 == j1), j0 * r + i0


def ortho32_bounds(lc, ldx, ldy, a, b, sel):
    """Light-frame ``lo``, ``hi`` ``(3,)`` of the boxes around the points of receivers
    ``sel`` (all: ``None``)."""
    sp = spread(ldx, ldy, a, b)
    lcs = lc if sel is None else lc[sel]
    sps = sp if sel is None else sp[sel]
    lo = np.array([(lcs[:, q] - sps[:, q]).min() for q in range(3)])
    hi = np.array([(lcs[:, q] + sps[:, q]).max() for q in range(3)])
    return lo, hi


def ortho32_nodes(lc, ldx, ldy, a, b, sel, box, r: int, *, chunk: int = BUILD_CHUNK):
    """Centre texels (int64), node texels (int32) and node receivers (int32) of receivers
    ``sel`` (all: ``None``) in one grid, in the build's order: the one-texel receivers' nodes
    first (receiver order), then the others' (receiver order, each distinct texel at its
    first point)."""
    sp = spread(ldx, ldy, a, b)
    idx = np.arange(len(lc)) if sel is None else np.asarray(sel)
    ci, cj = texel(lc[idx, 0], lc[idx, 1], box, r)
    ones, others = [], []
    for s0 in range(0, len(idx), chunk):  # chunks of receivers
        ch = idx[s0 : s0 + chunk]
        one, t = one_texel(lc[ch], sp[ch], box, r)
        ones.append((t[one], ch[one]))
        ch = ch[~one]
        x, y = (lc[ch, q, None] + ldx[ch, q, None] * a + ldy[ch, q, None] * b for q in range(2))
        i, j = texel(x, y, box, r)
        tex = j * r + i
        # each distinct texel at its first point: sorted stably, first of each run
        order = np.argsort(tex, axis=1, kind="stable")
        srt = np.take_along_axis(tex, order, axis=1)
        run = np.ones_like(srt, dtype=bool)
        run[:, 1:] = srt[:, 1:] != srt[:, :-1]
        first = np.zeros_like(run)
        np.put_along_axis(first, order, run, axis=1)
        others.append((tex[first], np.repeat(ch, first.sum(axis=1))))
    parts = ones + others
    node_texel = np.concatenate([t for t, _ in parts]).astype(np.int32)
    node_recv = np.concatenate([c for _, c in parts]).astype(np.int32)
    return cj * r + ci, node_texel, node_recv


def _dot(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(P, 4)`` dot products of the four plane normals ``n (P, 4, 3)`` with ``v (P, 3)``."""
    return n[:, :, 0] * v[:, None, 0] + n[:, :, 1] * v[:, None, 1] + n[:, :, 2] * v[:, None, 2]


def flags_single(planes: np.ndarray, p: np.ndarray, floor: np.ndarray, hit, epsilon: float):
    """Shadowed flags and epsilon-band flags of points ``p (P, 3)`` against ``planes
    (P, 4, 4)``; ``floor (P,)``: the lower end of the band (:func:`band_floor`); ``hit (P, 3)``:
    the pixels' exact hits, where the band is judged (edges within ``floor + epsilon``)."""
    v = _dot(planes[:, :, :3], p) + planes[:, :, 3]
    w = _dot(planes[:, :, :3], hit) + planes[:, :, 3]
    slack = -(floor + epsilon)
    edges = (v[:, 0] >= 0) & (v[:, 1] >= 0) & (v[:, 2] >= 0)
    near = (w[:, 0] >= slack) & (w[:, 1] >= slack) & (w[:, 2] >= slack)
    shadowed = edges & (v[:, 3] > 0)
    return shadowed, near & (w[:, 3] > floor) & ~shadowed


def _masks(v, edge, threshold, bits):
    e = edge[:, None]
    inside = (v[:, 0] >= e) & (v[:, 1] >= e) & (v[:, 2] >= e) & (v[:, 3] > threshold[:, None])
    return (inside.astype(np.uint64) @ bits).astype(np.uint32)


def masks_32(planes, p, dpdx, dpdy, floor, a, b, hit, epsilon):
    """32-bit masks of the points ``p + a dpdx + b dpdy`` inside the volumes and of the
    points in the epsilon band (judged at ``hit + a dpdx + b dpdy``, edges within
    ``floor + epsilon``; without the mask); bounds of the planes over the points decide most
    pairs (none inside, band included: both 0; all inside: mask full)."""
    bits = np.left_shift(np.uint64(1), np.arange(32, dtype=np.uint64))
    n = planes[:, :, :3]
    base = _dot(n, p) + planes[:, :, 3]
    exact = _dot(n, hit) + planes[:, :, 3]
    da = _dot(n, dpdx)
    db = _dot(n, dpdy)
    slack = -(floor + epsilon)
    reach = np.abs(da) * np.abs(a).max() + np.abs(db) * np.abs(b).max()
    hi = base + reach
    lo = base - reach
    top = exact + reach
    none = ((hi[:, :3] < 0).any(axis=1) | (hi[:, 3] <= 0)) & (
        (top[:, :3] < slack[:, None]).any(axis=1) | (top[:, 3] <= floor)
    )
    full = (lo[:, :3] >= 0).all(axis=1) & (lo[:, 3] > 0)
    masks = np.zeros(len(p), dtype=np.uint32)
    band = np.zeros(len(p), dtype=np.uint32)
    masks[full & ~none] = FULL
    mixed = np.flatnonzero(~none & ~full)
    if len(mixed):
        v = (
            base[mixed, :, None]
            + da[mixed, :, None] * a[None, None, :]
            + db[mixed, :, None] * b[None, None, :]
        )
        w = (
            exact[mixed, :, None]
            + da[mixed, :, None] * a[None, None, :]
            + db[mixed, :, None] * b[None, None, :]
        )
        zero = np.zeros(len(mixed))
        masks[mixed] = _masks(v, zero, zero, bits)
        band[mixed] = _masks(w, slack[mixed], floor[mixed], bits) & ~masks[mixed]
    return masks, band


def pair_tests(planes, recv: dict, epsilon: float, tri: np.ndarray, r: np.ndarray):
    """The tests of pairs ``(tri[i], r[i])``: shadowed and band flags (``recv`` holds ``p``
    only) or masks (``recv`` holds ``dpdx``, ``dpdy``, ``a``, ``b`` too), as
    :class:`~raster_models.izb.kernel.PairTester` takes them."""
    pl = planes[tri]
    p = recv["p"][r]
    scale = recv.get("floor_scale")
    floor = band_floor(p, epsilon) if scale is None else band_floor(p, epsilon, scale[r])
    hit = recv["hit"][r] if "hit" in recv else p
    if "dpdx" in recv:
        return masks_32(
            pl, p, recv["dpdx"][r], recv["dpdy"][r], floor, recv["a"], recv["b"], hit, epsilon
        )
    return flags_single(pl, p, floor, hit, epsilon)


def join(planes, recv, epsilon, frag_tri, lo, n, node_recv, state, *, chunk=PAIR_CHUNK):
    """:meth:`raster_models.izb.kernel.PairTester.join` on NumPy: every pair of the
    fragments ``(frag_tri, lo, n)`` with the nodes ``node_recv`` tested and OR-ed into
    ``state``; returns the pairs whose receiver the join left fully shadowed (not fully
    shadowed before it)."""
    key = "mask" if "dpdx" in recv else "shadowed"
    full = FULL if key == "mask" else 1
    was = state[key].astype(np.uint32) == full
    ends = np.cumsum(n)
    f = np.repeat(np.arange(len(n)), n)
    node = lo[f] + (np.arange(len(f)) - (ends - n)[f])
    r = node_recv[node]
    results = []
    for s0 in range(0, len(f), chunk):  # chunks of pairs
        sl = slice(s0, s0 + chunk)
        hit, near = pair_tests(planes, recv, epsilon, frag_tri[f[sl]], r[sl])
        if key == "mask":
            np.bitwise_or.at(state["mask"], r[sl], hit)
            np.bitwise_or.at(state["band"], r[sl], near)
        else:
            state["shadowed"][r[sl][hit]] = True
            state["band"][r[sl][near]] = True
        results.append(hit.astype(np.uint32))
    result = np.concatenate(results)
    pair = np.flatnonzero((state[key][r].astype(np.uint32) == full) & ~was[r])
    return DeadPairs(f[pair].astype(np.int64), r[pair].astype(np.int64), result[pair])
