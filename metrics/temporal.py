"""Temporal stability along a camera path: flicker and temporal error.

Sequences are float arrays ``(T, H, W)`` or ``(T, H, W, C)`` of linear values (radiance,
visibility or coverage), frame 0 first, row 0 at the top, ``T >= 2``.
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError, check_images, check_mask

__all__ = ["added_flicker", "flicker", "temporal_error"]


def _sequences(reference_frames, candidate_frames, mask):
    ref, cand = check_images(
        "reference_frames", reference_frames, "candidate_frames", candidate_frames, ndim=(3, 4)
    )
    if ref.shape[0] < 2:
        raise MetricError(f"sequences must have at least 2 frames, got shape {ref.shape}")
    sel = None if mask is None else check_mask("mask", mask, ref.shape[1:3])
    return ref, cand, sel


def _mean_abs_change(frames: np.ndarray, sel: np.ndarray | None) -> float:
    change = np.abs(np.diff(frames, axis=0))
    if sel is not None:
        change = change[:, sel]
    return float(change.mean()) if change.size else 0.0


def flicker(reference_frames, candidate_frames, *, mask=None) -> float:
    """Frame-to-frame change of the candidate in excess of the reference's.

    ``mean |c[t+1] - c[t]| - mean |r[t+1] - r[t]|`` over frames, pixels and channels. The
    reference's own change (camera motion, moving shadows) is subtracted, so what is left
    is the flicker a technique adds (crawling edges, shimmering shadow-map texels).

    Parameters
    ----------
    reference_frames, candidate_frames : array_like
        ``(T, H, W)`` or ``(T, H, W, C)``, same shape, ``T >= 2``, linear values.
    mask : array_like of bool or None, keyword-only
        ``(H, W)`` pixels to score in every frame; default all.

    Returns
    -------
    float
        Added flicker in the images' units per frame; 0 for identical sequences, negative
        when the candidate changes less than the reference (e.g. temporal smoothing). An
        empty mask gives 0.0.

    References
    ----------
    .. [1] L. Yang, S. Liu, M. Salvi, "A Survey of Temporal Antialiasing Techniques",
       Computer Graphics Forum 39(2), 2020. DOI: 10.1111/cgf.14018
    """
    ref, cand, sel = _sequences(reference_frames, candidate_frames, mask)
    return _mean_abs_change(cand, sel) - _mean_abs_change(ref, sel)


def temporal_error(reference_frames, candidate_frames, *, mask=None) -> float:
    """Mean change of the error between consecutive frames.

    ``mean |e[t+1] - e[t]|`` with ``e = candidate - reference``: 0 when the error is
    constant in time (a static bias is not temporal instability), large when it changes
    from frame to frame.

    Parameters
    ----------
    reference_frames, candidate_frames : array_like
        ``(T, H, W)`` or ``(T, H, W, C)``, same shape, ``T >= 2``, linear values.
    mask : array_like of bool or None, keyword-only
        ``(H, W)`` pixels to score in every frame; default all.

    Returns
    -------
    float
        Non-negative, in the images' units per frame; 0.0 for an empty mask.

    References
    ----------
    .. [1] L. Yang, S. Liu, M. Salvi, "A Survey of Temporal Antialiasing Techniques",
       Computer Graphics Forum 39(2), 2020. DOI: 10.1111/cgf.14018
    """
    ref, cand, sel = _sequences(reference_frames, candidate_frames, mask)
    return _mean_abs_change(cand - ref, sel)


def added_flicker(reference_frames, candidate_frames) -> float:
    """Flicker the candidate adds, non-negative: ``mean(max(0, |c[t+1] - c[t]| -
    |r[t+1] - r[t]|))`` over frame pairs, pixels and channels.

    :func:`flicker` subtracts the two means, so a candidate that is steadier than the
    reference in one region cancels flicker elsewhere and the value can be negative. Here the
    reference's own change is subtracted per pixel and only the excess counts: 0 when the
    candidate never changes more than the reference, and a smoothed-away change is not
    credited against a crawling edge.
    """
    ref = np.asarray(reference_frames, dtype=np.float64)
    cand = np.asarray(candidate_frames, dtype=np.float64)
    if ref.shape != cand.shape or ref.shape[0] < 2:
        raise MetricError(f"flicker needs two equal sequences of >= 2 frames, got {ref.shape}")
    excess = np.abs(np.diff(cand, axis=0)) - np.abs(np.diff(ref, axis=0))
    return float(np.maximum(excess, 0.0).mean())
