"""Boundary checks shared by every metric: shape, emptiness, finiteness, sign, dtype.

Every public metric passes its array inputs through :func:`check_images` (or
:func:`check_image` for a single array) before doing any arithmetic, so that every metric
fails the same way, with a message that names the parameter, what was expected and what
was received.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..scenes.base.arrays import check_array

__all__ = ["MetricError", "check_image", "check_images", "check_mask"]


class MetricError(ValueError):
    """Invalid input to a metric: wrong shape, empty, NaN/inf, negative, bad option."""


def check_image(
    name: str,
    a,
    *,
    ndim: Sequence[int] = (2, 3),
    allow_negative: bool = True,
    max_value: float | None = None,
    dtype=np.float64,
) -> np.ndarray:
    """Validate one array and return it as a floating-point array of ``dtype``.

    Parameters
    ----------
    name : str
        The parameter's name, used in error messages.
    a : array_like
        Real-valued (or boolean) array.
    ndim : sequence of int, keyword-only
        Accepted numbers of dimensions.
    allow_negative : bool, keyword-only
        When False, any value below 0 is an error (radiance, visibility, coverage).
    max_value : float or None, keyword-only
        When given, any value above it is an error (1 for visibility and coverage).
    dtype : numpy dtype, keyword-only
        Floating-point dtype of the returned array.

    Returns
    -------
    numpy.ndarray
        ``a`` converted to ``dtype`` (no copy when it already is).

    Raises
    ------
    MetricError
        When ``a`` is not numeric, has the wrong number of dimensions, is empty, holds NaN
        or inf (the counts are given), or breaks the sign/upper-bound requirements.
    """
    return check_array(
        name,
        a,
        error=MetricError,
        ndim=ndim,
        allow_negative=allow_negative,
        max_value=max_value,
        dtype=dtype,
    )


def check_images(
    name_a: str,
    a,
    name_b: str,
    b,
    *,
    ndim: Sequence[int] = (2, 3),
    allow_negative: bool = True,
    max_value: float | None = None,
    dtype=np.float64,
) -> tuple[np.ndarray, np.ndarray]:
    """Validate two arrays that are compared pixel by pixel; see :func:`check_image`.

    Both arrays get the checks of :func:`check_image`, and they must have the same shape.

    Returns
    -------
    tuple of numpy.ndarray
        ``(a, b)`` converted to ``dtype``.

    Raises
    ------
    MetricError
        As :func:`check_image`, or when the shapes differ:
        ``reference and candidate must have the same shape, got (64, 96) and (64, 95)``.
    """
    shape_a, shape_b = np.shape(a), np.shape(b)
    if shape_a != shape_b:
        raise MetricError(
            f"{name_a} and {name_b} must have the same shape, "
            f"got {tuple(shape_a)} and {tuple(shape_b)}"
        )
    kw = {"ndim": ndim, "allow_negative": allow_negative, "max_value": max_value, "dtype": dtype}
    return check_image(name_a, a, **kw), check_image(name_b, b, **kw)


def check_mask(name: str, mask, shape: tuple[int, ...]) -> np.ndarray:
    """Validate a boolean pixel mask of the given ``(H, W)`` shape and return it.

    Raises
    ------
    MetricError
        When ``mask`` is not boolean or its shape is not ``shape``.
    """
    m = np.asarray(mask)
    if m.dtype != np.bool_:
        raise MetricError(f"{name} must be a boolean array, got dtype {m.dtype}")
    if m.shape != tuple(shape):
        raise MetricError(f"{name} must have shape {tuple(shape)}, got {tuple(m.shape)}")
    return m
