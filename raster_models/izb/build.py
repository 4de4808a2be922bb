"""IZB list build, orthographic grids: the texels of each receiver's samples.

A grid is ``R x R`` texels over a light-frame box ``(x0, x1, y0, y1)`` (``x`` right, ``y``
up; texel row 0 at the top, ``y1``); light-frame point ``(x, y)`` falls in texel
``i = floor((x - x0) / ((x1 - x0) / R))``, ``j = floor((y1 - y) / ((y1 - y0) / R))``, both
clamped to ``[0, R - 1]`` (points on the far edge), id ``j R + i``.

FTIZB (32 samples) inserts a receiver in every texel one of its 32 tangent-plane points
``lc + a ldx + b ldy`` falls in (``lc``: light-frame centre, ``ldx``, ``ldy``: light-frame
``dP/dx``, ``dP/dy``). Most receivers (about 90% on city at 1080p) lie in one texel: a box
of half-size ``spread = |ldx| max|a| + |ldy| max|b|`` (slackened by float64 rounding, see
:data:`ONE_TEXEL_SLACK`) around the centre decides that without the points. The nodes come
in a fixed order, whatever the chunking: first the one-texel receivers (one node each, in
receiver order), then the others (in receiver order, one node per distinct texel, in the
order of the points' first occurrences).

The build runs in Dr.Jit kernels (a vectorized variant: LLVM or CUDA), one per receiver
(bounds, centre texel, one-texel decision) and one per other receiver (its 32 points'
texels, duplicates dropped), every value in float64 in a fixed order without fused
multiply-adds: ``spread = |ldx| amax + |ldy| bmax``, ``(lc + ldx a) + ldy b``,
``(x - x0) / s``. ``tests/_izb_reference.py`` holds a NumPy version of the same steps, the
reference ``tests/test_izb_build.py`` compares the kernels with (exactly: texel ids, receiver
indices and the bounds' float64 bits).
"""

from __future__ import annotations

import importlib

import numpy as np

__all__ = [
    "DRJIT_BUILD_CHUNK",
    "GRID_MARGIN",
    "MAX_RECEIVERS",
    "ONE_TEXEL_SLACK",
    "Ortho32Build",
    "grid",
    "one_texel_reach",
    "texel",
]

#: Relative margin around each grid's tight bounds, so samples on the boundary stay inside.
GRID_MARGIN = 1e-6

#: Relative slack of the box around a receiver's 32 points when deciding that they share one
#: texel: the points' float64 rounding is a few 2^-53 of ``|x| + spread``.
ONE_TEXEL_SLACK = 1e-12

#: Receivers per Dr.Jit launch (bounded memory: a few tens of bytes per receiver, plus
#: 128 bytes (32 texel ids) per receiver over several texels).
DRJIT_BUILD_CHUNK = 1 << 20

#: Most receivers of a build: the kernels index the ``(M, 3)`` rows with 32-bit integers.
MAX_RECEIVERS = 2**32 // 3 - 1

#: Dr.Jit: the texel id of a duplicate point (never a texel: ids are below 2^26 per grid).
_NONE = 0xFFFFFFFF

#: The smallest normal float64 (keeps the reach positive where ``x`` and ``spread`` are 0).
_TINY = float(np.finfo(float).tiny)


def grid(lo: np.ndarray, hi: np.ndarray):
    """Tight grid ``(x0, x1, y0, y1)`` around light-frame x/y bounds (never empty)."""
    size = np.maximum(hi - lo, 1e-9 * (1.0 + np.abs(lo)))
    pad = GRID_MARGIN * size
    return (lo[0] - pad[0], hi[0] + pad[0], lo[1] - pad[1], hi[1] + pad[1])


def texel(x, y, box, r):
    """Texel (i, j) of light-frame x, y in a grid box (clamped: points on the far edge)."""
    x0, x1, y0, y1 = box
    i = np.clip(np.floor((x - x0) / ((x1 - x0) / r)), 0, r - 1).astype(np.int64)
    j = np.clip(np.floor((y1 - y) / ((y1 - y0) / r)), 0, r - 1).astype(np.int64)
    return i, j


