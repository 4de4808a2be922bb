"""Anti-aliasing error: edge versus interior pixels, coverage error, and the coverage error
floor of a sample pattern on straight edges.

Pixel (x, y) covers [x, x+1) x [y, y+1), row 0 at the top. Sub-sample positions are in
[0, 1)^2 from the pixel's upper-left corner, y down (the Vulkan standard locations).
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError, check_image, check_images, check_mask

__all__ = [
    "COVERAGE_FLOOR_RMS",
    "COVERAGE_KEYS",
    "coverage_metrics",
    "coverage_error",
    "edge_interior_error",
    "edges_from_id",
    "half_plane_square_area",
    "straight_edge_error_floor",
]

# Edges processed per chunk in straight_edge_error_floor: bounds memory to
# chunk * samples * 8 bytes (16 MiB for 16 samples).
_EDGE_CHUNK = 131_072
# Below this slope ratio the area formula's divided difference loses precision; the
# limit (a line parallel to a square side) is used instead.
_PARALLEL_SLOPE = 1e-9


def _mae_rmse(error: np.ndarray, mask: np.ndarray) -> tuple[float, float, int]:
    """MAE and RMSE of ``error`` over ``mask`` (over all channels); 0.0 when empty."""
    count = int(mask.sum())
    if count == 0:
        return 0.0, 0.0, 0
    e = error[mask]
    return float(np.abs(e).mean()), float(np.sqrt(np.square(e).mean())), count


def edges_from_id(id_buffer) -> np.ndarray:
    """Pixels on a geometric edge: their id differs from a 4-neighbour's.

    Parameters
    ----------
    id_buffer : array_like
        ``(H, W)`` integer (or integral float) primitive/shape id per pixel, e.g. the
        reference's 1-sample id at pixel centres; the sky has its own id.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` bool; both pixels of every differing neighbour pair are marked.
    """
    ids = np.asarray(id_buffer)
    if ids.dtype.kind in "f":
        check_image("id_buffer", ids, ndim=(2,))
    elif ids.dtype.kind not in "biu":
        raise MetricError(f"id_buffer must be an integer array, got dtype {ids.dtype}")
    if ids.ndim != 2 or ids.size == 0:
        raise MetricError(f"id_buffer must be a non-empty 2-D array, got shape {ids.shape}")
    edges = np.zeros(ids.shape, dtype=bool)
    dx = ids[:, 1:] != ids[:, :-1]
    dy = ids[1:, :] != ids[:-1, :]
    edges[:, 1:] |= dx
    edges[:, :-1] |= dx
    edges[1:, :] |= dy
    edges[:-1, :] |= dy
    return edges


def edge_interior_error(reference, candidate, *, edge_mask) -> dict:
    """Error split into edge pixels and interior pixels.

    Parameters
    ----------
    reference, candidate : array_like
        Linear images (radiance, coverage or visibility), ``(H, W)`` or ``(H, W, C)``,
        same shape.
    edge_mask : array_like of bool, keyword-only
        ``(H, W)`` True on edge pixels: the reference's ``edge`` channel or
        :func:`edges_from_id` of its id buffer. Every other pixel is interior.

    Returns
    -------
    dict
        ``edge_mae``, ``edge_rmse``, ``interior_mae``, ``interior_rmse``: mean absolute and
        root-mean-square error (candidate - reference) over the pixel-channels of each set,
        in the images' units; ``edge_count``, ``interior_count``: pixel counts. An empty
        set gives 0.0.

    References
    ----------
    .. [1] A. Reshetov, "Morphological antialiasing", HPG 2009 (edge/interior split of AA
       error). DOI: 10.1145/1572769.1572787
    """
    ref, cand = check_images("reference", reference, "candidate", candidate)
    mask = check_mask("edge_mask", edge_mask, ref.shape[:2])
    error = cand - ref
    edge_mae, edge_rmse, n_edge = _mae_rmse(error, mask)
    interior_mae, interior_rmse, n_interior = _mae_rmse(error, ~mask)
    return {
        "edge_mae": edge_mae,
        "edge_rmse": edge_rmse,
        "interior_mae": interior_mae,
        "interior_rmse": interior_rmse,
        "edge_count": n_edge,
        "interior_count": n_interior,
    }


def coverage_error(reference_coverage, candidate_coverage, *, mask=None) -> dict:
    """Error of per-pixel coverage (fraction of the pixel covered), in [0, 1].

    Parameters
    ----------
    reference_coverage, candidate_coverage : array_like
        ``(H, W)`` coverage in [0, 1], same shape (e.g. supersampled reference coverage and
        an N-sample technique's resolved coverage).
    mask : array_like of bool or None, keyword-only
        ``(H, W)`` pixels to score; default all.

    Returns
    -------
    dict
        ``mae``, ``rmse``, ``max`` (largest absolute error), ``bias`` (mean signed error,
        candidate minus reference), all in coverage units, and ``count``; 0.0 when the
        mask is empty.

    References
    ----------
    .. [1] K. Akeley, "RealityEngine graphics", SIGGRAPH 1993 (box-resolved multisample
       coverage). DOI: 10.1145/166117.166131
    """
    ref, cand = check_images(
        "reference_coverage",
        reference_coverage,
        "candidate_coverage",
        candidate_coverage,
        ndim=(2,),
        allow_negative=False,
        max_value=1.0,
    )
    sel = np.ones(ref.shape, bool) if mask is None else check_mask("mask", mask, ref.shape)
    error = (cand - ref)[sel]
    if error.size == 0:
        return {"mae": 0.0, "rmse": 0.0, "max": 0.0, "bias": 0.0, "count": 0}
    return {
        "mae": float(np.abs(error).mean()),
        "rmse": float(np.sqrt(np.square(error).mean())),
        "max": float(np.abs(error).max()),
        "bias": float(error.mean()),
        "count": int(error.size),
    }


def half_plane_square_area(normal_x, normal_y, offset) -> np.ndarray:
    """Exact area of ``{p in [0, 1]^2 : normal . p <= offset}``, vectorized.

    Closed form: flip axes so that both normal components are >= 0 (``x -> 1 - x`` moves
    the offset by ``-min(n, 0)``), scale by the larger component ``a``; with ``u0 =
    offset / a`` and slope ``s = b / a`` in [0, 1], the area is ``(F(u0) - F(u0 - s)) / s``
    where ``F`` is the antiderivative of ``clip(u, 0, 1)`` (``0``, ``u^2 / 2``,
    ``u - 1/2``), and ``clip(u0, 0, 1)`` in the limit ``s -> 0``.

    Parameters
    ----------
    normal_x, normal_y, offset : array_like
        Broadcastable arrays; the normal need not be unit length but must be non-zero.

    Returns
    -------
    numpy.ndarray
        float64 area in [0, 1].
    """
    nx, ny, c = np.broadcast_arrays(
        np.asarray(normal_x, np.float64),
        np.asarray(normal_y, np.float64),
        np.asarray(offset, np.float64),
    )
    c = c - np.minimum(nx, 0.0) - np.minimum(ny, 0.0)
    ax, ay = np.abs(nx), np.abs(ny)
    big, small = np.maximum(ax, ay), np.minimum(ax, ay)
    if np.any(big == 0):
        raise MetricError("half-plane normals must be non-zero")
    u0 = c / big
    s = small / big
    sloped = s > _PARALLEL_SLOPE
    s_safe = np.where(sloped, s, 1.0)

    def antiderivative(u):
        return np.where(u <= 0, 0.0, np.where(u < 1, 0.5 * u * u, u - 0.5))

    area = (antiderivative(u0) - antiderivative(u0 - s_safe)) / s_safe
    return np.clip(np.where(sloped, area, np.clip(u0, 0.0, 1.0)), 0.0, 1.0)


def straight_edge_error_floor(sample_positions, *, n_edges: int = 200_000, seed: int = 0) -> dict:
    """Coverage error of a box-resolved N-sample pattern on random straight edges.

    For each random straight edge through the unit pixel, the pattern's coverage (the
    fraction of sample positions inside the half-plane) is compared with the exact area of
    the half-plane inside the pixel (:func:`half_plane_square_area`). This is the error
    floor of any technique that resolves N binary samples with a box filter.

    Edge distribution: the line ``cos(t) x + sin(t) y = c`` with ``t`` uniform in
    [0, 2 pi) (direction and covered side) and ``c`` uniform over the offsets at which the
    line crosses the pixel, ``[min_corner(n . p), max_corner(n . p)]``. This is the
    motion-invariant (Crofton) measure of lines hitting the square; it reproduces the
    published table (1x 0.250 / 0.50 ... 16x 0.044 / 0.17 RMS / max) within its
    Monte-Carlo noise, whereas lines through a uniform point of the pixel or offsets
    uniform around the centre do not.

    Parameters
    ----------
    sample_positions : array_like
        ``(N, 2)`` sample positions (x, y) in [0, 1]^2 from the upper-left corner, y down.
    n_edges : int, keyword-only
        Number of random edges, >= 1. The RMS's relative standard error is about
        ``0.6 / sqrt(n_edges)`` to ``0.75 / sqrt(n_edges)`` for the 1x to 16x patterns
        (``rms_stderr`` gives it).
    seed : int, keyword-only
        Seed of ``numpy.random.default_rng``; the same seed gives the same edges.

    Returns
    -------
    dict
        ``rms``: root-mean-square coverage error; ``max``: largest absolute error seen
        (a lower bound of the supremum, converging from below as ``n_edges`` grows);
        ``rms_stderr``: standard error of ``rms`` (delta method); ``n_edges``, ``seed``.

    References
    ----------
    .. [1] K. Akeley, "RealityEngine graphics", SIGGRAPH 1993.
       DOI: 10.1145/166117.166131
    .. [2] L. A. Santalo, "Integral Geometry and Geometric Probability", Cambridge
       University Press, 2004 (measure of lines hitting a convex set).
       DOI: 10.1017/CBO9780511617331
    """
    pts = check_image(
        "sample_positions", sample_positions, ndim=(2,), allow_negative=False, max_value=1.0
    )
    if pts.shape[1] != 2:
        raise MetricError(f"sample_positions must have shape (N, 2), got {pts.shape}")
    if isinstance(n_edges, bool) or not isinstance(n_edges, int | np.integer) or n_edges < 1:
        raise MetricError(f"n_edges must be a positive integer, got {n_edges!r}")
    rng = np.random.default_rng(seed)
    sum_sq = 0.0
    sum_sq2 = 0.0
    max_abs = 0.0
    for start in range(0, n_edges, _EDGE_CHUNK):
        m = min(_EDGE_CHUNK, n_edges - start)
        theta = rng.uniform(0.0, 2.0 * np.pi, m)
        nx, ny = np.cos(theta), np.sin(theta)
        low = np.minimum(nx, 0.0) + np.minimum(ny, 0.0)
        high = np.maximum(nx, 0.0) + np.maximum(ny, 0.0)
        c = rng.uniform(low, high)
        exact = half_plane_square_area(nx, ny, c)
        inside = (nx[:, None] * pts[None, :, 0] + ny[:, None] * pts[None, :, 1]) <= c[:, None]
        error = inside.mean(axis=1) - exact
        sq = np.square(error)
        sum_sq += float(sq.sum())
        sum_sq2 += float(np.square(sq).sum())
        max_abs = max(max_abs, float(np.abs(error).max()))
    mean_sq = sum_sq / n_edges
    var_sq = max(sum_sq2 / n_edges - mean_sq**2, 0.0)
    rms = float(np.sqrt(mean_sq))
    rms_stderr = float(np.sqrt(var_sq / n_edges) / (2 * rms)) if rms > 0 else 0.0
    return {
        "rms": rms,
        "max": max_abs,
        "rms_stderr": rms_stderr,
        "n_edges": int(n_edges),
        "seed": seed,
    }


#: RMS coverage error of a box-resolved N-sample standard pattern on one straight edge
#: (TECHNIQUES.md table; :func:`straight_edge_error_floor` reproduces it).
COVERAGE_FLOOR_RMS = {1: 0.250, 2: 0.159, 4: 0.092, 8: 0.057, 16: 0.044}
#: The keys :func:`coverage_metrics` returns (anti-aliasing techniques, or an engine's MSAA
#: coverage mask).
COVERAGE_KEYS = (
    "coverage_mae",
    "coverage_rmse",
    "coverage_bias",
    "coverage_edge_rmse",
    "coverage_interior_mae",
    "coverage_floor_rms",
    "coverage_edge_rmse_over_floor",
)


def coverage_metrics(ref, cand, *, edge, aa_samples) -> dict:
    """Coverage error overall, on edge and interior pixels, and against the N-sample floor.

    Edge pixels: ``edge`` (bool ``(H, W)``) or fractional reference coverage. The floor is
    the RMS error of N box-resolved standard samples on one straight edge
    (:data:`COVERAGE_FLOOR_RMS`); ``coverage_edge_rmse_over_floor`` near 1 means the
    technique is as good as its pattern allows (above 1 also where an edge pixel holds more
    than one edge, or the reference's own noise adds to the error).
    """
    edge = edge | ((ref > 0) & (ref < 1))
    every = coverage_error(ref, cand)
    on_edge = coverage_error(ref, cand, mask=edge)
    inside = coverage_error(ref, cand, mask=~edge)
    floor = COVERAGE_FLOOR_RMS.get(int(aa_samples)) if aa_samples else None
    ratio = on_edge["rmse"] / floor if floor and on_edge["count"] else None
    return {
        "coverage_mae": every["mae"],
        "coverage_rmse": every["rmse"],
        "coverage_bias": every["bias"],
        "coverage_edge_rmse": on_edge["rmse"] if on_edge["count"] else None,
        "coverage_interior_mae": inside["mae"] if inside["count"] else None,
        "coverage_floor_rms": floor,
        "coverage_edge_rmse_over_floor": ratio,
    }
