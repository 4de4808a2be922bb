"""The image gates engine teams already use, computed against the ray-traced truth.

- **Unreal Engine's screenshot comparison** (``FImageComparer::Compare``): two 8-bit display
  images; a pixel mismatches when a channel differs by more than the tolerance and, where
  either image is anti-aliased there (``IgnoreAntiAliasing``), its luminance differs by more
  than ``MinBrightness`` too. The **global error** is the mismatched fraction of the image,
  the **local error** the largest mismatched fraction of the 10 x 10 grid of blocks. A
  comparison passes when both are within ``MaximumGlobalError`` / ``MaximumLocalError``.
- **Unity's Graphics Test Framework** (``ImageAssert.AreEqual``): the per-pixel colour
  difference is the JzAzBz delta E (Safdar et al. 2017) of the 8-bit sRGB pixels; its
  excess over ``PerPixelCorrectnessThreshold`` averaged over the image must stay within
  ``AverageCorrectnessThreshold``.
- **An edge-aware tolerance** for data channels (visibility, coverage): a pixel whose truth
  is fractional (an edge crosses it) may differ by ``z`` standard errors plus the sub-pixel
  position error of the edge; any other pixel by ``z`` standard errors only. The error is
  the fraction of pixels beyond their tolerance.

Inputs are ``(H, W)`` grey or ``(H, W, 3)`` display images in [0, 1] (sRGB-encoded, as a
screenshot holds them; grey data as is) for the first two, linear data for the third.

References
----------
.. [1] Epic Games, Unreal Engine 4.27/5.x source: ``ScreenShotComparisonTools/Public/
   ImageComparer.h`` (``FImageTolerance``), ``Private/ImageComparer.cpp`` (``Compare``,
   ``IsAntialiased``), ``FunctionalTesting/Private/AutomationScreenshotOptions.cpp``
   (``SetToleranceAmounts``: Low, Medium, High; ``MaximumLocalError`` 0.10,
   ``MaximumGlobalError`` 0.02).
.. [2] Unity Technologies, Graphics Test Framework ``ImageAssert.cs`` (``RGBtoJAB``,
   ``JABDeltaE``) and the URP test projects' ``ImageComparisonSettings`` (per-pixel 0.001,
   average 0.005).
.. [3] M. Safdar, G. Cui, Y. J. Kim, M. R. Luo, "Perceptually uniform color space for image
   signals including high dynamic range and wide gamut", Optics Express 25(13), 2017.
   doi:10.1364/OE.25.015131
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .tonemap import srgb_decode

__all__ = [
    "UNITY_AVERAGE_THRESHOLD",
    "UNITY_PER_PIXEL_THRESHOLD",
    "UNREAL_TOLERANCES",
    "UnrealTolerance",
    "edge_aware_error",
    "jzazbz",
    "to_8bit",
    "unity_delta_e",
    "unreal_comparison",
    "unreal_comparisons",
]


@dataclass(frozen=True)
class UnrealTolerance:
    """``FImageTolerance``: per-channel tolerances (8-bit levels), the luminance tolerances,
    anti-aliasing relaxation and the local/global error limits."""

    red: int
    green: int
    blue: int
    alpha: int
    min_brightness: int
    max_brightness: int
    ignore_anti_aliasing: bool = True
    maximum_local_error: float = 0.10
    maximum_global_error: float = 0.02


#: ``EComparisonTolerance`` Low / Medium / High (``SetToleranceAmounts``) with the
#: screenshot options' defaults: ``bIgnoreAntiAliasing`` true, ``MaximumLocalError`` 0.10,
#: ``MaximumGlobalError`` 0.02 (``FAutomationScreenshotOptions``' constructor).
UNREAL_TOLERANCES = {
    "low": UnrealTolerance(16, 16, 16, 16, 16, 240),
    "medium": UnrealTolerance(24, 24, 24, 24, 24, 220),
    "high": UnrealTolerance(32, 32, 32, 32, 64, 96),
}
#: The URP graphics test projects' ``ImageComparisonSettings``.
UNITY_PER_PIXEL_THRESHOLD = 0.001
UNITY_AVERAGE_THRESHOLD = 0.005
#: Rec. 709 luminance weights, as ``FPixelOperations::GetLuminance`` uses them.
_LUMA = np.array([0.2126, 0.7152, 0.0722])
_NEIGHBOURS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]


def to_8bit(display) -> np.ndarray:
    """A display image in [0, 1] as 8-bit RGB levels (``(H, W, 3)`` int32; grey repeated),
    as a screenshot stores it."""
    d = np.asarray(display, dtype=np.float64)
    if d.ndim == 2:
        d = np.repeat(d[..., None], 3, axis=-1)
    return np.round(np.clip(d, 0.0, 1.0) * 255.0).astype(np.int32)


def _hue(rgb: np.ndarray) -> np.ndarray:
    """``FPixelOperations::GetHue`` of 8-bit RGB, in [0, 1)."""
    c = rgb.astype(np.float64) / 255.0
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    mx, mn = c.max(axis=-1), c.min(axis=-1)
    delta = np.where(mx > mn, mx - mn, 1.0)
    hue = np.where(mx == r, (g - b) / delta + np.where(g < b, 6.0, 0.0), 0.0)
    hue = np.where((mx != r) & (mx == g), (b - r) / delta + 2.0, hue)
    hue = np.where((mx != r) & (mx != g) & (mx == b), (r - g) / delta + 4.0, hue)
    return np.where(mx > mn, hue / 6.0, 0.0)


def _shifted(padded: np.ndarray, dy: int, dx: int, h: int, w: int) -> np.ndarray:
    """The ``(dy, dx)`` neighbour of every pixel, from an image padded by one pixel."""
    return padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]


def _aa_features(rgb: np.ndarray) -> dict:
    """What ``IsAntialiased`` counts over the eight neighbours, for any tolerance: identical
    neighbours, neighbours of another hue (> 0.3), and the second largest luminance
    difference to a neighbour (more than one high-contrast neighbour is that one above the
    tolerance; outside the image a neighbour is never high-contrast)."""
    h, w = rgb.shape[:2]
    lum = rgb @ _LUMA
    hue = _hue(rgb)
    # one integer per 8-bit colour: identical neighbours compare once, not per channel
    packed = (rgb[..., 0] * 256 + rgb[..., 1]) * 256 + rgb[..., 2]
    p_rgb = np.pad(packed, 1, constant_values=-1)
    p_lum = np.pad(lum, 1, constant_values=-np.inf)
    p_hue = np.pad(hue, 1, constant_values=np.nan)
    same = np.zeros((h, w), np.int32)
    other_hue = np.zeros((h, w), np.int32)
    diffs = np.empty((len(_NEIGHBOURS), h, w))
    for i, (dy, dx) in enumerate(_NEIGHBOURS):  # eight passes, not a loop over pixels
        same += packed == _shifted(p_rgb, dy, dx, h, w)
        with np.errstate(invalid="ignore"):
            other_hue += np.abs(hue - _shifted(p_hue, dy, dx, h, w)) > 0.3
        # outside the image: |lum - -inf| = inf; set to -inf below (never above a tolerance)
        diffs[i] = np.abs(lum - _shifted(p_lum, dy, dx, h, w))
    diffs[np.isinf(diffs)] = -np.inf
    second = np.partition(diffs, len(_NEIGHBOURS) - 2, axis=0)[len(_NEIGHBOURS) - 2]
    return {"same": same, "other_hue": other_hue, "second_lum_diff": second}


def _anti_aliased(features: dict, tol: UnrealTolerance) -> np.ndarray:
    """``FPixelOperations::IsAntialiased`` of every pixel: more than one high-contrast or
    other-hue neighbour, or fewer than two identical ones."""
    contrast = features["second_lum_diff"] > tol.max_brightness
    return (features["other_hue"] > 1) | contrast | (features["same"] < 2)


def prepare_reference(reference) -> dict:
    """The reference's side of :func:`unreal_comparisons` and :func:`unity_delta_e` (its
    8-bit levels, anti-aliasing features and JzAzBz), computed once for every candidate
    judged against it: pass it as ``prepared``."""
    a = to_8bit(reference)
    return {"rgb8": a, "features": _aa_features(a), "jab": jzazbz(a)}


def unreal_comparisons(reference, candidate, *, tolerances: dict, prepared=None) -> dict:
    """:func:`unreal_comparison` at each of ``tolerances`` (name -> tolerance), sharing the
    work that does not depend on the tolerance; ``prepared``: :func:`prepare_reference` of
    ``reference`` (then ``reference`` itself is not read)."""
    a = to_8bit(reference) if prepared is None else prepared["rgb8"]
    b = to_8bit(candidate)
    if a.shape != b.shape:
        raise ValueError(f"reference and candidate shapes differ: {a.shape} and {b.shape}")
    fa = _aa_features(a) if prepared is None else prepared["features"]
    fb = _aa_features(b)
    channel_diff = np.abs(a - b)
    lum_diff = np.abs(a @ _LUMA - b @ _LUMA)
    h, w = a.shape[:2]
    # 100 blocks: FMath::RoundFromZero(size / 10.0), i.e. ceil for positive sizes
    by, bx = int(np.ceil(h / 10.0)), int(np.ceil(w / 10.0))
    y, x = np.mgrid[0:h, 0:w]
    block = (y // by) * 10 + x // bx
    out = {}
    for name, tol in tolerances.items():
        limits = np.array([tol.red, tol.green, tol.blue])
        similar = np.all(channel_diff <= limits, axis=-1)  # alpha: both opaque
        relaxed = np.zeros(similar.shape, bool)
        if tol.ignore_anti_aliasing:
            aa = _anti_aliased(fa, tol) | _anti_aliased(fb, tol)
            relaxed = aa & (lum_diff <= tol.min_brightness)
        mismatch = ~similar & ~relaxed
        counts = np.bincount(block[mismatch], minlength=100)
        local = float(counts.max()) / (bx * by)
        global_ = float(mismatch.mean())
        passed = local <= tol.maximum_local_error and global_ <= tol.maximum_global_error
        out[name] = {
            "global_error": global_,
            "local_error": local,
            "passed": passed,
            "mismatch": mismatch,
        }
    return out


def unreal_comparison(reference, candidate, *, tolerance: UnrealTolerance) -> dict:
    """Unreal's screenshot comparison of two display images (see the module docstring).

    Returns ``{"global_error", "local_error", "passed", "mismatch"}``: the mismatched
    fraction of the image and of its worst block of the 10 x 10 grid, whether both are
    within the tolerance's limits, and the ``(H, W)`` bool mismatch map.
    """
    return unreal_comparisons(reference, candidate, tolerances={"t": tolerance})["t"]


def jzazbz(rgb8: np.ndarray) -> np.ndarray:
    """JzAzBz of 8-bit sRGB pixels as Unity's ``RGBtoJAB`` computes it: sRGB decoded to
    linear, to XYZ (D65) x 100, then Safdar et al.'s transform with peak 10000."""
    lin = srgb_decode(np.asarray(rgb8, dtype=np.float64) / 255.0)
    m = np.array(
        [
            [0.4124564, 0.3575761, 0.1804375],
            [0.2126729, 0.7151522, 0.0721750],
            [0.0193339, 0.1191920, 0.9503041],
        ]
    )
    xyz = (lin @ m.T) * 100.0
    X, Y, Z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    b, g = 1.15, 0.66
    x2, y2 = b * X - (b - 1.0) * Z, g * Y - (g - 1.0) * X
    lms = np.stack(
        [
            0.41478372 * x2 + 0.579999 * y2 + 0.0146480 * Z,
            -0.2015100 * x2 + 1.120649 * y2 + 0.0531008 * Z,
            -0.0166008 * x2 + 0.264800 * y2 + 0.6684799 * Z,
        ],
        -1,
    )
    c1, c2, c3 = 3424 / 2**12, 2413 / 2**7, 2392 / 2**7
    n, p = 2610 / 2**14, 1.7 * 2523 / 2**5
    lp = np.power(np.maximum(lms, 0.0) / 10000.0, n)
    lms_p = np.power((c1 + c2 * lp) / (1.0 + c3 * lp), p)
    iz = 0.5 * lms_p[..., 0] + 0.5 * lms_p[..., 1]
    az = 3.524000 * lms_p[..., 0] - 4.066708 * lms_p[..., 1] + 0.542708 * lms_p[..., 2]
    bz = 0.199076 * lms_p[..., 0] + 1.096799 * lms_p[..., 1] - 1.295875 * lms_p[..., 2]
    d, d0 = -0.56, 1.6295499532821566e-11
    jz = ((1.0 + d) * iz) / (1.0 + d * iz) - d0
    return np.stack([jz, az, bz], -1)


