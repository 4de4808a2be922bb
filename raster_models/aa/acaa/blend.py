"""ACAA's colour target: fragments blended additively, one blend at a time per pixel, in
float32 or in RGBA8 (8-bit UNORM, rounded at every blend)."""

from __future__ import annotations

import numpy as np

__all__ = ["blend", "rgba8_accumulate"]


def rgba8_accumulate(values: np.ndarray, slot: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Blend ``values`` (F, 3) additively into ``target`` (P, 3) at ``slot`` (F,) pixels, one
    blend at a time per pixel (fragments of one pixel in order), rounding the saturated sum
    to 8-bit UNORM after each addition. Returns the target (float64, multiples of 1/255)."""
    return blend(values, slot, target, rgba8=True)


def blend(values, pixel, target, *, rgba8: bool, grouped: bool = False) -> np.ndarray:
    """Additive blend of ``values`` ``(F, 3)`` into ``target`` at pixels ``pixel`` ``(F,)``,
    one blend at a time per pixel, the values of a pixel in their given order.

    ``target`` is a ``(P, 3)`` array or a pixel count ``P`` (a zero target). In float32, or
    with ``rgba8`` in float64 rounding the saturated sum to 8-bit UNORM after each addition
    (:func:`rgba8_accumulate`); ``grouped``: each pixel's values are already contiguous.
    The pixels' runs are blended side by side, one round per blend of the busiest pixel.
    """
    values = np.asarray(values, np.float64 if rgba8 else np.float32)
    dtype = np.float64 if rgba8 else np.float32
    zero = isinstance(target, (int, np.integer))
    out = np.zeros((target, 3), dtype) if zero else np.array(target, dtype=dtype)
    pixel = np.asarray(pixel, np.int64)
    if len(pixel) == 0:
        return out
    if not grouped and np.any(pixel[1:] < pixel[:-1]):
        order = np.argsort(pixel, kind="stable")
        values, pixel = values[order], pixel[order]
    # one run a pixel: blend j adds each pixel's j-th value (its rank within its run); the
    # running sums are kept per run and written to the target once
    start = np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])
    run = np.diff(np.r_[start, len(pixel)])
    values = np.ascontiguousarray(values)
    acc = None
    for j in range(int(run.max())):  # one round per blend of the busiest pixel
        sel = np.flatnonzero(run > j) if j else slice(None)
        if acc is None:  # first blend: onto zeros (+0: the same addition) or the target
            s = (dtype(0.0) if zero else _take_rows(out, pixel[start])) + _take_rows(values, start)
        else:
            s = acc[sel] + _take_rows(values, start[sel] + j)
        if rgba8:
            s = np.floor(np.clip(s, 0.0, 1.0) * 255.0 + 0.5) / 255.0
        if acc is None:
            acc = s
        else:
            acc[sel] = s
    _rows(out)[pixel[start]] = _rows(np.ascontiguousarray(acc))
    return out


def _rows(a: np.ndarray) -> np.ndarray:
    """A C-contiguous ``(N, K)`` array as ``N`` opaque rows (fast row gathers/scatters)."""
    return a.view(np.dtype((np.void, a.itemsize * a.shape[1]))).reshape(len(a))


def _take_rows(a: np.ndarray, rows) -> np.ndarray:
    """``a[rows]`` for a C-contiguous ``(N, K)`` array (the same bytes, row by row)."""
    return _rows(a)[rows].view(a.dtype).reshape(-1, a.shape[1])
