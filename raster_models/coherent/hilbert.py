"""The Hilbert curve on a ``2^k x 2^k`` grid: index <-> cell, vectorized over arrays.

The curve visits every cell of the ``n x n`` grid (``n`` a power of two) once, and
consecutive indices are edge neighbours (one step in x or in y). Coherent shadow maps number
their directions along it, so that maps with consecutive ids look from neighbouring
directions. Both functions loop over the ``k`` bit levels only (a list-length loop); every
level is one NumPy operation over all cells.

References
----------
.. [1] D. Hilbert, "Ueber die stetige Abbildung einer Linie auf ein Flaechenstueck",
   Mathematische Annalen 38, 1891. DOI: 10.1007/BF01199431
.. [2] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
"""

from __future__ import annotations

import numpy as np

__all__ = ["hilbert_cell", "hilbert_index", "is_power_of_two"]


def is_power_of_two(n: int) -> bool:
    """True for 1, 2, 4, 8, ..."""
    return n >= 1 and (n & (n - 1)) == 0


def _check(n: int) -> int:
    n = int(n)
    if not is_power_of_two(n):
        raise ValueError(f"Hilbert grid side must be a power of two, got {n}")
    return n


def _rotate(s: int, x, y, rx, ry):
    """Reflect/transpose the quadrant so that the sub-curve has the canonical orientation."""
    flip = (ry == 0) & (rx == 1)
    x = np.where(flip, s - 1 - x, x)
    y = np.where(flip, s - 1 - y, y)
    swap = ry == 0
    return np.where(swap, y, x), np.where(swap, x, y)


def hilbert_index(n: int, x, y) -> np.ndarray:
    """Hilbert index of cells ``(x, y)`` (integer arrays in ``[0, n)``) on an ``n x n`` grid.

    Returns int64 indices in ``[0, n^2)``; cell ``(0, 0)`` has index 0 and cell ``(n - 1, 0)``
    index ``n^2 - 1``.
    """
    n = _check(n)
    x = np.asarray(x, dtype=np.int64).copy()
    y = np.asarray(y, dtype=np.int64).copy()
    d = np.zeros(np.broadcast(x, y).shape, dtype=np.int64)
    s = n // 2
    while s > 0:
        rx = ((x & s) > 0).astype(np.int64)
        ry = ((y & s) > 0).astype(np.int64)
        d += s * s * ((3 * rx) ^ ry)
        x, y = _rotate(n, x, y, rx, ry)
        s //= 2
    return d


def hilbert_cell(n: int, d) -> tuple[np.ndarray, np.ndarray]:
    """Cells ``(x, y)`` of Hilbert indices ``d`` (integer array in ``[0, n^2)``); the inverse
    of :func:`hilbert_index`."""
    n = _check(n)
    t = np.asarray(d, dtype=np.int64).copy()
    x = np.zeros_like(t)
    y = np.zeros_like(t)
    s = 1
    while s < n:
        rx = 1 & (t // 2)
        ry = 1 & (t ^ rx)
        x, y = _rotate(s, x, y, rx, ry)
        x += s * rx
        y += s * ry
        t //= 4
        s *= 2
    return x, y
