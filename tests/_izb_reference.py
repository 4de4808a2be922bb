"""NumPy reference of the IZB orthographic 32-sample list build (the model runs it in Dr.Jit
kernels, :class:`raster_models.izb.build.Ortho32Build`).

The same steps as the kernels, in float64, in the same order, without fused multiply-adds:
``spread = |ldx| amax + |ldy| bmax``, the one-texel box of half-size
:func:`~raster_models.izb.build.one_texel_reach`, the points ``(lc + ldx a) + ldy b`` and
their texels. The kernels must give the same texel ids, receivers and bound bits
(:data:`BUILD_TOLERANCE`).
"""

from __future__ import annotations

import numpy as np

from raster_models.izb.build import one_texel_reach, texel

__all__ = [
    "BUILD_CHUNK",
    "BUILD_TOLERANCE",
    "one_texel",
    "ortho32_bounds",
    "ortho32_nodes",
    "spread",
]

#: The build's results are compared exactly: integer texel ids and receiver indices, and
#: bounds that are a min / max of float64 values computed by the same operations in the
#: same order (no rounding difference is possible).
BUILD_TOLERANCE = 0.0

#: Receivers per chunk of the reference (bounds its memory; the result does not depend on
#: it).
BUILD_CHUNK = 1 << 16


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
