"""Sub-pixel jitter sequences of temporal anti-aliasing.

Offsets are in pixels from the pixel centre, x right, y down, in ``[-0.5, 0.5]``: frame ``k``
renders the sample of every pixel at ``centre + jitter[k mod N]``.

- ``halton``: the Halton (2, 3) points ``(h2(i), h3(i)) - 0.5`` for ``i = 1..N`` (index 0,
  the origin, skipped), as Playdead's ``FrustumJitter`` (Halton_2_3_X8/X16), Unity HDRP and
  Filament (``HALTON_23_X8/X16``) do.
- ``ue4-gaussian``: UE4's mapping of the same points to a Gaussian windowed to the pixel
  (``SceneRendering.cpp``, r.TemporalAASamples > 8): ``u1 = h2(i)``, ``u2 = h3(i)``,
  ``sigma = 0.47 * FilterSize`` (FilterSize 1), ``InWindow = exp(-0.5 (0.5 / sigma)^2)``,
  ``r = sigma sqrt(-2 ln((1 - u1) InWindow + u1))``, ``theta = 2 pi u2``, offset
  ``(r cos theta, r sin theta)``: samples concentrate near the centre and never leave
  ``r <= 0.5``.
- ``none``: every frame samples the pixel centre.

References
----------
J. H. Halton, On the efficiency of certain quasi-random sequences of points, Numerische
Mathematik 2, 1960, doi:10.1007/BF01386213.
B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014 Advances in Real-Time Rendering.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["JITTERS", "UE4_SIGMA", "halton", "jitter_offsets"]

JITTERS = ("halton", "ue4-gaussian", "none")
#: UE4's Gaussian standard deviation for r.TemporalAAFilterSize = 1 (pixels).
UE4_SIGMA = 0.47


def halton(index: int, base: int) -> float:
    """The radical inverse of ``index`` in ``base`` (``halton(1, 2) = 0.5``,
    ``halton(2, 3) = 2/3``)."""
    f, r, i = 1.0, 0.0, int(index)
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


def jitter_offsets(kind: str, n: int) -> np.ndarray:
    """``(N, 2)`` float64 jitter offsets (pixels from the centre, x right, y down) of
    sequence ``kind`` (:data:`JITTERS`) with ``n`` samples."""
    if kind not in JITTERS:
        raise ValueError(f"jitter must be one of {', '.join(JITTERS)}, got {kind!r}")
    if kind == "none":
        return np.zeros((max(int(n), 1), 2))
    u = np.array([[halton(i, 2), halton(i, 3)] for i in range(1, int(n) + 1)])
    if kind == "halton":
        return u - 0.5
    window = math.exp(-0.5 * (0.5 / UE4_SIGMA) ** 2)
    r = UE4_SIGMA * np.sqrt(-2.0 * np.log((1.0 - u[:, 0]) * window + u[:, 0]))
    theta = 2.0 * math.pi * u[:, 1]
    return np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)
