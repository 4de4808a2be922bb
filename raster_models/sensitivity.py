"""Pixels whose visible surface a rasterizer may see differently from the model: the model's
own sub-pixel sensitivity.

The models (and the oracle) see, at each pixel centre, the surface a float64-accurate ray
through it hits. An engine's rasterizer decides coverage with its own fixed-point edge
functions, snaps vertices to its sub-pixel grid and interpolates its own depth: at a pixel
where another surface is a fraction of a pixel away (a silhouette, a one-pixel grass blade),
the engine may shade the other surface, correctly. Such pixels are *implementation-defined*
for conformance: a shadow lookup there answers for another surface.

:func:`surface_sensitivity` flags them without an engine layer: the pixel is traced again at
the four points ``(+-offset, +-offset)`` pixels from its centre (:data:`DEFAULT_OFFSET`);
where one of them misses the centre's plane (its hit lies off the plane
``p + dP/dx dx + dP/dy dy`` by more than :data:`PLANE_TOLERANCE` of the distance, or hits
another shape, or the sky differs), the pixel is sensitive. Flat surfaces seen head-on or
at grazing angles are not flagged.
"""

from __future__ import annotations

import numpy as np

from ..scenes.backend.raycast import trace_film
from .gbuffer import trace_gbuffer

__all__ = ["DEFAULT_OFFSET", "PLANE_TOLERANCE", "probe_hits", "surface_sensitivity"]

#: Sub-pixel distance (pixels) of the four probes: 1/64 pixel, four times the step of the
#: 8-bit sub-pixel grid D3D11 rasterizers snap vertices to (1/256), which covers an engine's
#: float32 vertex transform too. (A quarter pixel flags a third of a 100k-blade meadow.)
DEFAULT_OFFSET = 1.0 / 64.0
#: Relative distance off the centre's plane that counts as another surface.
PLANE_TOLERANCE = 1e-3


def probe_hits(scene, gbuf, *, offset: float = DEFAULT_OFFSET):
    """For each of the four probes ``(dx, dy)`` (``+-offset`` pixels): ``(dx, dy, hit,
    other)``: the probe's hit record (:func:`scenes.backend.raycast.trace_film`: ``valid``,
    ``position``, ``normal``, ``depth``, ``shape``, flat, row-major) and the flat bool mask
    of pixels where it sees another surface than the centre's plane (see module)."""
    w, h = gbuf.width, gbuf.height
    idx = np.arange(w * h)
    cx, cy = idx % w + 0.5, idx // w + 0.5
    pos = np.asarray(gbuf.position, dtype=np.float64)
    dpdx = np.asarray(gbuf.dpdx, dtype=np.float64)
    dpdy = np.asarray(gbuf.dpdy, dtype=np.float64)
    valid = np.asarray(gbuf.valid, dtype=bool)
    dist = np.asarray(gbuf.depth, dtype=np.float64)
    shape = None if gbuf.shape is None else np.asarray(gbuf.shape)
    for dx, dy in ((-offset, -offset), (offset, -offset), (-offset, offset), (offset, offset)):
        hit = trace_film(scene, cx + dx, cy + dy)
        hv = np.asarray(hit["valid"], dtype=bool)
        other = hv != valid
        both = hv & valid
        if shape is not None:
            other |= both & (np.asarray(hit["shape"]) != shape)
        predicted = pos + dpdx * dx + dpdy * dy
        off = np.linalg.norm(np.asarray(hit["position"], np.float64) - predicted, axis=1)
        other |= both & (off > PLANE_TOLERANCE * dist)
        yield dx, dy, hit, other


def surface_sensitivity(scene, *, offset: float = DEFAULT_OFFSET, gbuf=None) -> np.ndarray:
    """``(H, W)`` bool: pixels where a probe ``offset`` pixels from the centre (in each
    diagonal direction) sees another surface than the centre's plane (see module)."""
    gbuf = gbuf or trace_gbuffer(scene)
    flagged = np.zeros(gbuf.width * gbuf.height, dtype=bool)
    for _, _, _, other in probe_hits(scene, gbuf, offset=offset):
        flagged |= other
    return flagged.reshape(gbuf.height, gbuf.width)
