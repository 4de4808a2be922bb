"""The cost estimate of exact coverage, made before any polygon work, the budget's refusal
(:class:`OverBudget`) and its deadline (:class:`OutOfTime`, :func:`deadline_check`).

The estimate counts the work as the work counts it: each projected triangle larger than
:data:`coverage_projection.BIG_TILES` tiles is cut into the tiles it meets (as
:func:`coverage_projection.tile` cuts it: 16 x 16 tiles across the film, so N large
overlapping triangles make about 256 N^2 / 2 overlapping piece pairs), and the pairs of
pieces whose bounding boxes overlap are counted once each, on a grid of
:data:`CELLS_PER_TILE` cells a tile (a pair is counted in the cell holding the lower-left
corner of the two boxes' overlap).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .coverage_projection import BIG_TILES, FILM_MARGIN, TILES_ACROSS, film_boxes
from .coverage_triangles import TriangleSet

__all__ = [
    "CELLS_PER_TILE",
    "COST_PER_PAIR_LAYERED",
    "COST_PER_PAIR_POLYGONS",
    "COST_PER_PIECE",
    "COST_PER_TILE_PAIR_LAYERED",
    "COST_PER_TRIANGLE",
    "COST_PER_VIEW",
    "OutOfTime",
    "OverBudget",
    "deadline_check",
    "estimate_cost",
    "pixels_per_unit_near",
    "polygon_seconds",
]

#: The cost model of :func:`estimate_cost`: seconds per view (fixed costs), per projected
#: triangle, per tile piece, and per overlapping piece pair on the layered path and on the
#: polygon path (shapely intersections and unions), fitted to the exact pass's process CPU
#: time on the 2-core development machine (docs/research.md: estimate against actual, every
#: row within 3x; the polygon rate also gives the issue's 146.6 s for the 80 stacked panes
#: at 256 x 256: 6.26 million pairs x 2.2e-5 s = 138 s).
COST_PER_VIEW = 0.01
COST_PER_TRIANGLE = 1e-5
COST_PER_PIECE = 1e-5
COST_PER_PAIR_LAYERED = 7e-7
COST_PER_PAIR_POLYGONS = 2.2e-5
#: ... and on the layered path, per pair of two tile pieces (both cut from polygons larger
#: than :data:`coverage_projection.BIG_TILES` tiles): their long visible boundaries are
#: clipped against each other (stacked panes: 8e-6 s a pair in all).
COST_PER_TILE_PAIR_LAYERED = 7.3e-6
#: Cells a tile is divided into, across, for counting overlapping pairs (finer: fewer
#: pairs of small boxes that share a cell without overlapping are counted).
CELLS_PER_TILE = 8


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


class OutOfTime(Exception):
    """The exact pass ran past its deadline; ``elapsed``: its seconds when it stopped."""

    def __init__(self, elapsed: float):
        super().__init__(f"stopped after {elapsed:.1f} s of exact work (deadline reached)")
        self.elapsed = elapsed


def deadline_check(check=None, deadline: float | None = None, start: float | None = None):
    """A check for the work's chunk boundaries: calls ``check`` (None: nothing), then
    raises :class:`OutOfTime` once ``time.perf_counter()`` is past ``deadline`` (None: no
    deadline; ``start``: when the work began, for the elapsed time it reports)."""
    start = time.perf_counter() if start is None else start

    def run() -> None:
        if check is not None:
            check()
        now = time.perf_counter()
        if deadline is not None and now > deadline:
            raise OutOfTime(now - start)

    return run


def estimate_cost(camera, tset: TriangleSet, path: str = "layered", pairs=None) -> dict:
    """Deterministic cost estimate of :func:`exact_coverage_of`, made before any polygon
    work: the triangles are clipped and projected with NumPy (in chunks), cut into tile
    pieces as the work cuts them and the overlapping pairs of the pieces' bounding boxes
    counted once each (``pairs`` given: that count). ``{"seconds", "triangles", "pieces",
    "pairs", "path", "rounding_px"}``; seconds by the cost model above (``path``:
    ``"layered"`` or ``"polygons"``)."""
    w, h = camera.width, camera.height
    size = max(1, math.ceil((w + 2 * FILM_MARGIN) / TILES_ACROSS))
    cell = size / CELLS_PER_TILE
    nx = int(math.ceil((w + 2 * FILM_MARGIN) / cell)) + 1
    ny = int(math.ceil((h + 2 * FILM_MARGIN) / cell)) + 1
    grid = (cell, nx, ny)
    cells, classes, tile_cells, tile_classes = [], [], [], []
    n_tri = n_piece = 0
    reach = 0.0
    for start in range(0, len(tset.tris), 1 << 15):
        part, far = film_boxes(camera, tset.tris[start : start + (1 << 15)])
        reach = max(reach, far)
        if part is None:
            continue
        n_tri += len(part["box"])
        lo, hi, cut = _pieces(part, size)
        n_piece += len(lo)
        at, cls = _cells(lo, hi, grid)
        cells.append(at)
        classes.append(cls)
        at, cls = _cells(lo[cut], hi[cut], grid)
        tile_cells.append(at)
        tile_classes.append(cls)
    if pairs is None:
        pairs = _pairs(cells, classes, nx * ny)
    tile_pairs = min(pairs, _pairs(tile_cells, tile_classes, nx * ny))
    seconds = (
        COST_PER_TRIANGLE * n_tri
        + COST_PER_PIECE * n_piece
        + (
            COST_PER_PAIR_LAYERED * pairs + COST_PER_TILE_PAIR_LAYERED * tile_pairs
            if path == "layered"
            else COST_PER_PAIR_POLYGONS * pairs
        )
    )
    seconds += COST_PER_VIEW if n_tri else 0.0
    return {
        "seconds": float(seconds),
        "triangles": int(n_tri),
        "pieces": int(n_piece),
        "pairs": int(pairs),
        "tile_pairs": int(tile_pairs),
        "path": path,
        "rounding_px": float(reach * 2.0**-52 * pixels_per_unit_near(camera)),
    }


def polygon_seconds(est: dict) -> float:
    """The estimate ``est`` (:func:`estimate_cost`, layered) for the polygon path."""
    layered = COST_PER_PAIR_LAYERED * est["pairs"] + COST_PER_TILE_PAIR_LAYERED * est["tile_pairs"]
    return est["seconds"] - layered + COST_PER_PAIR_POLYGONS * est["pairs"]


def _pieces(part: dict, size: int):
    """Bounding boxes ``(lo, hi)`` of the tile pieces of the projected polygons of
    ``part`` (:func:`film_boxes`) and whether each is cut from a polygon larger than
    :data:`BIG_TILES` tiles (cut into the tiles it meets; a tile wholly beyond one of its
    edges is no piece); the others are one piece each."""
    box = part["box"]
    lo, hi = box[:, :2], box[:, 2:]
    big = part["area"] > BIG_TILES * size * size
    t0 = np.floor((lo + FILM_MARGIN) / size).astype(np.int64)
    t1 = np.floor((hi + FILM_MARGIN) / size).astype(np.int64)
    span = np.where(big[:, None], t1 - t0 + 1, 1)
    count = span.prod(axis=1)
    owner = np.repeat(np.arange(len(box)), count)
    k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    tile_lo = np.stack([t0[owner, 0] + k % span[owner, 0], t0[owner, 1] + k // span[owner, 0]], 1)
    tile_lo = tile_lo * size - FILM_MARGIN
    cut = big[owner]
    p_lo = np.where(cut[:, None], np.maximum(tile_lo, lo[owner]), lo[owner])
    p_hi = np.where(cut[:, None], np.minimum(tile_lo + size, hi[owner]), hi[owner])
    if cut.any():
        idx = np.flatnonzero(cut)
        o = owner[idx]
        away = _beyond_an_edge(part["film"][o], part["count"][o], p_lo[idx], p_hi[idx])
        keep = np.ones(len(owner), bool)
        keep[idx[away]] = False
        cut, p_lo, p_hi = cut[keep], p_lo[keep], p_hi[keep]
    return p_lo, p_hi, cut


def _beyond_an_edge(film, count, lo, hi) -> np.ndarray:
    """Whether each box ``[lo, hi]`` lies wholly outside its convex polygon ``film`` (``count``
    vertices): its four corners on the outer side of one edge's line."""
    k = film.shape[1]
    idx = np.arange(k)[None, :]
    valid = idx < count[:, None]
    b = np.take_along_axis(film, ((idx + 1) % count[:, None])[..., None], 1)
    x, y, xn, yn = film[..., 0], film[..., 1], b[..., 0], b[..., 1]
    turn = np.sign(np.where(valid, x * yn - xn * y, 0.0).sum(axis=1))[:, None, None]
    corners = np.stack(
        [lo, np.stack([hi[:, 0], lo[:, 1]], 1), np.stack([lo[:, 0], hi[:, 1]], 1), hi], 1
    )
    edge = (b - film)[:, :, None, :]
    rel = corners[:, None, :, :] - film[:, :, None, :]
    side = (edge[..., 0] * rel[..., 1] - edge[..., 1] * rel[..., 0]) * turn
    return ((side < 0).all(axis=2) & valid).any(axis=1)


