"""Temporal anti-aliasing over a frame sequence, each frame against its own truth:
convergence, ghosting, history error, lag and flicker relative to the truth's.

Sequences are float arrays ``(T, H, W)`` or ``(T, H, W, C)`` of linear values, frame 0 first;
motion ``(T, H, W, 2)`` in pixels from each pixel centre to the surface point's position in
the previous frame's image (the reference's ``motion`` group, docs/conventions.md) and
disocclusion ``(T, H, W)`` (1: the point was not seen by the previous frame).

References
----------
L. Yang, S. Liu, M. Salvi, A Survey of Temporal Antialiasing Techniques, CGF 39(2) 2020,
doi:10.1111/cgf.14018 (ghosting, lag and temporal stability as the failure modes of TAA).
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError, check_images

__all__ = [
    "CONVERGENCE_TOLERANCE",
    "FLICKER_FLOOR",
    "convergence",
    "disocclusion_age",
    "flicker_map",
    "flicker_ratio",
    "frame_errors",
    "ghosting",
    "history_error",
    "warp_previous",
]

#: "Within 10% of the steady level" (the issue's definition of convergence and of lag).
CONVERGENCE_TOLERANCE = 0.1
#: Smallest frame-to-frame change of the truth a flicker ratio divides by (channel units): a
#: still truth (identical frames) would otherwise make any change an infinite ratio.
FLICKER_FLOOR = 1e-3


def _abs_error(reference_frames, candidate_frames):
    ref, cand = check_images(
        "reference_frames", reference_frames, "candidate_frames", candidate_frames, ndim=(3, 4)
    )
    err = np.abs(cand - ref)
    return ref, cand, err if err.ndim == 3 else err.mean(axis=-1)


def frame_errors(reference_frames, candidate_frames) -> np.ndarray:
    """``(T,)`` mean absolute error of each frame against its own truth."""
    _, _, err = _abs_error(reference_frames, candidate_frames)
    return err.reshape(len(err), -1).mean(axis=1)


def convergence(
    errors, *, judged: int | None = None, tolerance=CONVERGENCE_TOLERANCE, window: int = 1
) -> dict:
    """Steady level and convergence of a per-frame error curve.

    ``steady_error`` is the mean of the last ``judged`` frames (all when None);
    ``convergence_frames`` is the first frame ``k`` from which every error stays within
    ``tolerance`` (relative) above the steady level: the frames a technique needs to get
    there (0: from the first frame). One-sided: a frame better than the steady level is not
    "not yet converged". With ``window`` > 1 each frame's error is first averaged with the
    ``window - 1`` frames before it (fewer at the start): an accumulating TAA's error
    oscillates with the phase of its jitter sequence (on ``star`` by +-25% over 16 frames),
    and the window of one sequence length averages the oscillation out.
    """
    e = np.asarray(errors, dtype=np.float64).ravel()
    if e.size == 0:
        raise MetricError("errors must not be empty")
    n = e.size if judged is None else int(judged)
    if not 1 <= n <= e.size:
        raise MetricError(f"judged must be in [1, {e.size}], got {judged}")
    steady = float(e[-n:].mean())
    c = np.cumsum(np.concatenate([[0.0], e]))
    lo = np.maximum(np.arange(e.size) + 1 - int(window), 0)
    smooth = (c[1:] - c[lo]) / (np.arange(e.size) + 1 - lo)
    ok = smooth <= (1.0 + tolerance) * steady + 1e-12
    bad = np.flatnonzero(~ok)
    return {"steady_error": steady, "convergence_frames": int(bad[-1] + 1) if bad.size else 0}


def warp_previous(image: np.ndarray, motion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The previous frame's ``image`` fetched where ``motion`` (``(H, W, 2)``) points (the
    nearest pixel), and the ``(H, W)`` mask of pixels whose position is inside the image."""
    h, w = motion.shape[:2]
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    px, py = x + motion[..., 0], y + motion[..., 1]
    inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
    ix = np.clip(np.floor(px).astype(np.int64), 0, w - 1)
    iy = np.clip(np.floor(py).astype(np.int64), 0, h - 1)
    return image[iy, ix], inside


