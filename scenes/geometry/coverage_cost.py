"""The cost estimate of exact coverage, made before any polygon work, and the budget's
refusal (:class:`OverBudget`)."""

from __future__ import annotations

import numpy as np

from .coverage_projection import FILM_MARGIN, film_boxes
from .coverage_triangles import TriangleSet

__all__ = [
    "BIG_CELLS",
    "COST_CELLS_ACROSS",
    "COST_PER_PAIR_LAYERED",
    "COST_PER_PAIR_POLYGONS",
    "COST_PER_TRIANGLE",
    "OverBudget",
    "estimate_cost",
    "pixels_per_unit_near",
]

#: The cost model of :func:`estimate_cost` (seconds on one core of the 2-core development
#: machine, measured in CPU time on the built-in scenes and meadow:n=10k-100k; see
#: docs/research.md): per projected triangle, per candidate pair sharing a grid cell on the
#: layered path, and per pair on the polygon path (shapely intersections and unions).
COST_PER_TRIANGLE = 3e-5
COST_PER_PAIR_LAYERED = 1.5e-6
COST_PER_PAIR_POLYGONS = 6e-6
#: Cells across the film of the grid :func:`estimate_cost` counts candidate pairs on (a
#: fixed number, so that the estimate does not grow with the resolution); polygons covering
#: more than ``BIG_CELLS`` cells are counted against every other polygon.
COST_CELLS_ACROSS = 80
BIG_CELLS = 4096


class OverBudget(Exception):
    """The estimated cost of the exact coverage exceeds the budget; ``estimate`` says by how
    much (:func:`estimate_cost`)."""

    def __init__(self, estimate: dict, budget: float):
        super().__init__(
            f"estimated {estimate['seconds']:.3g} s > budget {budget:g} s "
            f"({estimate['triangles']} projected triangles, {estimate['pairs']} overlapping "
            f"pairs, {estimate['path']} path)"
        )
        self.estimate, self.budget = estimate, budget


def estimate_cost(camera, tset: TriangleSet, path: str = "layered", pairs=None) -> dict:
    """Deterministic cost estimate of :func:`exact_coverage_of` from the projected
    triangles and their overlaps, made before any polygon work: the triangles are clipped
    and projected with NumPy (in chunks), their bounding boxes binned on a grid of
    :data:`COST_CELLS_ACROSS` cells across, and the pairs sharing a cell counted (``pairs``
    given: that count). ``{"seconds", "triangles", "pairs", "path"}``; seconds by the cost
    model above (``path``: ``"layered"`` or ``"polygons"``)."""
    w, h = camera.width, camera.height
    cell = w / COST_CELLS_ACROSS
    nx, ny = int(w / cell) + 3, int(h / cell) + 3
    counts = np.zeros(nx * ny, np.int64)
    n_tri = n_big = 0
    reach = 0.0
    for start in range(0, len(tset.tris), 1 << 15):
        box, far = film_boxes(camera, tset.tris[start : start + (1 << 15)])
        reach = max(reach, far)
        if box is None:
            continue
        c0 = np.floor((box[:, :2] + FILM_MARGIN) / cell).astype(np.int64) + 1
        c1 = np.floor((box[:, 2:] + FILM_MARGIN) / cell).astype(np.int64) + 1
        c0, c1 = np.clip(c0, 0, [nx - 1, ny - 1]), np.clip(c1, 0, [nx - 1, ny - 1])
        span = (c1 - c0 + 1).prod(axis=1)
        big = span > BIG_CELLS
        n_tri += len(box)
        n_big += int(big.sum())
        c0, c1, span = c0[~big], c1[~big], span[~big]
        own = np.repeat(np.arange(len(span)), span)
        k = np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span)
        wx = (c1 - c0 + 1)[own, 0]
        at = (c0[own, 1] + k // wx) * nx + c0[own, 0] + k % wx
        counts += np.bincount(at, minlength=nx * ny)
    if pairs is None:
        pairs = int((counts * (counts - 1) // 2).sum()) + n_big * n_tri
    rate = COST_PER_PAIR_LAYERED if path == "layered" else COST_PER_PAIR_POLYGONS
    seconds = COST_PER_TRIANGLE * n_tri + rate * pairs
    return {
        "seconds": float(seconds),
        "triangles": int(n_tri),
        "pairs": int(pairs),
        "path": path,
        "rounding_px": float(reach * 2.0**-52 * pixels_per_unit_near(camera)),
    }


def pixels_per_unit_near(camera) -> float:
    """Film pixels per world unit at the near plane (the largest scale a world distance in
    view is seen at)."""
    if camera.kind != "perspective":
        return camera.width / (2.0 * camera.half_extent()[0])
    return camera.width / (2.0 * camera.tan_half_x) / camera.near
