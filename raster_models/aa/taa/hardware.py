"""What the GPU does to a TAA's buffers between shader instructions: 8-bit sRGB storage
(unorm8 with the sRGB transfer on write and its inverse on read), half-float storage, and
the bilinear fetches that engines' 5-tap Catmull-Rom history sampler is built from.

All positions are film positions in pixels (x right, y down, texel ``i`` centred at
``i + 0.5``); every fetch clamps to the edge texel (``CLAMP_TO_EDGE`` / ``TextureWrapMode.Clamp``).

References
----------
IEC 61966-2-1:1999 (sRGB transfer functions).
Microsoft, Direct3D 11.3 Functional Specification, 3.2.3.6 FLOAT -> UNORM conversion (round
to nearest) and 7.18.8 (sRGB textures are converted to linear before filtering).
M. Pettineo, An HLSL function for sampling a 2D texture with Catmull-Rom filtering using 9
texture samples (TheRealMJP/Shadows, 2016): the 9-tap form the engines cut to 5 taps.
"""

from __future__ import annotations

import numpy as np

from .filters import bilinear

__all__ = [
    "catmull_rom_5tap",
    "r11g11b10",
    "half_float",
    "srgb8_store",
    "srgb_decode",
    "srgb_encode",
]


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer (IEC 61966-2-1) of values in ``[0, 1]``."""
    c = np.asarray(linear, dtype=np.float64)
    curve = 1.055 * np.power(np.maximum(c, 0.0), 1 / 2.4) - 0.055
    return np.where(c <= 0.0031308, 12.92 * c, curve)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """The inverse sRGB transfer (what an sRGB texture fetch returns before filtering)."""
    c = np.asarray(encoded, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


def srgb8_store(linear: np.ndarray) -> np.ndarray:
    """A linear colour written to an RGBA8 sRGB render target and read back (decoded): the
    value saturated to ``[0, 1]``, encoded, rounded to the nearest of 255 steps, decoded."""
    code = np.rint(255.0 * srgb_encode(np.clip(linear, 0.0, 1.0)))
    return srgb_decode(code / 255.0)


def half_float(values: np.ndarray) -> np.ndarray:
    """Values stored in a 16-bit float (RGBA16F / RGB16F) buffer and read back."""
    return np.asarray(values, dtype=np.float64).astype(np.float16).astype(np.float64)


def catmull_rom_5tap(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The 5-tap Catmull-Rom history sampler of Filament's ``taa.mat`` and HDRP's
    ``TemporalAntialiasing.hlsl`` (Pettineo's 9-tap form without its 4 corner taps): the
    middle two texels of each axis in one bilinear fetch each, weights renormalized by their
    sum ``k0 + ... + k4``."""
    sx, sy = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    t1x, t1y = np.floor(sx - 0.5) + 0.5, np.floor(sy - 0.5) + 0.5
    w = {}
    for axis, s, t1 in (("x", sx, t1x), ("y", sy, t1y)):
        f = s - t1
        f2, f3 = f * f, f * f * f
        w0 = f2 - 0.5 * (f3 + f)
        w1 = 1.5 * f3 - 2.5 * f2 + 1.0
        w3 = 0.5 * (f3 - f2)
        w2 = 1.0 - w0 - w1 - w3
        w12 = w1 + w2
        w[axis] = (w0, w12, w3, t1 - 1.0, t1 + w2 / w12, t1 + 2.0)
    w0x, w12x, w3x, p0x, p12x, p3x = w["x"]
    w0y, w12y, w3y, p0y, p12y, p3y = w["y"]
    taps = (
        (w12x * w0y, p12x, p0y),
        (w0x * w12y, p0x, p12y),
        (w12x * w12y, p12x, p12y),
        (w3x * w12y, p3x, p12y),
        (w12x * w3y, p12x, p3y),
    )
    total = sum(k for k, _, _ in taps)
    out = sum(k[..., None] * bilinear(img, px, py) for k, px, py in taps)
    return out / total[..., None]


def _small_float(v: np.ndarray, mantissa_bits: int) -> np.ndarray:
    """Non-negative values rounded to an unsigned float with a 5-bit exponent (bias 15) and
    ``mantissa_bits`` mantissa bits, to nearest (ties to even); negatives and NaN read 0,
    values beyond the largest finite one read it."""
    v = np.nan_to_num(np.asarray(v, dtype=np.float64), nan=0.0, posinf=np.inf)
    v = np.maximum(v, 0.0)
    largest = (2.0 - 2.0**-mantissa_bits) * 2.0**15
    with np.errstate(divide="ignore"):
        e = np.floor(np.log2(np.where(v > 0, v, 1.0)))
    e = np.maximum(e, -14.0)  # denormals share the smallest normal exponent's step
    ulp = np.power(2.0, e - mantissa_bits)
    return np.minimum(np.rint(v / ulp) * ulp, largest)


def r11g11b10(rgb: np.ndarray) -> np.ndarray:
    """Values stored in an R11G11B10 float buffer (6, 6 and 5 mantissa bits) and read back."""
    rgb = np.asarray(rgb, dtype=np.float64)
    bits = (6, 6, 5)
    return np.stack([_small_float(rgb[..., i], bits[i]) for i in range(3)], -1)