def one_texel_reach(x, w):
    """Half-size of the slackened box around a receiver's points: ``x`` the centre
    coordinate, ``w`` its spread (NumPy arrays or Dr.Jit Float64 alike). The texels of the
    box's corners bound those of the points (:func:`texel` is monotone in x and y)."""
    return w + (ONE_TEXEL_SLACK * (abs(x) + w) + _TINY)


class Ortho32Build:
    """The 32-sample receivers of orthographic grids: bounds, centre texels and nodes.

    Parameters
    ----------
    lc, ldx, ldy : ``(M, 3)`` float64 light-frame centre and derivatives of every receiver
        (at most :data:`MAX_RECEIVERS`).
    a, b : ``(32,)`` float64 tangent-plane offsets (pixels).
    """

    def __init__(self, lc, ldx, ldy, a, b):
        if len(lc) > MAX_RECEIVERS:
            raise ValueError(f"at most {MAX_RECEIVERS} receivers, got {len(lc)}")
        self.lc, self.ldx, self.ldy = lc, ldx, ldy
        self.a, self.b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        self.amax, self.bmax = np.abs(self.a).max(), np.abs(self.b).max()
        self._dr = None

    def bounds(self, sel: np.ndarray | None):
        """Light-frame ``lo``, ``hi`` ``(3,)`` of the points of receivers ``sel`` (all:
        ``None``): the boxes around them (half-size ``spread``), which contain the points."""
        import drjit as dr

        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for idx in self._chunks(sel):  # chunks of receivers
            ends = []
            for q in range(3):  # x, y, z
                c, w = self._column("lc", idx, q), self._spread_dr(idx, q)
                ends += [c - w, c + w]
            dr.eval(*ends)  # one kernel; then the reductions
            v = [(dr.min if k % 2 == 0 else dr.max)(e) for k, e in enumerate(ends)]
            dr.eval(*v)
            v = np.array([e.numpy()[0] for e in v])
            lo, hi = np.minimum(lo, v[0::2]), np.maximum(hi, v[1::2])
        return lo, hi

    def nodes(self, sel: np.ndarray | None, box, r: int):
        """Centre texels and list nodes of receivers ``sel`` (all: ``None``) in one grid.

        Returns
        -------
        centre : ``(n,)`` int64 texel ``j R + i`` of each receiver's centre ``lc``.
        node_texel, node_recv : texel (int32) and receiver index (into ``lc``; int32 below
            2^31 receivers) of every node, in the order of the module docstring.
        """
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        ti, tj = self._texel_dr(box, r)
        rr = dr.opaque(u32, r)
        centres, ones, others = [], [], []
        for idx in self._chunks(sel):  # chunks of receivers
            x, y = self._column("lc", idx, 0), self._column("lc", idx, 1)
            reach_x = one_texel_reach(x, self._spread_dr(idx, 0))
            reach_y = one_texel_reach(y, self._spread_dr(idx, 1))
            i0, j0 = ti(x - reach_x), tj(y + reach_y)
            i1, j1 = ti(x + reach_x), tj(y - reach_y)
            one = (i0 == i1) & (j0 == j1)
            t = j0 * rr + i0
            centre = tj(y) * rr + ti(x)
            dr.eval(t, one, centre)
            centres.append(centre.numpy().astype(np.int64))
            k = dr.compress(one)  # compacted in Dr.Jit (both threads), in receiver order
            ones.append((dr.gather(u32, t, k), dr.gather(u32, idx, k)))
            rest = dr.gather(u32, idx, dr.compress(~one))
            if dr.width(rest):
                tex = self._point_texels(rest, ti, tj, rr)
                k = dr.compress(tex != u32(_NONE))  # row-major: receiver, then point order
                others.append((dr.gather(u32, tex, k), dr.gather(u32, rest, k // 32)))
        parts = [(t.numpy().view(np.int32), c.numpy()) for t, c in ones + others]
        return np.concatenate(centres), *_concat(parts, len(self.lc))

    # ---- kernels' inputs and steps
    def _inputs(self):
        if self._dr is None:
            from ...scenes import backend

            mi = backend.mitsuba()
            f64 = mi.Float64
            arrays = {
                k: f64(np.ascontiguousarray(v, dtype=np.float64).ravel())
                for k, v in (("lc", self.lc), ("ldx", self.ldx), ("ldy", self.ldy))
            }
            self._dr = (mi, arrays)
        return self._dr

    def _chunks(self, sel):
        """Dr.Jit receiver indices, chunk by chunk."""
        import drjit as dr

        mi, _ = self._inputs()
        n = len(self.lc) if sel is None else len(sel)
        for s0 in range(0, n, DRJIT_BUILD_CHUNK):  # chunks of receivers
            s1 = min(n, s0 + DRJIT_BUILD_CHUNK)
            if sel is None:
                yield dr.arange(mi.UInt32, s0, s1)
            else:
                yield mi.UInt32(np.asarray(sel[s0:s1]).astype(np.uint32))

    def _column(self, key, idx, q):
        import drjit as dr

        mi, arrays = self._inputs()
        return dr.gather(mi.Float64, arrays[key], idx * 3 + q)

    def _spread_dr(self, idx, q):
        import drjit as dr

        dx, dy = self._column("ldx", idx, q), self._column("ldy", idx, q)
        return dr.abs(dx) * float(self.amax) + dr.abs(dy) * float(self.bmax)

    def _texel_dr(self, box, r):
        """Dr.Jit texel functions ``i(x)``, ``j(y)`` of the grid (UInt32)."""
        import drjit as dr

        mi, _ = self._inputs()
        f64, u32 = mi.Float64, mi.UInt32
        x0, x1, y0, y1 = box
        # The cell sizes as NumPy computes them; opaque: one kernel serves every grid.
        sx, sy = (x1 - x0) / r, (y1 - y0) / r
        x0_, y1_, sx_, sy_ = (dr.opaque(f64, float(v)) for v in (x0, y1, sx, sy))
        top = float(r - 1)

        def ti(x):
            return u32(dr.clip(dr.floor((x - x0_) / sx_), 0.0, top))

        def tj(y):
            return u32(dr.clip(dr.floor((y1_ - y) / sy_), 0.0, top))

        return ti, tj

    def _point_texels(self, idx, ti, tj, rr):
        """Dr.Jit ``(n * 32,)`` texels of the 32 points of receivers ``idx`` (row-major: by
        receiver, then point); a point in the texel of an earlier point of its receiver
        gives :data:`_NONE`."""
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        n = dr.width(idx)
        c = [self._column(k, idx, q) for k in ("lc", "ldx", "ldy") for q in range(2)]
        x, y, dxx, dxy, dyx, dyy = c
        outs, seen = [], []
        for q in range(32):  # the 32 fixed points (unrolled into the kernel)
            aq, bq = float(self.a[q]), float(self.b[q])
            t = tj((y + dxy * aq) + dyy * bq) * rr + ti((x + dxx * aq) + dyx * bq)
            dup = dr.zeros(mi.Bool, n)
            for s in seen:  # earlier points of the same receiver
                dup |= t == s
            seen.append(t)
            outs.append(dr.select(dup, u32(_NONE), t))
        out = dr.empty(u32, n * 32)
        arr = importlib.import_module(u32.__module__).ArrayXu
        dr.scatter(out, arr(outs), dr.arange(u32, n))  # row-major (n, 32), packet stores
        dr.eval(out)
        return out


def _concat(parts, m: int):
    """Node texels (int32) and receivers (int32 below 2^31 receivers) of ``parts``."""
    node_texel = np.concatenate([t for t, _ in parts]).astype(np.int32, copy=False)
    node_recv = np.concatenate([c for _, c in parts])
    if node_recv.dtype == np.uint32:  # from Dr.Jit: ids below 2^32 / 3, within int32
        node_recv = node_recv.view(np.int32)
    return node_texel, node_recv.astype(np.int32 if m < 2**31 else np.int64, copy=False)
