"""SMAA's second pass: blending weights (``SMAABlendingWeightCalculationPS`` of ``SMAA.hlsl``).

For every pixel with an edge on its top (G) or left (R) boundary: the diagonal pattern search
(``SMAACalculateDiagWeights``; diagonals take priority), else the orthogonal searches along
the edge in both directions, two pixels a step with one bilinear fetch reading four edges
(``@PSEUDO_GATHER4``: offsets -0.25, -0.125), the last step corrected by the search texture,
the crossing edges at both ends read two at a time by a fetch at -0.25 (``@CROSSING_OFFSET``),
the area texture looked up with the quadratically compressed distances and the sub-sample
row, and corner rounding. Every fetch is a bilinear, clamped fetch in texel units
(:mod:`._sampling`), the way the shader relies on the hardware filter. Pixels without edges
are not shaded (the stencil the header recommends). Searches run as one vectorised step per
iteration over all pixels still searching.

Output: the blend texture (RGBA8 UNORM: weights rounded to 1/255): R, G the areas above and
below the pixel's top edge, B, A left and right of its left edge.
"""

from __future__ import annotations

import numpy as np

from ._sampling import SUBTEXEL_BITS, Fetches, bilinear
from .textures import area_texture, search_texture

__all__ = ["blending_weights", "orthogonal_search"]

# SMAA.hlsl's non-configurable constants, in texels of each texture
AREATEX_MAX_DISTANCE = 16
AREATEX_MAX_DISTANCE_DIAG = 20
AREATEX_SUBTEX_ROWS = 80  # 560 / 7: rows per sub-sample band
AREATEX_DIAG_COLUMN = 80  # diagonal areas start at u = 0.5
SEARCH_SCALE = 255.0 / 127.0  # search texture stores 0, 1, 2 as 0, 127, 254
SEARCH_CONTINUE = 0.8281  # both edges of a fetched pair still on (0.8281 in the shader)