def _hue_angle(jab: np.ndarray) -> np.ndarray:
    """``Mathf.Atan(b / a)`` as Unity computes it (the limit where ``a`` is 0)."""
    a, b = jab[..., 1], jab[..., 2]
    safe = np.where(a != 0.0, a, 1.0)
    return np.where(a != 0.0, np.arctan(b / safe), np.sign(b) * np.pi / 2.0)


def unity_delta_e(
    reference,
    candidate,
    *,
    per_pixel_threshold: float = UNITY_PER_PIXEL_THRESHOLD,
    prepared=None,
) -> dict:
    """Unity's ``ImageAssert`` difference of two display images: ``{"average": mean over
    pixels of max(0, dE - per_pixel_threshold), "max": largest dE, "map": (H, W) dE}``,
    with dE the JzAzBz difference of ``JABDeltaE``; ``prepared``: as in
    :func:`unreal_comparisons`."""
    a = jzazbz(to_8bit(reference)) if prepared is None else prepared["jab"]
    b = jzazbz(to_8bit(candidate))
    ca, cb = np.hypot(a[..., 1], a[..., 2]), np.hypot(b[..., 1], b[..., 2])
    dh = 2.0 * np.sqrt(ca * cb) * np.sin((_hue_angle(a) - _hue_angle(b)) / 2.0)
    de = np.sqrt((a[..., 0] - b[..., 0]) ** 2 + (ca - cb) ** 2 + dh**2)
    over = np.maximum(de - per_pixel_threshold, 0.0)
    return {"average": float(over.mean()), "max": float(de.max()), "map": de}


