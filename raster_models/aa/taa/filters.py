"""Reconstruction of the current frame and resampling of the history.

Current frame (the jittered one-sample image): ``ue4`` weighs the 3x3 neighbours' samples by
``exp(-2.29 d^2)``, ``d`` the distance in pixels from this pixel's centre to the neighbour's
sample (UE4 ``PostProcessTemporalAA.cpp``: a Gaussian fit of the Blackman-Harris window, the
weights normalized to sum 1); ``box`` takes the pixel's own sample (a one-pixel box holds
only it: INSIDE's unfiltered colour).

History: ``bilinear`` (one hardware bilinear fetch) or ``catmull-rom`` (the 4x4 Catmull-Rom
spline, B = 0, C = 0.5; engines evaluate it in 9 or 5 bilinear fetches, the same values up
to the corner taps the 5-tap form drops). Positions outside the image clamp to the edge.

References
----------
B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014 (Blackman-Harris filter of the
jittered samples, Catmull-Rom history).
E. Catmull, R. Rom, A class of local interpolating splines, 1974.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "HISTORY_FILTERS",
    "INPUT_FILTERS",
    "UE4_FILTER_K",
    "bilinear",
    "catmull_rom",
    "filter_current",
    "filter_weights",
    "neighbours",
]

INPUT_FILTERS = ("ue4", "box")
HISTORY_FILTERS = ("bilinear", "catmull-rom")
#: UE4's exponent of its Blackman-Harris approximation ``exp(-2.29 d^2)``.
UE4_FILTER_K = 2.29
#: 3x3 neighbour offsets (dx, dy), row by row; index 4 is the pixel itself.
OFFSETS_3X3 = np.array([(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)], dtype=np.float64)
#: The plus-shaped (5-tap) subset of :data:`OFFSETS_3X3`.
PLUS = np.array([1, 3, 4, 5, 7])


def filter_weights(jitter, kind: str = "ue4") -> np.ndarray:
    """``(9,)`` normalized weights of the 3x3 neighbours' samples (order of
    :data:`OFFSETS_3X3`) for a frame jittered by ``jitter`` (pixels, x right, y down)."""
    if kind == "box":
        w = np.zeros(9)
        w[4] = 1.0
        return w
    d = OFFSETS_3X3 + np.asarray(jitter, dtype=np.float64)
    w = np.exp(-UE4_FILTER_K * np.sum(d * d, axis=1))
    return w / w.sum()


def neighbours(img: np.ndarray) -> np.ndarray:
    """``(9, H, W, C)``: each pixel's 3x3 neighbours (edge pixels repeat the border)."""
    h, w = img.shape[:2]
    pad = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode="edge")
    return np.stack(
        [pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] for dx, dy in OFFSETS_3X3.astype(int)]
    )


def filter_current(samples: np.ndarray, jitter, kind: str) -> np.ndarray:
    """The current frame reconstructed at the pixel centres from its jittered samples
    (``(H, W, C)``)."""
    w = filter_weights(jitter, kind)
    return np.tensordot(w, neighbours(samples), axes=1)


def _fetch(img, xi, yi):
    h, w = img.shape[:2]
    return img[np.clip(yi, 0, h - 1), np.clip(xi, 0, w - 1)]


def bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``img`` (``(H, W, C)``, texel centres at ``i + 0.5``) bilinearly sampled at film
    positions ``x``, ``y`` (``(H, W)``)."""
    fx, fy = x - 0.5, y - 0.5
    x0, y0 = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    tx, ty = (fx - x0)[..., None], (fy - y0)[..., None]
    top = _fetch(img, x0, y0) * (1 - tx) + _fetch(img, x0 + 1, y0) * tx
    bottom = _fetch(img, x0, y0 + 1) * (1 - tx) + _fetch(img, x0 + 1, y0 + 1) * tx
    return top * (1 - ty) + bottom * ty


def _catmull_rom_weights(t):
    t2, t3 = t * t, t * t * t
    return (
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    )


def catmull_rom(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``img`` sampled at ``x``, ``y`` with the 4x4 Catmull-Rom spline (as :func:`bilinear`)."""
    fx, fy = x - 0.5, y - 0.5
    x0, y0 = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    wx = _catmull_rom_weights(fx - x0)
    wy = _catmull_rom_weights(fy - y0)
    out = np.zeros(x.shape + img.shape[2:])
    for j in range(4):
        for i in range(4):
            out += (wx[i] * wy[j])[..., None] * _fetch(img, x0 + i - 1, y0 + j - 1)
    return out