class _Pass:
    """Textures and settings of one blending-weight pass."""

    def __init__(self, edges, bits, fetches):
        self.edges = np.asarray(edges, np.float64)
        self.area = area_texture().astype(np.float64) / 255.0
        self.search_tex = search_texture().astype(np.float64) / 255.0
        self.bits = bits
        self.fetches = fetches

    def fetch(self, tex, x, y, name: str):
        if self.fetches is not None:
            self.fetches.add(f"weights:{name}", np.size(x))
        return bilinear(tex, x, y, bits=self.bits)

    def e(self, x, y):
        return self.fetch(self.edges, x, y, "edges")

    # ------------------------------------------------------------------ orthogonal
    def search_length(self, e, offset: float):
        """``SMAASearchLength``: 0, 1 or 2 (times 127/255) from the last fetched edges."""
        x = 32.0 * e[:, 0] + 66.0 * offset + 0.5
        y = 32.5 - 32.0 * e[:, 1]
        return self.fetch(self.search_tex, x, y, "search")

    def search(self, pos, other, step: float, steps: int, along: int):
        """One of ``SMAASearchX{Left,Right}``/``SMAASearchY{Up,Down}``: march ``pos`` by
        ``step`` (+-2 texels) while the fetched pair of edges continues and no crossing edge
        breaks it; returns the corrected end coordinate."""
        pos = pos.copy()
        end = pos + step * steps
        e = np.zeros((len(pos), 2))
        e[:, along] = 1.0
        cross = 1 - along
        for _ in range(steps):
            go = (pos > end if step < 0 else pos < end) & (e[:, along] > SEARCH_CONTINUE)
            go &= e[:, cross] == 0.0
            if not go.any():
                break
            p = pos[go]
            e[go] = self.e(p, other[go]) if along == 1 else self.e(other[go], p)
            pos[go] += step
        e_sl = e if along == 1 else e[:, ::-1]
        offset = 3.25 - SEARCH_SCALE * self.search_length(e_sl, 0.0 if step < 0 else 0.5)
        return pos + offset if step < 0 else pos - offset

    def area_ortho(self, sqrt_d, e1, e2, sub: int):
        """``SMAAArea``: the area texture at the compressed distances and crossing edges."""
        x = AREATEX_MAX_DISTANCE * np.round(4.0 * e1) + sqrt_d[:, 0] + 0.5
        y = AREATEX_MAX_DISTANCE * np.round(4.0 * e2) + sqrt_d[:, 1] + 0.5
        return self.fetch(self.area, x, y + AREATEX_SUBTEX_ROWS * sub, "area")

    def corner(self, w, d, near, far, rounding, channel):
        """``SMAADetect{Horizontal,Vertical}CornerPattern``: ``near``/``far`` hold the four
        fetch positions ((x, y) pairs) of factor.x's two and factor.y's two taps."""
        lr = np.stack([d[:, 0] <= d[:, 1], d[:, 1] <= d[:, 0]], axis=1).astype(np.float64)
        r = (1.0 - rounding) * lr / (lr[:, :1] + lr[:, 1:])
        fx = 1.0 - r[:, 0] * self.e(*near[0])[:, channel] - r[:, 1] * self.e(*near[1])[:, channel]
        fy = 1.0 - r[:, 0] * self.e(*far[0])[:, channel] - r[:, 1] * self.e(*far[1])[:, channel]
        return w * np.clip(np.stack([fx, fy], axis=1), 0.0, 1.0)

    def horizontal(self, xc, yc, steps, sub, rounding):
        xl = self.search(xc - 0.25, yc - 0.125, -2.0, steps, along=1)
        xr = self.search(xc + 1.25, yc - 0.125, 2.0, steps, along=1)
        e1 = self.e(xl, yc - 0.25)[:, 0]
        e2 = self.e(xr + 1.0, yc - 0.25)[:, 0]
        d = np.abs(np.round(np.stack([xl - xc, xr - xc], axis=1)))
        w = self.area_ortho(np.sqrt(d), e1, e2, sub)
        if rounding is not None:
            near = ((xl, yc + 1.0), (xr + 1.0, yc + 1.0))
            far = ((xl, yc - 2.0), (xr + 1.0, yc - 2.0))
            w = self.corner(w, d, near, far, rounding, 0)
        return w

    def vertical(self, xc, yc, steps, sub, rounding):
        yu = self.search(yc - 0.25, xc - 0.125, -2.0, steps, along=0)
        yd = self.search(yc + 1.25, xc - 0.125, 2.0, steps, along=0)
        e1 = self.e(xc - 0.25, yu)[:, 1]
        e2 = self.e(xc - 0.25, yd + 1.0)[:, 1]
        d = np.abs(np.round(np.stack([yu - yc, yd - yc], axis=1)))
        w = self.area_ortho(np.sqrt(d), e1, e2, sub)
        if rounding is not None:
            near = ((xc + 1.0, yu), (xc + 1.0, yd + 1.0))
            far = ((xc - 2.0, yu), (xc - 2.0, yd + 1.0))
            w = self.corner(w, d, near, far, rounding, 1)
        return w

    # ------------------------------------------------------------------ diagonal
    @staticmethod
    def decode(e, cols):
        """``SMAADecodeDiagBilinearAccess``: unpack two edges from one fetch at +0.25."""
        e = e.copy()
        for c in cols:
            e[:, c] = e[:, c] * np.abs(5.0 * e[:, c] - 5.0 * 0.75)
        return np.round(e)

    def search_diag(self, xc, yc, dx, dy, steps, second: bool):
        """``SMAASearchDiag1`` (``second`` False) or ``SMAASearchDiag2``: returns the
        steps taken (coord.z), the last ``dot(e, 0.5)`` (coord.w) and the last edges."""
        n = len(xc)
        x = xc + (0.25 if second else 0.0)
        y = yc.copy()
        z = np.full(n, -1.0)
        wv = np.ones(n)
        e = np.zeros((n, 2))
        for _ in range(max(steps, 0)):
            go = (z < steps - 1) & (wv > 0.9)
            if not go.any():
                break
            x[go] += dx
            y[go] += dy
            z[go] += 1.0
            eg = self.e(x[go], y[go])
            e[go] = self.decode(eg, (0,)) if second else eg
            wv[go] = e[go] @ np.array([0.5, 0.5])
        return z, wv, e

    def area_diag(self, dist, cc, sub: int):
        """``SMAAAreaDiag``."""
        x = AREATEX_MAX_DISTANCE_DIAG * cc[:, 0] + dist[:, 0] + 0.5 + AREATEX_DIAG_COLUMN
        y = AREATEX_MAX_DISTANCE_DIAG * cc[:, 1] + dist[:, 1] + 0.5
        return self.fetch(self.area, x, y + AREATEX_SUBTEX_ROWS * sub, "area")

    def diagonal(self, xc, yc, e, steps, sub3, sub4):
        """``SMAACalculateDiagWeights``: (n, 2) weights of both diagonal directions."""
        n = len(xc)
        weights = np.zeros((n, 2))
        d = np.zeros((n, 4))
        m = e[:, 0] > 0.0
        z, wv, end = self.search_diag(xc[m], yc[m], -1.0, 1.0, steps, False)
        d[m, 0], d[m, 2] = z + (end[:, 1] > 0.9), wv
        d[:, 1], d[:, 3], _ = self.search_diag(xc, yc, 1.0, -1.0, steps, False)
        go = d[:, 0] + d[:, 1] > 2.0
        if go.any():
            g = d[go]
            c_xy = self.e(xc[go] - g[:, 0] + 0.25 - 1.0, yc[go] + g[:, 0])
            c_zw = self.e(xc[go] + g[:, 1] + 1.0, yc[go] - g[:, 1] - 0.25)
            dec = self.decode(np.concatenate([c_xy, c_zw], axis=1), (0, 2))
            c = dec[:, [1, 0, 3, 2]]  # c.yxwz = decoded.xyzw
            cc = 2.0 * c[:, [0, 2]] + c[:, [1, 3]]
            cc[g[:, 2] >= 0.9, 0] = 0.0
            cc[g[:, 3] >= 0.9, 1] = 0.0
            weights[go] += self.area_diag(g[:, :2], cc, sub3)
        d[:] = 0.0
        d[:, 0], d[:, 2], _ = self.search_diag(xc, yc, -1.0, -1.0, steps, True)
        m = self.e(xc + 1.0, yc)[:, 0] > 0.0
        z, wv, end = self.search_diag(xc[m], yc[m], 1.0, 1.0, steps, True)
        d[m, 1], d[m, 3] = z + (end[:, 1] > 0.9), wv
        go = d[:, 0] + d[:, 1] > 2.0
        if go.any():
            g = d[go]
            x0, y0 = xc[go] - g[:, 0], yc[go] - g[:, 0]
            x1, y1 = xc[go] + g[:, 1], yc[go] + g[:, 1]
            c = np.stack(
                [
                    self.e(x0 - 1.0, y0)[:, 1],
                    self.e(x0, y0 - 1.0)[:, 0],
                    *self.e(x1 + 1.0, y1)[:, ::-1].T,
                ],
                axis=1,
            )
            cc = 2.0 * c[:, [0, 2]] + c[:, [1, 3]]
            cc[g[:, 2] >= 0.9, 0] = 0.0
            cc[g[:, 3] >= 0.9, 1] = 0.0
            weights[go] += self.area_diag(g[:, :2], cc, sub4)[:, ::-1]
        return weights