def edge_aware_error(
    reference,
    candidate,
    *,
    reference_stderr,
    mask=None,
    z: float = 3.0,
    position_error: float = 0.25,
) -> dict:
    """Fraction of pixels beyond an edge-aware tolerance (data in [0, 1]: visibility or
    coverage).

    A pixel may differ from the truth by ``z`` standard errors of the reference; where the
    truth is fractional (an edge crosses the pixel) also by ``position_error``: moving a
    straight edge by ``d`` pixels changes the covered fraction of a pixel it crosses by at
    most ``d`` (the edge's length in a unit pixel is at most sqrt(2), its component across
    the motion at most 1). A pixel that is all lit or all shadowed in the truth gets no such
    allowance: a shadow moved by a whole pixel fails on the pixels beside its edge.

    Returns ``{"fraction", "count", "allowance": (H, W) map}`` over ``mask`` (None: all).
    """
    r = np.asarray(reference, dtype=np.float64)
    c = np.asarray(candidate, dtype=np.float64)
    se = np.asarray(reference_stderr, dtype=np.float64)
    fractional = (r > 0.0) & (r < 1.0)
    allowance = z * se + np.where(fractional, position_error, 0.0)
    beyond = np.abs(c - r) > allowance + 1e-6  # float32 rounding of stored values
    if mask is not None:
        beyond = beyond[np.asarray(mask, dtype=bool)]
    n = beyond.size
    return {
        "fraction": float(beyond.mean()) if n else 0.0,
        "count": int(beyond.sum()),
        "allowance": allowance,
    }
