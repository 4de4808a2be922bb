"""Depth partitions of the view frustum: uniform, logarithmic, practical (PSSM), manual, and
the sample-distribution schemes of the Intel SDSM sample (log over [zmin, zmax], histogram
log, adaptive log, K-means).

All depths are view-space depths (distance along the camera's forward axis, camera units).
A scheme returns ``k + 1`` increasing boundaries ``z_0 .. z_k``; partition ``i`` covers
``[z_i, z_{i+1})``.

References
----------
.. [1] F. Zhang, H. Sun, L. Xu, L. K. Lun, "Parallel-Split Shadow Maps for Large-scale
   Virtual Environments", VRCIA 2006. DOI: 10.1145/1128923.1128975
.. [2] A. Lauritzen, M. Salvi, A. Lefohn, "Sample Distribution Shadow Maps", I3D 2011.
   DOI: 10.1145/1944745.1944761
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "Histogram",
    "adaptive_log_bins",
    "build_histogram",
    "kmeans_bins",
    "log_bins",
    "log_splits",
    "manual_splits",
    "practical_splits",
    "uniform_splits",
]


def uniform_splits(near: float, far: float, k: int) -> np.ndarray:
    """``z_i = n + (f - n) i / k``."""
    i = np.arange(k + 1)
    return near + (far - near) * i / k


#: Log splits need ``n > 0``: a non-positive near distance is raised to this fraction of far.
MIN_LOG_NEAR = 1e-6


def log_splits(near: float, far: float, k: int) -> np.ndarray:
    """``z_i = n (f / n)^(i / k)`` (the Intel sample's ``LogPartitionFromRange``)."""
    i = np.arange(k + 1)
    n = max(near, MIN_LOG_NEAR * far)
    z = n * (far / n) ** (i / k)
    z[0], z[-1] = near, far
    return z


def practical_splits(near: float, far: float, k: int, lam: float) -> np.ndarray:
    """``C_i = lambda n (f/n)^(i/k) + (1 - lambda)(n + (f - n) i/k)`` (PSSM)."""
    z = lam * log_splits(near, far, k) + (1.0 - lam) * uniform_splits(near, far, k)
    z[0], z[-1] = near, far
    return z


def manual_splits(near: float, far: float, fractions) -> np.ndarray:
    """MJP's manual splits: ``z_i = n + s_i (f - n)`` for the end ``s_i`` of each cascade."""
    s = np.asarray(fractions, dtype=np.float64)
    return np.concatenate([[near], near + s * (far - near)])


# ---------------------------------------------------------------------- histogram schemes
class Histogram:
    """The Intel sample's depth histogram: ``bins`` bins warped by ``power``.

    ``bin(z) = floor(((z - n) / (f - n))^(1 / power) * bins)``; ``z(bin) = n + (f - n) *
    (bin / bins)^power``. Each bin holds the sample count and the light-space bounds of its
    samples (``lo``, ``hi``: ``(bins, 3)``, empty bins ``+inf / -inf``).
    """

    def __init__(self, near: float, far: float, bins: int, power: float):
        self.near, self.far, self.bins, self.power = float(near), float(far), int(bins), power
        self.count = np.zeros(self.bins, dtype=np.int64)
        self.lo = np.full((self.bins, 3), np.inf)
        self.hi = np.full((self.bins, 3), -np.inf)

    def z_to_bin(self, z: np.ndarray) -> np.ndarray:
        t = np.clip((np.asarray(z, dtype=np.float64) - self.near) / (self.far - self.near), 0, 1)
        return np.minimum(np.floor(t ** (1.0 / self.power) * self.bins), self.bins - 1).astype(
            np.int64
        )

    def bin_to_z(self, b) -> np.ndarray:
        t = np.asarray(b, dtype=np.float64) / self.bins
        return self.near + (self.far - self.near) * t**self.power


def build_histogram(
    z: np.ndarray, light_coords: np.ndarray, near: float, far: float, bins: int, power: float
) -> Histogram:
    """Scatter samples (view depths ``z``, light-space points ``(N, 3)``) into a histogram."""
    h = Histogram(near, far, bins, power)
    if len(z) == 0:
        return h
    b = h.z_to_bin(z)
    h.count = np.bincount(b, minlength=bins).astype(np.int64)
    for axis in range(3):
        np.minimum.at(h.lo[:, axis], b, light_coords[:, axis])
        np.maximum.at(h.hi[:, axis], b, light_coords[:, axis])
    return h


def _populated(h: Histogram) -> tuple[int, int]:
    nz = np.nonzero(h.count)[0]
    return int(nz[0]), int(nz[-1]) + 1


def log_bins(h: Histogram, k: int) -> np.ndarray:
    """Partition end bins of ``ComputeLogPartitionsFromHistogram`` (length ``k``)."""
    lo, hi = _populated(h)
    zmin, zmax = h.bin_to_z(lo), h.bin_to_z(hi)
    ends = h.z_to_bin(log_splits(float(zmin), float(zmax), k)[1:])
    ends[-1] = h.bins
    return ends


def adaptive_log_bins(h: Histogram, k: int) -> np.ndarray:
    """``ComputeAdaptiveLogPartitions``: log splits of the remaining range, each pushed out
    to the next populated bin, re-planned after every split."""
    lo, hi = _populated(h)
    # empty_step[b]: bins from b to the next populated bin (0 when b is populated).
    populated = h.count > 0
    idx = np.arange(h.bins + 1)
    nxt = np.full(h.bins + 1, h.bins)
    pos = np.nonzero(populated)[0]
    nxt_idx = np.searchsorted(pos, idx)
    has = nxt_idx < len(pos)
    nxt[has] = pos[nxt_idx[has]]
    empty_step = nxt - idx
    zmax = float(h.bin_to_z(hi))
    ends = np.empty(k, dtype=np.int64)
    min_bin = lo
    for i in range(k - 1):
        zmin = float(h.bin_to_z(min_bin))
        target = zmin * (zmax / zmin) ** (1.0 / (k - i))
        b = int(h.z_to_bin(target))
        b = min(b + int(empty_step[min(b, h.bins)]), h.bins)
        ends[i] = b
        min_bin = b
    ends[-1] = h.bins
    return ends


def kmeans_bins(h: Histogram, k: int, iterations: int) -> np.ndarray:
    """``ComputeKMeansPartitions``: Lloyd iterations on bin depths weighted by counts,
    initialised at equal-weight quantiles; splits halfway between centroids."""
    w = h.count.astype(np.float64)
    zc = h.bin_to_z(np.arange(h.bins))
    wsum = np.cumsum(w)
    zsum = np.cumsum(w * zc)
    total = wsum[-1]
    targets = (np.arange(k) + 1) * total / (k + 1)
    centroids = h.bin_to_z(np.searchsorted(wsum, targets, side="right"))
    for _ in range(iterations):
        mids = 0.5 * (centroids[:-1] + centroids[1:])
        edges = np.concatenate([[0], h.z_to_bin(mids), [h.bins]]).astype(np.int64)
        left = edges[:-1] - 1
        right = edges[1:] - 1
        wl = np.where(left >= 0, wsum[np.maximum(left, 0)], 0.0)
        zl = np.where(left >= 0, zsum[np.maximum(left, 0)], 0.0)
        wr = np.where(right >= 0, wsum[np.maximum(right, 0)], 0.0)
        zr = np.where(right >= 0, zsum[np.maximum(right, 0)], 0.0)
        ws, zs = wr - wl, zr - zl
        with np.errstate(invalid="ignore", divide="ignore"):
            centroids = np.where(ws > 0, zs / ws, centroids)
    ends = np.empty(k, dtype=np.int64)
    ends[:-1] = h.z_to_bin(0.5 * (centroids[:-1] + centroids[1:]))
    ends[-1] = h.bins
    return ends
