"""Fragments of a multisampled pixel: the samples one primitive owns, found by grouping.

A fragment is a (primitive, pixel) pair with at least one visible sample. Grouping compares
every sample's ``(shape, primitive)`` key with every other sample's of the same pixel
(``(P, N, N)`` comparisons, vectorized over pixels in chunks), giving for each sample the
first sample of its pixel with the same key: its fragment's representative.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "Fragments",
    "first_of_key",
    "fragments_from_prepass",
    "group_fragments",
    "sample_film_positions",
    "shading_positions",
]

#: Pixels per grouping chunk (keeps the ``(P, N, N)`` comparison cache-sized: 8 MiB at N = 16).
GROUP_CHUNK = 1 << 15


class Fragments:
    """Fragments of ``P`` pixels with ``N`` samples each.

    Attributes
    ----------
    pixel, sample : ``(F,)`` pixel index and representative sample slot of each fragment.
    count : ``(F,)`` samples each fragment owns.
    of_sample : ``(P, N)`` fragment index of every sample (-1: sky).
    """

    def __init__(self, pixel, sample, count, of_sample):
        self.pixel = pixel
        self.sample = sample
        self.count = count
        self.of_sample = of_sample

    def __len__(self) -> int:
        return len(self.pixel)

    def per_pixel(self, n_pix: int) -> np.ndarray:
        """Fragments (shading events) per pixel, ``(P,)`` int."""
        return np.bincount(self.pixel, minlength=n_pix)


def first_of_key(valid: np.ndarray, shape: np.ndarray, prim: np.ndarray) -> np.ndarray:
    """``(P, N)`` first sample of each sample's pixel with the same (shape, primitive)."""
    n_pix, n = valid.shape
    key = np.where(valid, (shape.astype(np.int64) << 40) ^ prim.astype(np.int64), -1)
    first = np.empty((n_pix, n), np.int64)
    for start in range(0, n_pix, GROUP_CHUNK):
        k = key[start : start + GROUP_CHUNK]
        eq = k[:, :, None] == k[:, None, :]
        first[start : start + GROUP_CHUNK] = np.argmax(eq, axis=2)
    return first


def group_fragments(valid: np.ndarray, shape=None, prim=None, *, first=None) -> Fragments:
    """Group the samples of each pixel by primitive; ``valid``/``shape``/``prim`` are (P, N).

    ``first`` (from :func:`._pixel_dr.first_of_key` on the Dr.Jit side) skips the NumPy
    comparison of :func:`first_of_key`.
    """
    n_pix, n = valid.shape
    if first is None:
        first = first_of_key(valid, shape, prim)
    first = np.asarray(first)
    rep = (first == np.arange(n, dtype=first.dtype)[None, :]) & valid
    flat = rep.ravel()
    # fragment ids in pixel-major order; a sample's fragment is its representative's id
    fid = np.cumsum(flat, dtype=np.int64) - 1
    lane = np.where(valid, np.arange(n_pix)[:, None] * n + first, 0)
    of_sample = np.where(valid, fid[lane], -1)
    reps = np.flatnonzero(flat)
    fp, fs = reps // n, reps % n
    count = np.bincount(of_sample.ravel() + 1, minlength=len(reps) + 1)[1:]
    return Fragments(fp, fs, count, of_sample)


def fragments_from_prepass(buf: dict, n: int) -> Fragments:
    """:class:`Fragments` from the Dr.Jit bookkeeping of ``trace_samples(..., group=True)``."""
    reps = np.flatnonzero(buf["rep"].ravel())
    count = buf["count"].ravel()[reps].astype(np.int64)
    return Fragments(reps // n, reps % n, count, buf["of"])


def shading_positions(frags: Fragments, offsets, width: int, centroid: bool, n: int):
    """Film positions where each fragment is shaded: the pixel centre, or with ``centroid``
    the mean of the fragment's sample positions unless it owns all ``n`` samples (then the
    centre: the rule of centroid interpolation)."""
    px = (frags.pixel % width).astype(np.float64)
    py = (frags.pixel // width).astype(np.float64)
    cx, cy = px + 0.5, py + 0.5
    if centroid and len(frags):
        offs = np.asarray(offsets, np.float64)
        of = frags.of_sample
        ok = of >= 0
        slot = np.broadcast_to(np.arange(of.shape[1]), of.shape)[ok]
        sum_x = np.bincount(of[ok], weights=offs[slot, 0], minlength=len(frags))
        sum_y = np.bincount(of[ok], weights=offs[slot, 1], minlength=len(frags))
        partial = frags.count < n
        cx = np.where(partial, px + sum_x / frags.count, cx)
        cy = np.where(partial, py + sum_y / frags.count, cy)
    return cx, cy


def sample_film_positions(frags: Fragments, offsets, width: int):
    """Film position of each fragment's representative sample."""
    offs = np.asarray(offsets, np.float64)
    sx = (frags.pixel % width) + offs[frags.sample, 0]
    sy = (frags.pixel // width) + offs[frags.sample, 1]
    return sx, sy
