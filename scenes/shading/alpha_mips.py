"""Mipmapped alpha as a rasterizer samples it: box-filtered and coverage-preserving mip
chains, the mip level from a pixel's texture-coordinate derivatives, trilinear filtering.

The truth (:mod:`.alpha`) samples the base level only; a real-time renderer samples a mip
chain at the level its pixel footprint selects, and the box-filtered mips of an alpha-tested
texture lose coverage with distance (thin features average below the cutoff: foliage
"dissolves"). The models of :mod:`raster_models` sample through this module:

- :func:`box_mips`: each level the 2 x 2 box average of the one above (sizes halve, rounding
  down, to 1 x 1; an odd size's last row or column is averaged with its neighbour's clamp);
- :func:`coverage_mips`: Castaño's alpha-coverage preservation as NVIDIA Texture Tools does
  it: the base level's alpha-test coverage (:func:`nvtt_alpha_test_coverage`) is measured
  once, each box-filtered level is scaled by the factor whose coverage comes closest to it
  (:func:`nvtt_scale_alpha_to_coverage`, a ten-step bisection over [0, 4]) and the next level
  is built from the unscaled one (the flow of NVTT's ``imperativeapi.cpp``);
- :func:`mip_level`: OpenGL 4.6 section 8.14.1, ``rho = max(|d(uW, vH)/dx|, |d(uW, vH)/dy|)``,
  ``lambda = log2(rho) + bias``;
- :func:`sample_mips`: ``LINEAR_MIPMAP_LINEAR`` (section 8.14.3): at ``lambda <= 0`` the
  magnification filter on level 0, else bilinear on levels ``floor(lambda)`` and the next,
  blended by ``frac(lambda)``, both clamped to the last level.

NVTT's own coverage (pinned source, MIT licence; transcribed, not copied):
castano/nvidia-texture-tools commit aeddd65f81d36d8cb7b169b469ef25156666077e,
``src/nvimage/FloatImage.cpp``:

- lines 1379-1422 ``FloatImage::alphaTestCoverage``: over the ``(w-1) x (h-1)`` cells between
  texel centres, 4 x 4 sub-samples at ``(s + 0.5) / 4`` bilinear between the cell's four
  texels, each alpha first scaled and saturated; a sub-sample counts when ``alpha > alphaRef``
  (line 1413, strictly: glTF keeps ``alpha >= cutoff``); the mean over all cells (a level
  1 texel wide or high has no cell: 0 / 0, and the bisection below then keeps scale 1);
- lines 1424-1490 ``FloatImage::scaleAlphaToCoverage`` (the ``#else`` branch, lines 1453-1486):
  ``minAlphaScale = 0``, ``maxAlphaScale = 4``, start at 1, ten steps, keep the scale of the
  smallest ``|coverage - desired|``, stop early on equality; then ``alpha * scale`` clamped to
  [0, 1] (lines 1484-1485);
- ``src/nvtt/tests/imperativeapi.cpp`` lines 72-86: the desired coverage is the base level's,
  each ``buildNextMipmap`` works from the unscaled level, the scaled copy is what is stored
  (that test builds with NVTT's Kaiser filter; here the chain is the box filter's).

References
----------
I. Castaño, "Computing Alpha Mipmaps", 2010, and NVIDIA Texture Tools 2.1 (above).
M. Segal and K. Akeley, The OpenGL Graphics System: A Specification, version 4.6 (core
profile), 2022: 8.14.1 "Scale Factor and Level of Detail", 8.14.3 "Mipmapping".
"""

from __future__ import annotations

import math

import numpy as np

from .alpha import AlphaError, sample_np

__all__ = [
    "NVTT_SCALE_MAX",
    "NVTT_STEPS",
    "NVTT_SUBSAMPLES",
    "box_mips",
    "coverage_mips",
    "mip_level",
    "nvtt_alpha_test_coverage",
    "nvtt_scale_alpha_to_coverage",
    "sample_mips",
]

#: FloatImage.cpp:1396 ``const uint n = 4``: sub-samples per cell side.
NVTT_SUBSAMPLES = 4
#: FloatImage.cpp:1454-1455 ``minAlphaScale = 0.0f``, ``maxAlphaScale = 4.0f``.
NVTT_SCALE_MAX = 4.0
#: FloatImage.cpp:1461 ``for (int i = 0; i < 10; i++)``: bisection steps.
NVTT_STEPS = 10


def _check_alpha(alpha) -> np.ndarray:
    a = np.asarray(alpha, dtype=np.float32)
    if a.ndim != 2 or a.size == 0 or not np.all(np.isfinite(a)):
        raise AlphaError(f"alpha must be a finite (H, W) array with H, W >= 1, got {a.shape}")
    return a


