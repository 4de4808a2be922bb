"""Adaptive sampling: which pixels the next pass refines, and the record of what it achieved.

After a first pass over every pixel, a pixel near a feature (:func:`feature_mask`) refines
while a group's standard error of it exceeds the target (visibility, coverage and front
coverage: the Jeffreys binomial one, :func:`binary_stderr`; the soft channels: their sample
one), and wherever it is while its colour's sample standard error does; the groups say which
(:class:`oracle.reference.group.SampledGroup`). The passes themselves are the loop's
(:mod:`oracle.reference.render`).
"""

from __future__ import annotations

import math

import numpy as np

from ...metrics.stats import binomial_stderr_floor
from .group import Accumulators, binary_stderr

__all__ = ["adaptive_stats", "binary_stderr", "feature_mask", "refine_mask"]


def _dilate(mask: np.ndarray) -> np.ndarray:
    """3x3 dilation of a boolean ``(H, W)`` image (vectorised: nine shifted ORs)."""
    out = mask.copy()
    out[1:, :] |= mask[:-1, :]
    out[:-1, :] |= mask[1:, :]
    rows = out.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


def _differs_from_neighbour(values: np.ndarray) -> np.ndarray:
    """True where a pixel's value differs from one of its 8 neighbours' (``(H, W, ...)``)."""
    out = np.zeros(values.shape[:2], dtype=bool)
    h, w = out.shape
    for dy, dx in ((0, 1), (1, -1), (1, 0), (1, 1)):
        ys, yd = slice(0, h - dy), slice(dy, h)
        xs = slice(max(0, -dx), w - max(0, dx))
        xd = slice(max(0, dx), w + min(0, dx))
        diff = values[ys, xs] != values[yd, xd]
        if diff.ndim == 3:
            diff = diff.any(axis=2)
        out[ys, xs] |= diff
        out[yd, xd] |= diff
    return out


def feature_mask(acc: Accumulators, width: int, height: int) -> np.ndarray:
    """Pixels near a feature: the 3x3 dilation of the pixels that show an edge.

    A pixel shows an edge when its own samples disagree (hit shape id, visibility or
    coverage differ between them), or when what its samples agree on differs from a
    neighbour's (another shape id, visibility or coverage: the two pixels lie on either side
    of an edge, or a thin feature that one of them caught). A pixel whose samples all missed a
    thin feature that crosses a neighbour is thereby flagged by that neighbour, which its own
    standard error (zero sample variance) cannot do.
    """
    shape = (height, width)
    own = np.zeros(acc.npix, dtype=bool)
    # what the pixel's samples agree on: shape range, whether any sample was lit/covered and,
    # in a penumbra, whether its soft values are all 0 or all 1
    parts = []
    for g in acc.groups.values():
        mine, agree = g.feature(acc.n)
        if mine is not None:
            own |= mine
        parts += agree
    state = np.stack(parts, axis=1).reshape(*shape, len(parts))
    edge = own.reshape(shape) | _differs_from_neighbour(state)
    return _dilate(edge).ravel()


def _largest(arrays) -> np.ndarray:
    """Element-wise largest of the groups' per-pixel arrays (None: no opinion)."""
    arrays = [a for a in arrays if a is not None]
    out = arrays[0]
    for a in arrays[1:]:
        out = np.maximum(out, a)
    return out


def refine_mask(acc: Accumulators, settings, width: int, height: int) -> np.ndarray:
    """Pixels of the next adaptive pass.

    A pixel near a feature (:func:`feature_mask`: an edge, id change or visibility change in
    it or a neighbour) refines while a group's standard error of it (binary for visibility
    and coverage, :func:`binary_stderr`) exceeds the target; a pixel far from every feature
    stops after the first pass, however few samples agree in it (its neighbours' agreeing
    samples are the evidence). Stopped pixels rejoin when a neighbour later shows a feature,
    so refinement follows thin features from the pixels that caught them. With colour, a
    pixel also refines while the sample standard error of its colour exceeds the target.
    """
    groups = acc.groups.values()
    se = _largest([g.refine_stderr(acc.n) for g in groups])
    want = feature_mask(acc, width, height) & (se > settings.target_stderr)
    for g in groups:
        anywhere = g.refine_anywhere(acc.n, settings.target_stderr)
        if anywhere is not None:
            want |= anywhere
    return want & (acc.n < settings.max_spp)


def adaptive_stats(settings, acc: Accumulators, width: int, height: int) -> dict:
    """The adaptive record: samples spent, standard errors achieved and the uniform spp
    that would meet the same maximum standard error on the pixels near features.

    Pixels far from every feature stop after the first pass and keep their binomial floor
    (``achieved_max_stderr`` includes it, ``achieved_max_stderr_near_features`` does not);
    the uniform comparison is over the near pixels, where the target applies (this is the
    stderr comparison; `bench oracle` measures the true error).
    """
    npix = width * height
    se = _largest([g.stderr(acc.n) for g in acc.groups.values()])
    near = feature_mask(acc, width, height)
    near_se = float(se[near].max()) if near.any() else 0.0
    n2 = np.maximum(acc.n, 2)
    parts = [v for g in acc.groups.values() for v in g.variance(n2)]
    var = np.maximum(np.max(parts, axis=0), 0.0)
    target = max(near_se, settings.target_stderr)
    floor_spp = 1
    while binomial_stderr_floor(floor_spp) > target:
        floor_spp *= 2
    uniform_spp = max(
        settings.adaptive_spp, floor_spp, int(math.ceil(float(var.max()) / target**2))
    )
    adaptive_samples = int(acc.n.sum())
    return {
        "target_stderr": settings.target_stderr,
        "achieved_max_stderr": float(se.max()),
        "achieved_max_stderr_near_features": near_se,
        "samples": adaptive_samples,
        "mean_spp": adaptive_samples / npix,
        "max_spp_used": int(acc.n.max()),
        "uniform_spp_for_same_max_stderr": uniform_spp,
        "uniform_samples": int(uniform_spp * npix),
        "rays_ratio_vs_uniform": adaptive_samples / float(uniform_spp * npix),
        "pixels_refined": int((acc.n > settings.adaptive_spp).sum()),
        "pixels_near_features": int(near.sum()),
    }
