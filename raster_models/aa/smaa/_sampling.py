"""Texture fetches as the GPU performs them for SMAA: bilinear filtering with clamp
addressing (every SMAA sampler is "linear filtering and clamp", ``SMAA.hlsl`` step 4), with the
filter weights quantised to the hardware's sub-texel precision, and a fetch counter for the
cost record.

Coordinates are in texel units (``texcoord * size``): texel ``(i, j)`` has its centre at
``(i + 0.5, j + 0.5)``, x to the right, y down (row 0 first), as Direct3D addresses textures.
"""

from __future__ import annotations

import numpy as np

#: Sub-texel precision of the filter weights: 8 fractional bits, the Direct3D 11 minimum
#: ("texture filtering ... at least 8 bits of sub-texel precision"), what GPUs implement.
SUBTEXEL_BITS = 8


class Fetches:
    """Counts texture fetches per pass (one per pixel and tap, whatever the filter reads)."""

    def __init__(self):
        self.by_pass: dict[str, int] = {}

    def add(self, name: str, n: int) -> None:
        self.by_pass[name] = self.by_pass.get(name, 0) + int(n)


def bilinear_taps(shape, x, y, *, bits: int = SUBTEXEL_BITS):
    """The four texels (clamped ``(row, column)`` index arrays) and weights of a bilinear
    fetch at texel coordinates ``x``, ``y`` of a texture of ``shape`` ((H, W, ...))."""
    h, w = shape[:2]
    fx = np.asarray(x, np.float64) - 0.5
    fy = np.asarray(y, np.float64) - 0.5
    x0 = np.floor(fx)
    y0 = np.floor(fy)
    ax = fx - x0
    ay = fy - y0
    if bits:
        q = float(1 << bits)
        ax = np.round(ax * q) / q
        ay = np.round(ay * q) / q
    i0 = np.clip(x0, 0, w - 1).astype(np.intp)
    i1 = np.clip(x0 + 1, 0, w - 1).astype(np.intp)
    j0 = np.clip(y0, 0, h - 1).astype(np.intp)
    j1 = np.clip(y0 + 1, 0, h - 1).astype(np.intp)
    taps = ((j0, i0), (j0, i1), (j1, i0), (j1, i1))
    weights = ((1.0 - ay) * (1.0 - ax), (1.0 - ay) * ax, ay * (1.0 - ax), ay * ax)
    return taps, weights


def bilinear(tex: np.ndarray, x, y, *, bits: int = SUBTEXEL_BITS) -> np.ndarray:
    """Bilinear fetch of ``tex`` ((H, W) or (H, W, C), float) at texel coordinates ``x``,
    ``y`` (arrays of one shape), clamp addressing; weights rounded to ``bits`` fractional
    bits (0: exact). Returns ``x.shape`` (+ ``(C,)``) float64."""
    ((j0, i0), (_, i1), (j1, _), _), _ = bilinear_taps(tex.shape, x, y, bits=bits)
    fx = np.asarray(x, np.float64) - 0.5
    fy = np.asarray(y, np.float64) - 0.5
    ax = fx - np.floor(fx)
    ay = fy - np.floor(fy)
    if bits:
        q = float(1 << bits)
        ax = np.round(ax * q) / q
        ay = np.round(ay * q) / q
    if tex.ndim == 3:
        ax = ax[..., None]
        ay = ay[..., None]
    top = (1.0 - ax) * tex[j0, i0] + ax * tex[j0, i1]
    bottom = (1.0 - ax) * tex[j1, i0] + ax * tex[j1, i1]
    return (1.0 - ay) * top + ay * bottom


def point(tex: np.ndarray, ix, iy) -> np.ndarray:
    """Point fetch of texel (``ix``, ``iy``) (integer arrays), clamp addressing."""
    h, w = tex.shape[:2]
    return tex[np.clip(iy, 0, h - 1), np.clip(ix, 0, w - 1)]
