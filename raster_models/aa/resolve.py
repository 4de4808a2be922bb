"""Multisample resolves: the box average in linear, and wide separable filters.

A resolve turns per-sample colours ``(P, N, 3)`` (P pixels row-major, N samples at the
same offsets in every pixel) into one colour per pixel. ``box`` averages a pixel's own
samples (the hardware resolve, ``ResolveSubresource``). The wide filters weigh every sample
within the filter radius of the pixel centre, including the neighbours' samples, by a
separable kernel ``f(dx) f(dy)`` and divide by the sum of the weights used (so the image
border needs no special case). With ``inverse_luminance`` each sample's weight is divided by
``1 + luma`` (luma: Rec. 709 weights), the "tone-mapped resolve" that keeps a very bright
sample from dominating an edge pixel.

Radii (pixels): triangle 1; Gaussian 2 (standard deviation 0.5, Mitsuba's ``gaussian``
reconstruction filter, with its value at the radius subtracted so it reaches 0);
Blackman-Harris 2, Mitchell-Netravali (B = C = 1/3) 2 and Catmull-Rom (B = 0, C = 1/2) 2,
the filter width MJP's MSAAFilter sample uses by default.

References
----------
D. P. Mitchell, A. N. Netravali, Reconstruction filters in computer graphics, SIGGRAPH 1988,
doi:10.1145/54852.378514.
F. J. Harris, On the use of windows for harmonic analysis with the discrete Fourier
transform, Proc. IEEE 66(1), 1978, doi:10.1109/PROC.1978.10837.
M. Pettineo, MSAAFilter sample (TheRealMJP/MSAAFilter), 2012-2015.
B. Karis, High-quality temporal supersampling, SIGGRAPH 2014 course (inverse-luminance
weighting).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "FILTERS",
    "LUMA_WEIGHTS",
    "box_from_fragments",
    "filter_weight",
    "resolve",
]

#: Resolve filters by name.
FILTERS = ("box", "triangle", "gaussian", "blackman-harris", "mitchell", "catmull-rom")

#: Rec. 709 luminance weights of linear RGB (the inverse-luminance weighting).
LUMA_WEIGHTS = (0.2126, 0.7152, 0.0722)

_RADIUS = {
    "box": 0.5,
    "triangle": 1.0,
    "gaussian": 2.0,
    "blackman-harris": 2.0,
    "mitchell": 2.0,
    "catmull-rom": 2.0,
}


def _cubic(x, b, c):
    x = np.abs(x)
    near = ((12 - 9 * b - 6 * c) * x**3 + (-18 + 12 * b + 6 * c) * x**2 + (6 - 2 * b)) / 6
    far = (
        (-b - 6 * c) * x**3 + (6 * b + 30 * c) * x**2 + (-12 * b - 48 * c) * x + (8 * b + 24 * c)
    ) / 6
    return np.where(x < 1, near, np.where(x < 2, far, 0.0))


def filter_weight(name: str, x: np.ndarray) -> np.ndarray:
    """1D kernel ``f(x)`` of ``name`` at offsets ``x`` (pixels) from the pixel centre."""
    x = np.asarray(x, dtype=np.float64)
    r = _RADIUS[name]
    inside = np.abs(x) <= r
    if name == "box":
        w = np.ones_like(x)
        inside = np.abs(x) < r
    elif name == "triangle":
        w = 1.0 - np.abs(x) / r
    elif name == "gaussian":
        sigma = 0.5
        w = np.exp(-(x**2) / (2 * sigma**2)) - math.exp(-(r**2) / (2 * sigma**2))
    elif name == "blackman-harris":
        t = (x / (2 * r)) + 0.5
        a0, a1, a2, a3 = 0.35875, 0.48829, 0.14128, 0.01168
        w = (
            a0
            - a1 * np.cos(2 * np.pi * t)
            + a2 * np.cos(4 * np.pi * t)
            - a3 * np.cos(6 * np.pi * t)
        )
    elif name == "mitchell":
        w = _cubic(x, 1 / 3, 1 / 3)
    elif name == "catmull-rom":
        w = _cubic(x, 0.0, 0.5)
    else:  # pragma: no cover - guarded by the parameter choices
        raise KeyError(name)
    return np.where(inside, w, 0.0)


def resolve(
    colors: np.ndarray,
    offsets: np.ndarray,
    width: int,
    height: int,
    name: str = "box",
    *,
    inverse_luminance: bool = False,
) -> np.ndarray:
    """Resolve ``(P, N, 3)`` sample colours at ``offsets`` ``(N, 2)`` to ``(H, W, 3)`` float32.

    The box filter averages each pixel's own samples (float64 sums). Wide filters loop over
    the pixel offsets of their support (at most 5 x 5 rounds, vectorized over the image).
    """
    offs = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    if name == "box" and not inverse_luminance:
        # Unit weights: the float64 sum of the samples over their count, reduced over the
        # sample axis in place of the colours' own layout (no float64 copy of every sample).
        src = np.asarray(colors).reshape(height, width, -1, 3)
        num = np.add.reduce(src, axis=2, dtype=np.float64)
        return (num / float(src.shape[2])).astype(np.float32)
    c = np.asarray(colors, dtype=np.float64).reshape(height, width, -1, 3)
    wl = np.ones(c.shape[:3])
    if inverse_luminance:
        wl = 1.0 / (1.0 + np.maximum(c @ np.asarray(LUMA_WEIGHTS), 0.0))
    if name == "box":
        num = np.einsum("hwn,hwnc->hwc", wl, c)
        den = wl.sum(axis=2)
        return (num / den[..., None]).astype(np.float32)
    r = _RADIUS[name]
    reach = int(math.ceil(r + 0.5))
    num = np.zeros((height, width, 3))
    den = np.zeros((height, width))
    wc = wl[..., None] * c
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            # samples of pixel (x + dx, y + dy) seen from the centre of pixel (x, y)
            fx = filter_weight(name, dx + offs[:, 0] - 0.5)
            fy = filter_weight(name, dy + offs[:, 1] - 0.5)
            k = fx * fy
            if not np.any(k):
                continue
            ys, yd = _span(dy, height)
            xs, xd = _span(dx, width)
            num[yd, xd] += np.tensordot(wc[ys, xs], k, axes=([2], [0]))
            den[yd, xd] += wl[ys, xs] @ k
    return (num / np.where(den > 0, den, 1.0)[..., None]).astype(np.float32)


def box_from_fragments(
    pixel, count, rgb, n: int, n_pix: int, *, inverse_luminance: bool = False
) -> np.ndarray:
    """The box resolve of :func:`resolve` computed per fragment: a fragment's colour fills
    the ``count`` samples it owns, the pixel's other samples are sky (0); ``(P, 3)`` float32.

    Identical in value to averaging the ``(P, N, 3)`` sample colours (float64 sums), without
    building them.
    """
    c = np.asarray(rgb, np.float64)
    w = np.asarray(count, np.float64)
    if inverse_luminance:
        w = w / (1.0 + np.maximum(c @ np.asarray(LUMA_WEIGHTS), 0.0))
    num = np.stack(
        [np.bincount(pixel, weights=w * c[:, k], minlength=n_pix) for k in range(3)], axis=1
    )
    if inverse_luminance:
        sky = n - np.bincount(pixel, weights=count, minlength=n_pix)
        den = np.bincount(pixel, weights=w, minlength=n_pix) + sky
    else:
        den = np.full(n_pix, float(n))
    return (num / den[:, None]).astype(np.float32)


def _span(d: int, size: int) -> tuple[slice, slice]:
    """Source and destination slices for reading pixel ``i + d`` into pixel ``i``."""
    if d >= 0:
        return slice(d, size), slice(0, size - d)
    return slice(0, size + d), slice(-d, size)
