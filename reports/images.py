"""Arrays to embeddable images: colour maps, downscaling and data-URI encoding.

Conventions: images are float arrays, row 0 at the top. Visibility and error maps are
``(H, W)``; colour images are ``(H, W, 3)`` sRGB-encoded in [0, 1]. Encoded images are
``data:`` URIs (PNG for visibility, heatmaps and crops; WebP, or JPEG where Pillow lacks WebP,
for colour thumbnails).
"""

from __future__ import annotations

import base64
import functools
import io
import math

import numpy as np
from PIL import Image, features

__all__ = [
    "COLOR_QUALITY",
    "SIGNED_NEGATIVE",
    "SIGNED_POSITIVE",
    "colorbar_uri",
    "colorize",
    "downscale_factor",
    "encode_color",
    "encode_heatmap",
    "encode_visibility",
    "palette",
    "reduce_error",
    "reduce_image",
]

#: Lossy quality of colour thumbnails: 85 keeps Monte Carlo noise and aliasing visible at
#: about a tenth of the PNG size.
COLOR_QUALITY = 85

#: Signed style end colours (sRGB 8-bit): positive = false-lit (green), negative =
#: false-shadowed (red); zero is black, like the bottom of magma.
SIGNED_POSITIVE = (46, 204, 64)
SIGNED_NEGATIVE = (240, 60, 50)

#: Number of palette entries of the signed style: odd, so that zero is one exact entry.
_SIGNED_LEVELS = 255


@functools.cache
def palette(style: str) -> np.ndarray:
    """Return the ``(N, 3)`` uint8 palette of ``style`` ("magma": 256, "signed": 255 entries)."""
    if style == "magma":
        from matplotlib import colormaps

        rgb = colormaps["magma"](np.linspace(0.0, 1.0, 256))[:, :3]
        return np.round(rgb * 255.0).astype(np.uint8)
    if style == "signed":
        v = np.linspace(-1.0, 1.0, _SIGNED_LEVELS)[:, None]
        pos = np.asarray(SIGNED_POSITIVE, dtype=np.float64)[None, :]
        neg = np.asarray(SIGNED_NEGATIVE, dtype=np.float64)[None, :]
        rgb = np.where(v >= 0.0, v * pos, -v * neg)
        return np.round(rgb).astype(np.uint8)
    raise ValueError(f"style must be one of ['magma', 'signed'], got {style!r}")


def colorize(data: np.ndarray, *, style: str, value_range: tuple[float, float]) -> Image.Image:
    """Map ``(H, W)`` values to a palette image; values outside ``value_range`` saturate."""
    lut = palette(style)
    lo, hi = value_range
    t = np.clip((np.asarray(data, dtype=np.float64) - lo) / (hi - lo), 0.0, 1.0)
    index = np.round(t * (len(lut) - 1)).astype(np.uint8)
    image = Image.fromarray(index)
    image.putpalette(lut.tobytes())
    return image


def _uri(image: Image.Image, fmt: str, **options) -> str:
    buffer = io.BytesIO()
    image.save(buffer, format=fmt, **options)
    mime = {"PNG": "image/png", "WEBP": "image/webp", "JPEG": "image/jpeg"}[fmt]
    return f"data:{mime};base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _to_uint8(values: np.ndarray) -> np.ndarray:
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def encode_visibility(vis: np.ndarray) -> str:
    """Encode ``(H, W)`` visibility in [0, 1] (1 = lit = white) as a grey PNG data URI."""
    return _uri(Image.fromarray(_to_uint8(vis)), "PNG", optimize=True)


def encode_color(rgb: np.ndarray, *, lossless: bool = False) -> str:
    """Encode ``(H, W, 3)`` sRGB in [0, 1]: WebP/JPEG thumbnail, or PNG when ``lossless``."""
    image = Image.fromarray(_to_uint8(rgb))
    if lossless:
        return _uri(image, "PNG", optimize=True)
    if features.check("webp"):
        return _uri(image, "WEBP", quality=COLOR_QUALITY, method=4)
    return _uri(image, "JPEG", quality=COLOR_QUALITY, optimize=True)


def encode_heatmap(data: np.ndarray, *, style: str, value_range: tuple[float, float]) -> str:
    """Encode an ``(H, W)`` error map with its fixed-range palette as a PNG data URI."""
    return _uri(colorize(data, style=style, value_range=value_range), "PNG", optimize=True)


@functools.cache
def colorbar_uri(style: str) -> str:
    """A 256 x 1 PNG of the palette of ``style``, left = low end, for CSS stretching."""
    lut = palette(style)
    index = np.linspace(0, len(lut) - 1, 256).round().astype(np.uint8)
    return _uri(Image.fromarray(lut[index][None, :, :]), "PNG", optimize=True)


def downscale_factor(shape: tuple[int, ...], *, max_size: int) -> int:
    """Smallest integer factor that brings the longer side of ``shape`` to ``<= max_size``."""
    return max(1, math.ceil(max(shape[0], shape[1]) / max_size))


def _blocks(values: np.ndarray, factor: int) -> np.ndarray:
    """View ``values`` as ``(h, factor, w, factor, ...)`` blocks, padding by edge replication."""
    h, w = -(-values.shape[0] // factor), -(-values.shape[1] // factor)
    pad = [(0, h * factor - values.shape[0]), (0, w * factor - values.shape[1])]
    pad += [(0, 0)] * (values.ndim - 2)
    padded = np.pad(values, pad, mode="edge")
    return padded.reshape(h, factor, w, factor, *values.shape[2:])


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def reduce_image(values: np.ndarray, factor: int, *, srgb: bool) -> np.ndarray:
    """Box-filter ``values`` by an integer ``factor``; sRGB data is averaged in linear light."""
    if factor == 1:
        return values
    data = _srgb_to_linear(values.astype(np.float64)) if srgb else values.astype(np.float64)
    mean = _blocks(data, factor).mean(axis=(1, 3))
    return (_linear_to_srgb(mean) if srgb else mean).astype(np.float32)


def reduce_error(values: np.ndarray, factor: int) -> np.ndarray:
    """Downscale an error map keeping, per block, the value of largest magnitude.

    Averaging would dilute thin errors (a one-pixel shadow acne line) until they vanish from
    the thumbnail; the signed maximum keeps every error visible.
    """
    if factor == 1:
        return values
    blocks = _blocks(values, factor)
    h, _, w, _ = blocks.shape
    flat = blocks.transpose(0, 2, 1, 3).reshape(h, w, factor * factor)
    pick = np.abs(flat).argmax(axis=2)
    return np.take_along_axis(flat, pick[..., None], axis=2)[..., 0]
