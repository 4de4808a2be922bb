"""NumPy reference of the coherent-shadow-map compression analysis (the model runs it in
Dr.Jit kernels, :mod:`raster_models.coherent.kernels`): the visibility intervals of the
texels and the greedy run compression of one ordering, written directly from their
definitions (Ritschel et al. 2007, lossless compression).

The kernels compute the same float64 operations in the same order with one rounding to
float32, so they must give exactly these bytes (:data:`COMPRESSION_TOLERANCE`).
"""

from __future__ import annotations

import numpy as np
from raster_oracle.raster_models.coherent.surfaces import SPREAD_GUARD, stored_depth

__all__ = ["COMPRESSION_TOLERANCE", "below", "compress_runs", "visibility_intervals"]

#: Intervals, decoded maps and run counts are compared exactly: integer counts, and float32
#: values from the same float64 operations in the same order, rounded once.
COMPRESSION_TOLERANCE = 0.0


def below(x: np.ndarray) -> np.ndarray:
    """Largest float32 strictly below each float64 ``x`` (``inf`` stays ``inf``)."""
    f = x.astype(np.float32)
    f = np.where(f.astype(np.float64) >= x, np.nextafter(f, np.float32(-np.inf)), f)
    return np.where(np.isinf(x), np.float32(np.inf), f).astype(np.float32)


def visibility_intervals(z1, z2, bias: float, *, dz1=None, dz2=None, guard=SPREAD_GUARD):
    """Per texel, the stored values ``[lo, hi]`` (float32, inclusive) that give the
    uncompressed map's answer to every receiver on the texel's first or second surface.

    ``lo`` is the stored first depth ``s1``. A receiver is compared as ``z - bias <=
    stored``; on a surface of depth ``z`` at the texel centre and depth spread ``dz`` to the
    texel's corners (its plane), its reference lies in ``[z - dz - bias, z + dz - bias]``.
    First surface: if any of its references exceeds ``s1`` (acne: the uncompressed map
    shadows it there) no other value is safe, ``hi = s1``. Second surface: its references
    must stay above the stored value, ``hi`` = the largest float32 below
    ``z2 - dz2 - bias`` (``s1`` when that is not above ``s1``). Without ``dz`` (texel
    centres only) the spreads are 0. No first surface: the map is cleared to 1, every
    receiver inside the sphere is lit by any value >= 1 (``hi = inf``).
    """
    z1 = np.asarray(z1, dtype=np.float64)
    z2 = np.asarray(z2, dtype=np.float64)
    dz1 = np.zeros_like(z1) if dz1 is None else np.asarray(dz1, dtype=np.float64)
    dz2 = np.zeros_like(z2) if dz2 is None else np.asarray(dz2, dtype=np.float64)
    lo = stored_depth(z1)
    s1 = lo.astype(np.float64)
    with np.errstate(invalid="ignore"):
        acne = np.isfinite(z1) & (z1 + dz1 * guard - bias > s1)
        h2 = z2 - dz2 * guard - bias
    h2 = np.where(np.isfinite(z2), h2, np.inf)
    hi = np.where(h2 > s1, below(h2), lo)
    hi = np.where(acne, lo, hi)
    return lo, np.maximum(hi, lo).astype(np.float32)


def compress_runs(lo: np.ndarray, hi: np.ndarray, order: np.ndarray):
    """Greedy runs of consecutive maps (in ``order``) whose intervals intersect.

    Parameters
    ----------
    lo, hi : ``(N, T)`` float32 interval bounds per map id and texel.
    order : the map ids in storage order (a permutation of ``range(N)``).

    Returns
    -------
    runs : total number of stored values (runs summed over texels).
    decoded : ``(N, T)`` float32 value each map id reads after decompression (the run's
        largest ``lo``), by map id.
    """
    n, t = lo.shape
    starts = np.zeros((n, t), dtype=bool)  # a run starts at this position
    prefix = np.empty((n, t), dtype=np.float32)  # largest lo of the run so far
    cur_lo = lo[order[0]].copy()
    cur_hi = hi[order[0]].copy()
    starts[0] = True
    prefix[0] = cur_lo
    for pos in range(1, n):
        m = order[pos]
        new_lo = np.maximum(cur_lo, lo[m])
        new_hi = np.minimum(cur_hi, hi[m])
        brk = new_lo > new_hi
        cur_lo = np.where(brk, lo[m], new_lo)
        cur_hi = np.where(brk, hi[m], new_hi)
        starts[pos], prefix[pos] = brk, cur_lo
    runs = int(starts.sum())
    # Backward: every member of a run reads the run's final (largest) lo.
    value = prefix
    for pos in range(n - 2, -1, -1):
        value[pos] = np.where(starts[pos + 1], prefix[pos], value[pos + 1])
    decoded = np.empty_like(value)
    decoded[order] = value
    return runs, decoded