def orthogonal_search(edges, pos, across, step: float, steps: int, along: int, *, bits=0):
    """One orthogonal search of :func:`blending_weights` (``SMAASearchXLeft`` etc.) on the
    edges texture ``edges`` from texel positions ``pos`` (the pass's start offsets included)
    at ``across`` on the other axis: the corrected end coordinate in texels. ``step`` is
    -2 or +2, ``along`` 1 for horizontal searches (reading G), 0 for vertical (R)."""
    tex = _Pass(edges, bits, None)
    p = np.asarray(pos, np.float64)
    return tex.search(p, np.asarray(across, np.float64), step, steps, along)


def blending_weights(
    edges: np.ndarray,
    *,
    max_search_steps: int = 16,
    max_search_steps_diag: int | None = 8,
    corner_rounding: float | None = 25.0,
    subsample_indices: tuple[int, int, int, int] = (0, 0, 0, 0),
    subtexel_bits: int = SUBTEXEL_BITS,
    fetches: Fetches | None = None,
    quantize: bool = True,
) -> np.ndarray:
    """The blend texture of an edges texture.

    Parameters
    ----------
    edges : (H, W, 2) float, 0 or 1 (:func:`.edges.detect_edges`).
    max_search_steps : ``SMAA_MAX_SEARCH_STEPS`` (each step covers two pixels).
    max_search_steps_diag : ``SMAA_MAX_SEARCH_STEPS_DIAG``; None: diagonal detection off
        (``SMAA_DISABLE_DIAG_DETECTION``).
    corner_rounding : ``SMAA_CORNER_ROUNDING`` in [0, 100]; None: corner detection off
        (``SMAA_DISABLE_CORNER_DETECTION``).
    subsample_indices : ``subsampleIndices`` (x: vertical, y: horizontal, z, w: the two
        diagonal directions), rows of the area texture; zeros for SMAA 1x.
    subtexel_bits : fractional bits of the bilinear weights (0: exact).
    fetches : counter of texture fetches (pass ``weights``).
    quantize : round to the RGBA8 target's 1/255 (False: the shader's float output).

    Returns
    -------
    (H, W, 4) float32 in [0, 1], multiples of 1/255 (RGBA8 UNORM).
    """
    tex = _Pass(edges, subtexel_bits, fetches)
    h, w = tex.edges.shape[:2]
    out = np.zeros((h, w, 4))
    rounding = None if corner_rounding is None else float(corner_rounding) / 100.0
    sub_v, sub_h, sub_d1, sub_d2 = (int(s) for s in subsample_indices)

    jy, jx = np.nonzero(tex.edges[..., 1] > 0.0)
    xc, yc = jx + 0.5, jy + 0.5
    if fetches is not None:  # the pass's first fetch, where the stencil lets it run
        fetches.add("weights:edges", int(np.count_nonzero(tex.edges.any(axis=-1))))
    horiz = np.ones(len(jx), bool)
    if max_search_steps_diag is not None and len(jx):
        e = tex.edges[jy, jx]
        wd = tex.diagonal(xc, yc, e, int(max_search_steps_diag), sub_d1, sub_d2)
        out[jy, jx, :2] = wd
        horiz = wd[:, 0] == -wd[:, 1]
    skip_vertical = np.zeros((h, w), bool)
    skip_vertical[jy[~horiz], jx[~horiz]] = True  # a diagonal was found: no vertical pass
    if horiz.any():
        out[jy[horiz], jx[horiz], :2] = tex.horizontal(
            xc[horiz], yc[horiz], max_search_steps, sub_h, rounding
        )
    jy, jx = np.nonzero((tex.edges[..., 0] > 0.0) & ~skip_vertical)
    if len(jx):
        out[jy, jx, 2:] = tex.vertical(jx + 0.5, jy + 0.5, max_search_steps, sub_v, rounding)
    if not quantize:
        return out
    return (np.round(np.clip(out, 0.0, 1.0) * 255.0) / 255.0).astype(np.float32)
