"""Fragments of a multisampled pixel: the samples one primitive owns.

A fragment is a (primitive, pixel) pair with at least one visible sample. The prepass groups
the samples on the Dr.Jit side (:func:`.pixel_dr.first_of_key`: for each sample the first
sample of its pixel with the same ``(shape, primitive)`` key, its fragment's representative;
:func:`.pixel_dr.fragments_of`); :func:`fragments_from_prepass` takes its bookkeeping, and
the functions here give each fragment's film positions.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Fragments", "fragments_from_prepass", "sample_film_positions", "shading_positions"]


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