def _box_down(a: np.ndarray) -> np.ndarray:
    """One 2 x 2 box step (sizes halve, rounding down; an odd size's last index clamps)."""
    h, w = a.shape
    h2, w2 = max(1, h // 2), max(1, w // 2)
    r0 = np.minimum(2 * np.arange(h2), h - 1)
    r1 = np.minimum(r0 + 1, h - 1)
    c0 = np.minimum(2 * np.arange(w2), w - 1)
    c1 = np.minimum(c0 + 1, w - 1)
    s = a[r0][:, c0] + a[r0][:, c1] + a[r1][:, c0] + a[r1][:, c1]
    return (0.25 * s).astype(np.float32)


def box_mips(alpha) -> list[np.ndarray]:
    """The box-filtered mip chain of ``alpha`` ((H, W) in [0, 1]): level 0 first, to 1 x 1."""
    levels = [_check_alpha(alpha)]
    while levels[-1].shape != (1, 1):
        levels.append(_box_down(levels[-1]))
    return levels


def nvtt_alpha_test_coverage(alpha, alpha_ref: float, alpha_scale: float = 1.0) -> float:
    """NVTT's ``FloatImage::alphaTestCoverage`` (see the module text): the fraction of 4 x 4
    bilinear sub-samples per cell with ``saturate(alpha * scale) > alpha_ref``, float32
    arithmetic; NaN for a level 1 texel wide or high (NVTT's 0 / 0)."""
    a = np.clip(_check_alpha(alpha) * np.float32(alpha_scale), 0.0, 1.0)
    h, w = a.shape
    if h < 2 or w < 2:
        return math.nan
    n = NVTT_SUBSAMPLES
    f = ((np.arange(n, dtype=np.float32) + np.float32(0.5)) / np.float32(n)).astype(np.float32)
    fx, fy = f[None, :], f[:, None]
    a00, a10 = a[:-1, :-1, None, None], a[:-1, 1:, None, None]
    a01, a11 = a[1:, :-1, None, None], a[1:, 1:, None, None]
    one = np.float32(1.0)
    s = (
        a00 * (one - fx) * (one - fy)
        + a10 * fx * (one - fy)
        + a01 * (one - fx) * fy
        + a11 * fx * fy
    )
    count = np.count_nonzero(s > np.float32(alpha_ref), axis=(2, 3)).astype(np.float64)
    return float(np.sum(count / (n * n)) / ((w - 1) * (h - 1)))


def nvtt_scale_alpha_to_coverage(alpha, desired: float, alpha_ref: float) -> np.ndarray:
    """NVTT's ``FloatImage::scaleAlphaToCoverage``: ``alpha`` scaled by the factor (bisection
    over [0, 4] from 1, ten steps, the best one kept) whose coverage at ``alpha_ref`` is
    closest to ``desired``, clamped to [0, 1] (float32)."""
    a = _check_alpha(alpha)
    lo, hi, scale = 0.0, NVTT_SCALE_MAX, 1.0
    best_scale, best_error = 1.0, math.inf
    for _ in range(NVTT_STEPS):  # ten coverage counts of one level
        current = nvtt_alpha_test_coverage(a, alpha_ref, scale)
        error = abs(current - desired)
        if error < best_error:  # False for NaN, as in C
            best_error, best_scale = error, scale
        if current < desired:
            lo = scale
        elif current > desired:
            hi = scale
        else:  # equal, or NaN
            break
        scale = np.float32((lo + hi) * 0.5)
    return np.clip(a * np.float32(best_scale), 0.0, 1.0).astype(np.float32)


def coverage_mips(alpha, cutoff: float) -> list[np.ndarray]:
    """The coverage-preserving mip chain of ``alpha`` for alpha test ``cutoff`` (see the
    module text): level 0 unchanged, each further level the box-filtered level scaled to the
    base level's NVTT coverage."""
    chain = box_mips(alpha)
    desired = nvtt_alpha_test_coverage(chain[0], cutoff)
    return [chain[0]] + [nvtt_scale_alpha_to_coverage(m, desired, cutoff) for m in chain[1:]]


def mip_level(dudx, dvdx, dudy, dvdy, *, width: int, height: int, bias: float = 0.0):
    """OpenGL's level of detail ``lambda = log2(rho) + bias`` with ``rho = max(sqrt((W du/dx)^2
    + (H dv/dx)^2), sqrt((W du/dy)^2 + (H dv/dy)^2))`` (section 8.14.1; derivatives of the
    texture coordinates per pixel, texture ``width`` x ``height``). ``-inf`` where the footprint
    is a point (float64)."""
    w, h = float(width), float(height)
    rx = np.hypot(w * np.asarray(dudx, np.float64), h * np.asarray(dvdx, np.float64))
    ry = np.hypot(w * np.asarray(dudy, np.float64), h * np.asarray(dvdy, np.float64))
    rho = np.maximum(rx, ry)
    with np.errstate(divide="ignore"):
        return np.log2(rho) + bias


def sample_mips(
    levels: list[np.ndarray],
    u,
    v,
    lam,
    *,
    wrap_s: str = "repeat",
    wrap_t: str = "repeat",
    mag_nearest: bool = False,
) -> np.ndarray:
    """Trilinear (``LINEAR_MIPMAP_LINEAR``) alpha of a mip chain at ``u, v`` with levels of
    detail ``lam`` (arrays of one shape; see the module text), float64. A non-finite ``lam``
    below 0 (a point footprint) magnifies."""
    u, v, lam = np.broadcast_arrays(
        np.asarray(u, np.float64), np.asarray(v, np.float64), np.asarray(lam, np.float64)
    )
    q = len(levels) - 1
    out = np.zeros(u.shape)
    mag = ~(lam > 0.0)
    if np.any(mag):
        out[mag] = sample_np(
            levels[0], u[mag], v[mag], wrap_s=wrap_s, wrap_t=wrap_t, nearest=mag_nearest
        )
    d = np.where(mag, 0.0, np.minimum(np.where(np.isfinite(lam), lam, q), q))
    d1 = np.floor(d).astype(np.int64)
    frac = np.where(d1 >= q, 0.0, d - d1)
    for k in range(q + 1):  # levels, not pixels
        for level, weight in ((k, 1.0 - frac), (min(k + 1, q), frac)):
            sel = ~mag & (d1 == k) & (weight > 0)
            if np.any(sel):
                out[sel] += weight[sel] * sample_np(
                    levels[level], u[sel], v[sel], wrap_s=wrap_s, wrap_t=wrap_t
                )
    return out
