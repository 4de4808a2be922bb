"""Shadow (visibility) error on receiver pixels, overall and in a band around shadow edges.

Visibility is float in [0, 1], 1 = lit, ``(H, W)``, row 0 at the top. Only receivers are
scored: valid (non-sky) pixels whose surface faces the light (N.L > 0); elsewhere the
visibility of either image has no effect on any value.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .validate import MetricError, check_images, check_mask

__all__ = ["SHADOW_KEYS", "shadow_edges", "shadow_metrics"]

#: Scalar keys of :func:`shadow_metrics`'s result, in report order.
SHADOW_KEYS = (
    "visibility_mae",
    "visibility_rmse",
    "misclassified_fraction",
    "false_lit_fraction",
    "false_shadow_fraction",
    "edge_band_mae",
    "edge_band_misclassified_fraction",
    "receiver_count",
    "edge_band_count",
)


def _fraction(count: int, total: int) -> float:
    return count / total if total else 0.0


def shadow_edges(lit, receivers) -> np.ndarray:
    """Receiver pixels on a shadow boundary of a binary lit/shadowed classification.

    A receiver pixel is an edge pixel when one of its 4-neighbours is also a receiver and
    has the other class. Both sides of a boundary are marked; boundaries between receivers
    and non-receivers (silhouettes, sky, back faces) are not shadow edges.

    Parameters
    ----------
    lit : array_like of bool
        ``(H, W)`` True where lit.
    receivers : array_like of bool
        ``(H, W)`` True on receiver pixels.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` bool edge mask.
    """
    lit = check_mask("lit", lit, np.shape(lit))
    if lit.ndim != 2:
        raise MetricError(f"lit must be a 2-D array, got shape {lit.shape}")
    rec = check_mask("receivers", receivers, lit.shape)
    edges = np.zeros_like(lit)
    # Horizontal and vertical neighbour pairs that are both receivers and differ in class.
    dx = (lit[:, 1:] != lit[:, :-1]) & rec[:, 1:] & rec[:, :-1]
    dy = (lit[1:, :] != lit[:-1, :]) & rec[1:, :] & rec[:-1, :]
    edges[:, 1:] |= dx
    edges[:, :-1] |= dx
    edges[1:, :] |= dy
    edges[:-1, :] |= dy
    return edges


def shadow_metrics(
    reference,
    candidate,
    *,
    receivers,
    edge_band: int = 2,
    threshold: float = 0.5,
    full: bool = False,
) -> dict:
    """Visibility error of a candidate against the reference, on receiver pixels only.

    A pixel is classified lit when its visibility is ``>= threshold``. "False lit" is a
    receiver that the candidate classifies lit and the reference shadowed (light leaking,
    peter-panning); "false shadow" the opposite (acne, over-blurred or misplaced shadows).
    The edge band is every receiver within ``edge_band`` pixels (Chebyshev distance) of a
    shadow edge of the thresholded reference (:func:`shadow_edges`).

    Parameters
    ----------
    reference, candidate : array_like
        Visibility in [0, 1], 1 = lit, ``(H, W)`` float, same shape.
    receivers : array_like of bool, keyword-only
        ``(H, W)`` True on valid pixels with N.L > 0.
    edge_band : int, keyword-only
        Half-width of the edge band in pixels, >= 0 (0 = the edge pixels only).
    threshold : float, keyword-only
        Lit/shadowed classification threshold, in (0, 1].
    full : bool, keyword-only
        Also return per-pixel maps.

    Returns
    -------
    dict
        ``visibility_mae``, ``visibility_rmse``: mean absolute and root-mean-square
        visibility error over receivers, in [0, 1].
        ``misclassified_fraction`` = ``false_lit_fraction + false_shadow_fraction``:
        fractions of receivers, in [0, 1].
        ``edge_band_mae``, ``edge_band_misclassified_fraction``: the same inside the edge
        band (fractions of the band's receivers).
        ``receiver_count``, ``edge_band_count``: pixel counts (int).
        With ``full=True`` also ``signed_error`` (``(H, W)`` float32, candidate minus
        reference on receivers, 0 elsewhere; positive = too lit), ``misclassified``
        (``(H, W)`` int8: +1 false lit, -1 false shadow, 0 otherwise) and ``edge_band``
        (``(H, W)`` bool). With no receivers (or an empty band) the corresponding values
        are 0.0, never NaN.

    References
    ----------
    .. [1] D. Scherzer, M. Wimmer, W. Purgathofer, "A Survey of Real-Time Hard Shadow
       Mapping Methods", Computer Graphics Forum 30(1), 2011.
       DOI: 10.1111/j.1467-8659.2010.01841.x
    .. [2] A. Lauritzen, M. Salvi, A. Lefohn, "Sample Distribution Shadow Maps", I3D 2011.
       DOI: 10.1145/1944745.1944761
    """
    ref, cand = check_images(
        "reference",
        reference,
        "candidate",
        candidate,
        ndim=(2,),
        allow_negative=False,
        max_value=1.0,
    )
    rec = check_mask("receivers", receivers, ref.shape)
    if isinstance(edge_band, bool) or not isinstance(edge_band, int | np.integer) or edge_band < 0:
        raise MetricError(f"edge_band must be a non-negative integer, got {edge_band!r}")
    if not 0.0 < threshold <= 1.0:
        raise MetricError(f"threshold must be in (0, 1], got {threshold!r}")

    ref_lit = ref >= threshold
    cand_lit = cand >= threshold
    false_lit = rec & cand_lit & ~ref_lit
    false_shadow = rec & ~cand_lit & ref_lit
    wrong = false_lit | false_shadow
    error = np.where(rec, cand - ref, 0.0)
    abs_error = np.abs(error)

    band = shadow_edges(ref_lit, rec)
    if edge_band > 0:
        square = np.ones((2 * edge_band + 1, 2 * edge_band + 1), dtype=bool)
        band = ndimage.binary_dilation(band, structure=square)
    band &= rec

    n = int(rec.sum())
    n_band = int(band.sum())
    n_false_lit = int(false_lit.sum())
    n_false_shadow = int(false_shadow.sum())
    result = {
        "visibility_mae": _fraction(float(abs_error[rec].sum()), n),
        "visibility_rmse": float(np.sqrt(_fraction(float(np.square(error[rec]).sum()), n))),
        "misclassified_fraction": _fraction(n_false_lit + n_false_shadow, n),
        "false_lit_fraction": _fraction(n_false_lit, n),
        "false_shadow_fraction": _fraction(n_false_shadow, n),
        "edge_band_mae": _fraction(float(abs_error[band].sum()), n_band),
        "edge_band_misclassified_fraction": _fraction(int(wrong[band].sum()), n_band),
        "receiver_count": n,
        "edge_band_count": n_band,
    }
    if full:
        result["signed_error"] = error.astype(np.float32)
        result["misclassified"] = false_lit.astype(np.int8) - false_shadow.astype(np.int8)
        result["edge_band"] = band
    return result
