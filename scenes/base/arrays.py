"""The one array check at every boundary: numeric, dimensions, non-empty, finite, sign, bound.

:func:`check_array` is what the metrics (``metrics.validate``) and the display transform
(:mod:`scenes.base.display`) run on every array they take, each raising its own error class;
:func:`nonfinite_counts` is the finiteness part alone, for callers that phrase their own
message (a candidate image's channel). Pure: imports nothing of the project, never Mitsuba.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["check_array", "describe_ndim", "nonfinite_counts"]


def describe_ndim(ndim: Sequence[int]) -> str:
    """``(2, 3)`` -> ``"2-D or 3-D"``."""
    names = [f"{n}-D" for n in sorted(ndim)]
    return names[0] if len(names) == 1 else " or ".join([", ".join(names[:-1]), names[-1]])


def nonfinite_counts(arr: np.ndarray) -> tuple[int, int] | None:
    """``(n_nan, n_inf)`` of a numeric array, or None when every value is finite."""
    finite = np.isfinite(arr)
    if finite.all():
        return None
    n_nan = int(np.isnan(arr).sum())
    return n_nan, int(arr.size - finite.sum() - n_nan)


def check_array(
    name: str,
    a,
    *,
    error: type[Exception] = ValueError,
    ndim: Sequence[int] = (2, 3),
    allow_negative: bool = True,
    max_value: float | None = None,
    dtype=np.float64,
) -> np.ndarray:
    """``a`` as a ``dtype`` array (no copy when it already is); ``error`` naming ``name`` when
    it is not real numeric, has a number of dimensions outside ``ndim``, is empty, holds NaN
    or inf (both counted), has negative values (``allow_negative=False``) or values above
    ``max_value``."""
    arr = np.asarray(a)
    if arr.dtype.kind not in "biuf":
        raise error(f"{name} must be a real numeric array, got dtype {arr.dtype}")
    if arr.ndim not in tuple(ndim):
        raise error(f"{name} must be a {describe_ndim(ndim)} array, got shape {tuple(arr.shape)}")
    if arr.size == 0:
        raise error(f"{name} must not be empty, got shape {tuple(arr.shape)}")
    arr = arr.astype(dtype, copy=False)
    counts = nonfinite_counts(arr)
    if counts is not None:
        raise error(
            f"{name} must be finite, got {counts[0]} NaN and {counts[1]} inf values "
            f"(of {arr.size}, shape {tuple(arr.shape)})"
        )
    if not allow_negative:
        n_neg = int((arr < 0).sum())
        if n_neg:
            raise error(
                f"{name} must be non-negative, got {n_neg} negative values "
                f"(minimum {float(arr.min()):.6g})"
            )
    if max_value is not None:
        n_big = int((arr > max_value).sum())
        if n_big:
            raise error(
                f"{name} must be at most {max_value:g}, got {n_big} larger values "
                f"(maximum {float(arr.max()):.6g})"
            )
    return arr
