"""Temporal shadow denoisers against an unbiased truth with standard errors: lag after an
event and over-blur of penumbrae (ghosting by disocclusion age and added flicker are
:func:`metrics.ghosting.ghosting` and :func:`metrics.temporal.added_flicker`).

Sequences are ``(T, H, W)`` float arrays of shadow factor in [0, 1] (1 lit), frame 0 first;
``stderr`` the truth's per-pixel standard error, ``mask`` the receivers ``(T, H, W)`` or
``(H, W)``.

References
----------
C. Schied, C. Peters, C. Dachsbacher, Gradient Estimation for Real-Time Adaptive Temporal
Filtering, HPG 2018, doi:10.1145/3233301 (temporal lag after a change as a denoiser's
failure mode).
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError

__all__ = ["CI_Z", "event_lag", "frame_error_with_floor", "penumbra_width"]

#: Two-sided 95 % normal quantile: the truth's confidence interval is ``+- CI_Z stderr``.
CI_Z = 1.96


def _seq(name, a, ndim=3) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != ndim:
        raise MetricError(f"{name} must be {ndim}-D, got shape {a.shape}")
    return a


def frame_error_with_floor(truth, candidate, stderr, mask) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the mean absolute error of ``candidate`` on the receivers and the truth's
    noise floor there, the mean ``CI_Z * stderr`` over receivers whose truth is neither 0 nor
    1 (an error below it is within the truth's own 95 % confidence interval on average).
    Where every sample agreed (truth exactly 0 or 1) the reference reports a binomial bound,
    not an estimate, and the sample variance is 0: those pixels add 0. Two ``(T,)`` arrays."""
    t, c, s = _seq("truth", truth), _seq("candidate", candidate), _seq("stderr", stderr)
    if not t.shape == c.shape == s.shape:
        raise MetricError(
            f"truth, candidate and stderr must match, got {t.shape}, {c.shape}, {s.shape}"
        )
    m = np.broadcast_to(np.asarray(mask, dtype=bool), t.shape)
    n = np.maximum(m.sum(axis=(1, 2)), 1)
    err = np.where(m, np.abs(c - t), 0.0).sum(axis=(1, 2)) / n
    mixed = m & (t > 0.0) & (t < 1.0)
    floor = np.where(mixed, CI_Z * s, 0.0).sum(axis=(1, 2)) / n
    return err, floor


def event_lag(
    errors, floors, *, event: int, baseline: int = 4, steady: float | None = None
) -> int | None:
    """Frames after the event at frame ``event`` until the error is back: the first ``k >= 0``
    with ``errors[event + k] <= steady + floors[event + k]``, ``steady`` the mean error of the
    ``baseline`` frames before the event (the denoiser's own steady state: a denoiser is
    biased, its error never reaches the truth's floor) unless ``steady`` gives it (a light
    coming back on is judged against the lit steady state). 0: no lag; None: not back within
    the sequence.

    Raises
    ------
    MetricError
        Fewer than ``baseline`` frames before the event, or the event past the sequence.
    """
    e, f = np.asarray(errors, dtype=np.float64), np.asarray(floors, dtype=np.float64)
    if e.shape != f.shape or e.ndim != 1:
        raise MetricError(f"errors and floors must be equal 1-D arrays, got {e.shape}, {f.shape}")
    if not baseline <= event < len(e):
        raise MetricError(
            f"event must leave {baseline} baseline frames and lie in the sequence of "
            f"{len(e)} frames, got {event}"
        )
    if steady is None:
        steady = float(e[event - baseline : event].mean())
    back = np.flatnonzero(e[event:] <= steady + f[event:])
    return int(back[0]) if back.size else None


def penumbra_width(image, truth, *, mask, band: int = 3) -> float | None:
    """Mean 10-90 % penumbra width of ``image`` in pixels across the truth's shadow edges.

    The width is the count of pixels whose value lies in (0.1, 0.9), inside ``band`` pixels of
    the truth's penumbra (truth in (0.02, 0.98)), divided by the length of the truth's 0.5
    contour (pixel pairs, horizontal and vertical, whose truth values straddle 0.5): an edge
    of length ``L`` px whose profile rises from 10 % to 90 % over ``w`` px covers ``w L``
    pixels. The same length divides the truth's own count, so ``penumbra_width(c) -
    penumbra_width(t)`` is the over-blur in pixels. Exact for horizontal and vertical edges;
    along an edge at angle ``a`` both read ``1 / (|cos a| + |sin a|)`` of the width across it
    (0.71 at 45 degrees). None without a truth edge.
    """
    img = _seq("image", image, 2)
    t = _seq("truth", truth, 2)
    m = np.asarray(mask, dtype=bool)
    if not img.shape == t.shape == m.shape:
        raise MetricError(
            f"image, truth and mask must match, got {img.shape}, {t.shape}, {m.shape}"
        )
    hi = t > 0.5
    cross_x = (hi[:, 1:] != hi[:, :-1]) & m[:, 1:] & m[:, :-1]
    cross_y = (hi[1:] != hi[:-1]) & m[1:] & m[:-1]
    length = float(cross_x.sum() + cross_y.sum())
    if length == 0:
        return None
    region = (t > 0.02) & (t < 0.98) & m
    for _ in range(band):
        grown = region.copy()
        grown[1:] |= region[:-1]
        grown[:-1] |= region[1:]
        grown[:, 1:] |= region[:, :-1]
        grown[:, :-1] |= region[:, 1:]
        region = grown & m
    inside = (img > 0.1) & (img < 0.9) & region
    return float(inside.sum()) / length
