"""How close each receiver's depth compares came to the other answer: the *compare margin*.

A compare filter reads a set of texels per lookup (each tap's 2x2 bilinear footprint; the
nearest texel for ``point``) and compares the receiver's reference depth with each. The
margin is the smallest ``|ref - stored|`` over those texels, in normalized depth: where it
is within the rounding of the depth format (and of the engine's float32 matrices), an
engine implementing the same technique exactly may decide the other way. Conformance
scoring names those pixels *implementation-defined* instead of counting them as failures.

Taps per filter: ``point`` and ``hw_pcf`` one (the sample), ``pcf`` the ``N x N`` grid,
``poisson`` the disc (rotated per pixel when it is), ``three_pcf`` the Vogel disk. Other
filters (moments, PCSS) have no margin (``None``). The receiver-plane bias is not applied
per tap here (the margin uses the centre reference).
"""

from __future__ import annotations

import numpy as np

from . import filters as _filters
from . import three_filters as _three

__all__ = ["MARGIN_FILTERS", "compare_margin", "tap_offsets"]

#: Filters that have a compare margin.
MARGIN_FILTERS = ("point", "hw_pcf", "pcf", "poisson", "three_pcf")


def tap_offsets(params, resolution: int, rotation, n: int):
    """``(du, dv)`` texture-coordinate offsets of a lookup's taps, each ``(K, n)``."""
    r = float(resolution)
    kind = params.filter
    if kind in ("point", "hw_pcf"):
        return np.zeros((1, n)), np.zeros((1, n))
    if kind == "pcf":
        k = (np.arange(params.pcf_size) - (params.pcf_size - 1) / 2.0) / r
        du, dv = np.meshgrid(k, k)
        return np.repeat(du.reshape(-1, 1), n, 1), np.repeat(dv.reshape(-1, 1), n, 1)
    if kind == "poisson":
        disc = _filters.poisson_disc(int(params.poisson_taps), int(params.seed))
        disc = disc * (0.5 * params.filter_size / r)
        ox, oy = disc[:, :1], disc[:, 1:]
        if rotation is None:
            return np.repeat(ox, n, 1), np.repeat(oy, n, 1)
        c, s = np.cos(rotation)[None, :], np.sin(rotation)[None, :]
        return c * ox - s * oy, s * ox + c * oy
    if kind == "three_pcf":
        scale = float(params.shadow_radius) / r
        taps = [_three.vogel_disk(k, _three.PCF_SAMPLES, rotation) for k in range(5)]
        return (
            np.stack([dx * scale for dx, _ in taps]),
            np.stack([-dy * scale for _, dy in taps]),
        )
    raise ValueError(f"no compare margin for filter {kind!r}")


def compare_margin(depth_map: np.ndarray, u, v, ref, du, dv, *, point: bool) -> np.ndarray:
    """Smallest ``|ref - stored|`` over the texels the taps ``(u + du, v + dv)`` read (2x2
    bilinear footprints, or the nearest texel with ``point``), float64 ``(n,)``; clamp
    addressing, the reference clamped to [0, 1] as the compare does."""
    d = np.asarray(depth_map, dtype=np.float64)
    r = d.shape[0]
    ref = np.clip(np.asarray(ref, dtype=np.float64), 0.0, 1.0)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    best = np.full(u.shape, np.inf)
    for k in range(du.shape[0]):
        x = (u + du[k]) * r
        y = (v + dv[k]) * r
        if point:
            cols = [np.floor(x)]
            rows = [np.floor(y)]
        else:
            x0, y0 = np.floor(x - 0.5), np.floor(y - 0.5)
            cols, rows = [x0, x0 + 1], [y0, y0 + 1]
        for cy in rows:
            iy = np.clip(cy, 0, r - 1).astype(np.int64)
            for cx in cols:
                ix = np.clip(cx, 0, r - 1).astype(np.int64)
                best = np.minimum(best, np.abs(ref - d[iy, ix]))
    return best