def _cells(lo, hi, grid):
    """The grid cells each box covers (flat index), each with its class (bit 0: the box's
    first column, bit 1: its first row)."""
    cell, nx, ny = grid
    c0 = np.floor((lo + FILM_MARGIN) / cell).astype(np.int64)
    c1 = np.floor((hi + FILM_MARGIN) / cell).astype(np.int64)
    c1 = np.clip(c1, 0, [nx - 1, ny - 1])
    c0 = np.clip(c0, 0, c1)
    span = c1 - c0 + 1
    m = span.prod(axis=1)
    which = np.repeat(np.arange(len(c0)), m)
    k = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m)
    cx, cy = k % span[which, 0], k // span[which, 0]
    at = (c0[which, 1] + cy) * nx + c0[which, 0] + cx
    return at, (cx == 0).astype(np.int8) + 2 * (cy == 0).astype(np.int8)


def _pairs(cells, classes, n_cells: int) -> int:
    """Overlapping box pairs, each counted in the one cell that holds the corner where both
    start (the later first column and the later first row): per cell, with the boxes
    counted by class (first column and first row there ``xy``, only one of them ``x``/``y``,
    neither ``n``), ``C(xy, 2) + xy (x + y + n) + x y``."""
    if not cells:
        return 0
    at, cls = np.concatenate(cells), np.concatenate(classes)
    n, x, y, xy = (np.bincount(at[cls == c], minlength=n_cells) for c in range(4))
    return int((xy * (xy - 1) // 2 + xy * (x + y + n) + x * y).sum())


def pixels_per_unit_near(camera) -> float:
    """Film pixels per world unit at the near plane (the largest scale a world distance in
    view is seen at)."""
    if camera.kind != "perspective":
        return camera.width / (2.0 * camera.half_extent()[0])
    return camera.width / (2.0 * camera.tan_half_x) / camera.near
