"""Summaries of error maps: histograms, scalar statistics and the worst tiles.

All functions take ``(H, W)`` float arrays (row 0 at the top, pixel (x, y) covering
[x, x+1) x [y, y+1)) and return plain JSON-compatible records. Vectorized: no loop over
pixels or tiles.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HISTOGRAM_BINS", "error_summary", "histogram", "worst_tiles"]

#: Histogram bins per style: odd for "signed" so that zero error is the centre of one bin.
HISTOGRAM_BINS = {"signed": 51, "magma": 50}


def histogram(data: np.ndarray, *, style: str, value_range: tuple[float, float]) -> dict:
    """Bin counts of ``data`` over the fixed display range.

    Values outside the range are counted in the end bins (as the heatmap saturates them) and
    also reported as ``below``/``above``, so ``sum(counts)`` is always the pixel count.

    Returns
    -------
    dict
        ``{"edges": [n + 1 floats], "counts": [n ints], "total": int, "below": int,
        "above": int}``.
    """
    lo, hi = value_range
    bins = HISTOGRAM_BINS[style]
    counts, edges = np.histogram(np.clip(data, lo, hi), bins=bins, range=(lo, hi))
    return {
        "edges": [round(float(e), 9) for e in edges],
        "counts": [int(c) for c in counts],
        "total": int(data.size),
        "below": int(np.count_nonzero(data < lo)),
        "above": int(np.count_nonzero(data > hi)),
    }


def error_summary(data: np.ndarray) -> dict:
    """Mean, mean |e|, 99th percentile of |e|, max |e| and the fraction of non-zero pixels."""
    magnitude = np.abs(data.astype(np.float64))
    return {
        "mean": float(data.mean(dtype=np.float64)),
        "mean_abs": float(magnitude.mean()),
        "p99_abs": float(np.percentile(magnitude, 99.0)),
        "max_abs": float(magnitude.max()),
        "nonzero_fraction": float(np.count_nonzero(magnitude) / magnitude.size),
    }


def worst_tiles(error: np.ndarray, *, tile: int, count: int) -> list[dict]:
    """The ``count`` tiles of ``tile`` x ``tile`` pixels with the largest mean |error|.

    The image is cut into a grid from the top-left corner; the tiles of the last row and
    column may be smaller and are averaged over their own pixels. Tiles with zero error are
    never returned; ties go to the tile that comes first in row-major order.

    Returns
    -------
    list of dict
        ``{"rank": 1.., "x", "y", "w", "h": pixel rectangle, "mean_abs_error": float}``,
        worst first.
    """
    height, width = error.shape
    ny, nx = -(-height // tile), -(-width // tile)
    padded = np.zeros((ny * tile, nx * tile), dtype=np.float64)
    padded[:height, :width] = np.abs(error)
    sums = padded.reshape(ny, tile, nx, tile).sum(axis=(1, 3))
    tile_h = np.minimum(tile, height - tile * np.arange(ny))
    tile_w = np.minimum(tile, width - tile * np.arange(nx))
    means = (sums / (tile_h[:, None] * tile_w[None, :])).ravel()
    order = np.argsort(-means, kind="stable")[:count]
    order = order[means[order] > 0.0]
    rows, cols = np.divmod(order, nx)
    return [
        {
            "rank": rank + 1,
            "x": int(c * tile),
            "y": int(r * tile),
            "w": int(tile_w[c]),
            "h": int(tile_h[r]),
            "mean_abs_error": float(means[i]),
        }
        for rank, (i, r, c) in enumerate(zip(order, rows, cols, strict=True))
    ]
