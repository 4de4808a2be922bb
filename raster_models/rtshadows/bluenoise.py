"""A 128 x 128 blue-noise tile made by void and cluster (Ulichney 1993), vectorised.

AMD's hybrid-shadows sample reads a 128 x 128 RGBA8 blue-noise texture (its ``rg`` channels
pick the ray on the sun's cone, :mod:`.rays`). That sample ships Heitz et al.'s
"samplerBlueNoiseErrorDistribution" tables; this project generates its own tile instead, so
no third-party data is committed: each channel is a rank image of Ulichney's void-and-cluster
method on the torus with a Gaussian energy filter of ``sigma = 1.5`` pixels (the paper's
value), started from :data:`INITIAL_FRACTION` of the pixels chosen by a seeded
``numpy.random.Generator(PCG64(seed))``. The ``r`` channel uses ``SEED``, ``g`` uses
``SEED + 1``; both are ranks ``0..N-1`` mapped to ``(rank + 0.5) / N``, so each value occurs
once (a uniform histogram) and the low spatial frequencies are nearly empty (the spectrum test
in tests/test_rtshadows_rays.py).

The method takes about 2 s a process, so the package ships its output: ``bluenoise_ranks.u16``
holds both channels' ranks (``(128, 128, 2)`` little-endian uint16, row-major, SHA-256
:data:`RANKS_SHA256`), made by this module's :func:`void_and_cluster`; the tests regenerate it
and compare it with the file byte for byte, so the file is this module's output, not data of
its own.

References
----------
R. Ulichney, The void-and-cluster method for dither array generation, Proc. SPIE 1913,
Human Vision, Visual Processing, and Digital Display IV, 1993, doi:10.1117/12.152707.
E. Heitz, L. Belcour, V. Ostromoukhov, D. Coeurjolly, J.-C. Iehl, A Low-Discrepancy Sampler
that Distributes Monte Carlo Errors as a Blue Noise in Screen Space, SIGGRAPH Talks 2019.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

import numpy as np

__all__ = [
    "INITIAL_FRACTION",
    "RANKS_FILE",
    "RANKS_SHA256",
    "SEED",
    "SIGMA",
    "TILE",
    "blue_noise_tile",
    "tile_ranks",
    "void_and_cluster",
]

#: Tile size of AMD's sample (``t2d_blueNoise[pixelCoord % 128]``).
TILE = 128
#: Seed of the ``r`` channel (``g`` is ``SEED + 1``).
SEED = 46
#: Ulichney's Gaussian energy filter width (pixels).
SIGMA = 1.5
#: Fraction of pixels in the initial binary pattern (Ulichney: at most half; 10 % is usual).
INITIAL_FRACTION = 0.1
#: The shipped ranks of both channels (package data): :func:`void_and_cluster`'s output.
RANKS_FILE = Path(__file__).with_name("bluenoise_ranks.u16")
#: SHA-256 of :data:`RANKS_FILE`.
RANKS_SHA256 = "707945d1a2a78c8cc7d8588febacd0e28d55733e4486b7db91e3490753d4c38f"


def _energy_kernel(n: int, sigma: float) -> np.ndarray:
    """Toroidal Gaussian ``exp(-r^2 / (2 sigma^2))`` centred on pixel (0, 0), ``(n, n)``."""
    d = np.minimum(np.arange(n), n - np.arange(n)).astype(np.float64)
    g = np.exp(-(d**2) / (2.0 * sigma**2))
    return np.outer(g, g)


def _rolled(kernel: np.ndarray, flat_index: int) -> np.ndarray:
    n = kernel.shape[0]
    return np.roll(kernel, (flat_index // n, flat_index % n), axis=(0, 1))


def void_and_cluster(n: int = TILE, *, seed: int = SEED, sigma: float = SIGMA) -> np.ndarray:
    """Rank image ``(n, n)`` int64 of the void-and-cluster method (values ``0..n*n-1``).

    Phase 0 makes the initial pattern "prototype" by moving the tightest cluster's pixel to
    the largest void until that is the same pixel; phase 1 removes pixels of the initial
    pattern tightest cluster first (ranks below the initial count); phases 2 and 3 add pixels
    largest void first. Energies are updated by adding or subtracting a rolled Gaussian (one
    ``(n, n)`` array operation a pixel, no per-pixel Python work inside it).
    """
    rng = np.random.Generator(np.random.PCG64(seed))
    size = n * n
    kernel = _energy_kernel(n, sigma)
    ones = np.zeros(size, dtype=bool)
    ones[rng.choice(size, size=max(1, int(INITIAL_FRACTION * size)), replace=False)] = True
    energy = np.real(
        np.fft.ifft2(np.fft.fft2(ones.reshape(n, n).astype(np.float64)) * np.fft.fft2(kernel))
    ).ravel()
    for _ in range(size):  # phase 0: relax the initial pattern (terminates far earlier)
        cluster = int(np.argmax(np.where(ones, energy, -np.inf)))
        ones[cluster] = False
        energy -= _rolled(kernel, cluster).ravel()
        void = int(np.argmin(np.where(ones, np.inf, energy)))
        ones[void] = True
        energy += _rolled(kernel, void).ravel()
        if void == cluster:
            break
    rank = np.empty(size, dtype=np.int64)
    start = int(ones.sum())
    pattern, e = ones.copy(), energy.copy()
    for r in range(start - 1, -1, -1):  # phase 1: tightest cluster first
        cluster = int(np.argmax(np.where(pattern, e, -np.inf)))
        pattern[cluster] = False
        e -= _rolled(kernel, cluster).ravel()
        rank[cluster] = r
    for r in range(start, size):  # phases 2 and 3: largest void first
        void = int(np.argmin(np.where(ones, np.inf, energy)))
        ones[void] = True
        energy += _rolled(kernel, void).ravel()
        rank[void] = r
    return rank.reshape(n, n)


def tile_ranks() -> np.ndarray:
    """``(128, 128, 2)`` int64 ranks of both channels from :data:`RANKS_FILE` (checked against
    :data:`RANKS_SHA256`: a changed file is an error, never a different tile)."""
    raw = RANKS_FILE.read_bytes()
    if hashlib.sha256(raw).hexdigest() != RANKS_SHA256:
        raise RuntimeError(f"{RANKS_FILE.name}: not the shipped blue-noise ranks (checksum)")
    return np.frombuffer(raw, dtype="<u2").reshape(TILE, TILE, 2).astype(np.int64)


@lru_cache(maxsize=1)
def blue_noise_tile() -> np.ndarray:
    """``(128, 128, 2)`` float32 tile, values ``(rank + 0.5) / 16384`` per channel (``r``:
    :data:`SEED`, ``g``: ``SEED + 1``), row = pixel y modulo 128, column = x modulo 128;
    the ranks are the shipped :func:`tile_ranks` (the void-and-cluster output)."""
    out = (tile_ranks().astype(np.float64) + 0.5) / float(TILE * TILE)
    out = out.astype(np.float32)
    out.setflags(write=False)
    return out
