"""Sub-pixel displacement of edges between two images, and gains between them.

:func:`subpixel_shift` estimates the translation ``(dx, dy)`` (pixels, x right, y down) that
best maps ``reference`` onto ``candidate`` near edges: Lucas-Kanade on the whole image
(Lucas and Kanade 1981), ``c(x) ~ r(x - d)``, linearised as ``c - r = -grad(r) . d``, solved by
least squares over the pixels with a gradient, and iterated with the reference resampled at
the running estimate (bilinear), so shifts of more than a pixel converge too. A shadow edge
moved by one shadow-map texel shows as a shift of the texel's footprint on screen.

:func:`best_gain` is the least-squares gain ``g`` that minimises ``|c - g r|`` (per label
with :func:`label_gains`): a units or shading-model gap scales radiance, a visibility or
geometry error does not.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["apply_shift", "best_gain", "label_gains", "subpixel_shift"]

#: Pixels of gradient below this (relative to the image's largest) carry no edge.
_GRADIENT_FLOOR = 0.05


def _grey(image) -> np.ndarray:
    a = np.asarray(image, dtype=np.float64)
    return a.mean(axis=-1) if a.ndim == 3 else a


def apply_shift(image, dx: float, dy: float) -> np.ndarray:
    """``image`` moved by ``(dx, dy)`` pixels (bilinear, the border repeated): ``out(x) =
    image(x - d)``."""
    a = np.asarray(image, dtype=np.float64)
    shift = (dy, dx) + (0,) * (a.ndim - 2)
    return ndimage.shift(a, shift, order=1, mode="nearest")


def subpixel_shift(
    reference, candidate, *, mask=None, iterations: int = 12, smooth: float = 1.0
) -> dict:
    """The translation ``d = (dx, dy)`` with ``candidate(x) ~ reference(x - d)``.

    Parameters
    ----------
    reference, candidate : ``(H, W)`` or ``(H, W, C)`` (averaged over channels).
    mask : ``(H, W)`` bool: the pixels that count (None: all).
    smooth : both images are blurred with a Gaussian of this many pixels first, so hard
        (aliased, binary) edges have the smooth profile the linearisation needs.

    Returns ``{"dx", "dy", "magnitude", "pixels"}`` (``pixels``: the edge pixels the estimate
    rests on; 0 and a zero shift when the reference has no edge).
    """
    r = _grey(reference)
    c = _grey(candidate)
    if smooth > 0:
        r = ndimage.gaussian_filter(r, smooth, mode="nearest")
        c = ndimage.gaussian_filter(c, smooth, mode="nearest")
    keep = np.ones(r.shape, bool) if mask is None else np.asarray(mask, bool)
    d = np.zeros(2)
    n = 0
    for _ in range(iterations):
        moved = apply_shift(r, d[0], d[1])
        gy, gx = np.gradient(moved)
        mag = np.hypot(gx, gy)
        edge = keep & (mag > _GRADIENT_FLOOR * max(float(mag.max()), 1e-12))
        n = int(edge.sum())
        if n < 2:
            return {"dx": 0.0, "dy": 0.0, "magnitude": 0.0, "pixels": n}
        a = np.stack([-gx[edge], -gy[edge]], -1)
        b = (c - moved)[edge]
        step, *_ = np.linalg.lstsq(a, b, rcond=None)
        step = np.clip(step, -1.0, 1.0)  # the linearisation holds within a pixel
        d += step
        if np.hypot(*step) < 1e-3:
            break
    return {"dx": float(d[0]), "dy": float(d[1]), "magnitude": float(np.hypot(*d)), "pixels": n}


def best_gain(reference, candidate, *, mask=None) -> float | None:
    """The least-squares gain ``g = sum(r c) / sum(r r)`` with ``candidate ~ g reference``
    over ``mask`` (None where the reference is black there)."""
    r = np.asarray(reference, dtype=np.float64)
    c = np.asarray(candidate, dtype=np.float64)
    if mask is not None:
        r, c = r[np.asarray(mask, bool)], c[np.asarray(mask, bool)]
    rr = float(np.sum(r * r))
    return float(np.sum(r * c) / rr) if rr > 0 else None


def label_gains(reference, candidate, labels) -> dict[int, float | None]:
    """:func:`best_gain` per label (``labels`` ``(H, W)`` int, -1 skipped)."""
    labels = np.asarray(labels)
    return {
        int(k): best_gain(reference, candidate, mask=labels == k)
        for k in np.unique(labels)
        if k >= 0
    }
