"""Motion vectors: conventions and the end-point error of an engine's velocity buffer.

The oracle's convention (the reference's ``motion`` group): pixels, the previous frame's film
position minus this pixel's centre, x right, y down. :data:`CONVENTIONS` and the table in
docs/conventions.md give the others.
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError

__all__ = [
    "CONVENTIONS",
    "EPE_THRESHOLD_PX",
    "from_oracle_motion",
    "motion_errors",
    "to_oracle_motion",
]

#: name -> ``(ax, ay)``: a vector of that convention is ``(ax mx / W, ay my / H)`` for the
#: oracle's ``(mx, my)`` pixels (None: the oracle's own pixels, as DLSS takes them).
CONVENTIONS = {
    "pixels": None,
    "unreal": (-2.0, 2.0),
    "unity": (-1.0, 1.0),
    "uv": (1.0, 1.0),
}
#: End-point error above which a vector counts as wrong (the issue's half pixel).
EPE_THRESHOLD_PX = 0.5


def _check(motion, convention):
    mv = np.asarray(motion, dtype=np.float64)
    if mv.ndim < 1 or mv.shape[-1] != 2:
        raise MetricError(f"motion must be (..., 2), got shape {mv.shape}")
    if convention not in CONVENTIONS:
        raise MetricError(
            f"motion convention must be one of {', '.join(CONVENTIONS)}, got {convention!r}"
        )
    return mv, CONVENTIONS[convention]


def to_oracle_motion(motion, *, convention: str, width: int, height: int) -> np.ndarray:
    """Motion vectors ``(..., 2)`` of ``convention`` as the oracle's pixels (see the module
    docstring): ``unreal`` is current minus previous in NDC (y up), ``unity`` current minus
    previous in UV (v up), ``uv`` previous minus current in UV (v down), ``pixels`` the
    oracle's own."""
    mv, a = _check(motion, convention)
    if a is None:
        return mv.copy()
    return np.stack([mv[..., 0] * width / a[0], mv[..., 1] * height / a[1]], -1)


def from_oracle_motion(motion, *, convention: str, width: int, height: int) -> np.ndarray:
    """The inverse of :func:`to_oracle_motion`."""
    mv, a = _check(motion, convention)
    if a is None:
        return mv.copy()
    return np.stack([mv[..., 0] * a[0] / width, mv[..., 1] * a[1] / height], -1)


def motion_errors(reference, candidate, *, disocclusion, candidate_disocclusion=None) -> dict:
    """End-point error of ``candidate`` motion (``(H, W, 2)``, oracle convention) against
    the reference's on the pixels the reference does not mark disoccluded, and the
    candidate's disocclusion mask against the reference's.

    Returns ``motion_epe_mean``, ``motion_epe_p99``, ``motion_epe_over_half`` (fraction above
    :data:`EPE_THRESHOLD_PX`), ``disocclusion_recall``, ``disocclusion_precision`` (None
    without a candidate mask, or with nothing to recall / nothing marked), and ``epe`` the
    ``(H, W)`` float32 map (0 on disoccluded pixels).
    """
    ref = np.asarray(reference, dtype=np.float64)
    cand = np.asarray(candidate, dtype=np.float64)
    if ref.shape != cand.shape or ref.ndim != 3 or ref.shape[-1] != 2:
        raise MetricError(
            f"reference and candidate motion must be the same (H, W, 2), got {ref.shape} "
            f"and {cand.shape}"
        )
    if not np.all(np.isfinite(cand)):
        raise MetricError("candidate motion holds NaN or inf")
    dis = np.asarray(disocclusion) > 0.5
    epe = np.hypot(*(cand - ref).transpose(2, 0, 1))
    keep = epe[~dis]
    out = {
        "motion_epe_mean": float(keep.mean()) if keep.size else None,
        "motion_epe_p99": float(np.percentile(keep, 99)) if keep.size else None,
        "motion_epe_over_half": float(np.mean(keep > EPE_THRESHOLD_PX)) if keep.size else None,
        "disocclusion_recall": None,
        "disocclusion_precision": None,
        "epe": np.where(dis, 0.0, epe).astype(np.float32),
    }
    if candidate_disocclusion is not None:
        mine = np.asarray(candidate_disocclusion) > 0.5
        both = int(np.count_nonzero(mine & dis))
        out["disocclusion_recall"] = both / int(dis.sum()) if dis.any() else None
        out["disocclusion_precision"] = both / int(mine.sum()) if mine.any() else None
    return out