def disocclusion_age(motion, disocclusion) -> np.ndarray:
    """``(T, H, W)`` int: frames since each pixel's surface point was last disoccluded (0:
    in this frame; frame 0 is 0 everywhere, the start of the sequence), following the point
    back along ``motion``; a point coming from outside the image counts as disoccluded."""
    motion = np.asarray(motion, dtype=np.float64)
    dis = np.asarray(disocclusion) > 0.5
    if motion.ndim != 4 or motion.shape[-1] != 2 or motion.shape[:3] != dis.shape:
        raise MetricError(
            f"motion must be (T, H, W, 2) and disocclusion (T, H, W), got {motion.shape} "
            f"and {dis.shape}"
        )
    age = np.zeros(dis.shape, dtype=np.int64)
    for k in range(1, len(dis)):
        before, inside = warp_previous(age[k - 1], motion[k])
        age[k] = np.where(dis[k] | ~inside, 0, before + 1)
    return age


def ghosting(reference_frames, candidate_frames, age, *, window: int = 4) -> dict:
    """Error where history cannot be trusted: on pixels disoccluded within the last
    ``window`` frames (``1 <= age + 1 <= window``, frames 1.. only: frame 0 has no history at
    all), and the error as a function of the age for lag.

    Returns ``ghosting_error`` (mean absolute error on those pixels, None without any),
    ``settled_error`` (on pixels older than the window), ``error_by_age`` (list, age 0 ..
    window - 1; None where no pixel has that age) and ``lag_frames``: the first age whose
    error is within :data:`CONVERGENCE_TOLERANCE` of the settled error (``window`` when none
    is; None without disoccluded pixels).
    """
    _, _, err = _abs_error(reference_frames, candidate_frames)
    age = np.asarray(age)
    if age.shape != err.shape:
        raise MetricError(f"age must be {err.shape}, got {age.shape}")
    err, age = err[1:], age[1:]
    young = age < window
    settled = float(err[~young].mean()) if np.any(~young) else None
    by_age = [float(err[age == a].mean()) if np.any(age == a) else None for a in range(window)]
    lag = None
    if np.any(young) and settled is not None:
        lag = window
        for a, e in enumerate(by_age):
            if e is not None and e <= (1 + CONVERGENCE_TOLERANCE) * settled:
                lag = a
                break
    return {
        "ghosting_error": float(err[young].mean()) if np.any(young) else None,
        "settled_error": settled,
        "error_by_age": by_age,
        "lag_frames": lag,
    }


def history_error(reference_frames, candidate_frames, motion, *, relative: float = 0.1):
    """Mean absolute error where the truth changed along its motion since the previous frame
    (``|r[k] - r[k-1](p + m)|`` above ``relative`` of their larger value, plus 1e-3): what
    a history that lags behind the truth gets wrong; None where nothing changed."""
    ref, _, err = _abs_error(reference_frames, candidate_frames)
    motion = np.asarray(motion, dtype=np.float64)
    total, count = 0.0, 0
    for k in range(1, len(ref)):
        before, inside = warp_previous(ref[k - 1], motion[k])
        change = np.abs(ref[k] - before)
        big = change > relative * np.maximum(np.abs(ref[k]), np.abs(before)) + 1e-3
        if big.ndim == 3:
            big = big.any(axis=-1)
        sel = big & inside
        total += float(err[k][sel].sum())
        count += int(sel.sum())
    return total / count if count else None


def _changes(frames: np.ndarray) -> np.ndarray:
    d = np.abs(np.diff(frames, axis=0))
    return d if d.ndim == 3 else d.mean(axis=-1)


def flicker_ratio(reference_frames, candidate_frames) -> float:
    """Mean frame-to-frame change of the candidate over the truth's (floored at
    :data:`FLICKER_FLOOR`): 1 is as steady as the truth, above 1 it flickers more."""
    ref, cand, _ = _abs_error(reference_frames, candidate_frames)
    if len(ref) < 2:
        raise MetricError(f"sequences must have at least 2 frames, got shape {ref.shape}")
    return float(_changes(cand).mean() / max(float(_changes(ref).mean()), FLICKER_FLOOR))


def flicker_map(reference_frames, candidate_frames) -> np.ndarray:
    """``(H, W)`` float32: each pixel's change in excess of the truth's,
    ``mean_t max(0, |c[t+1] - c[t]| - |r[t+1] - r[t]|)`` (channels averaged)."""
    ref, cand, _ = _abs_error(reference_frames, candidate_frames)
    if len(ref) < 2:
        raise MetricError(f"sequences must have at least 2 frames, got shape {ref.shape}")
    excess = np.maximum(_changes(cand) - _changes(ref), 0.0)
    return excess.mean(axis=0).astype(np.float32)
