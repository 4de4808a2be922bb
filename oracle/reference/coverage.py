"""The reference's ``front_coverage``: the coverage of each pixel's front-most primitive.

``coverage`` counts the samples that hit any geometry: 1 everywhere on a scene with a
backdrop, so its metrics say nothing about the anti-aliasing of the silhouettes in front of
it. ``front_coverage`` counts the samples whose nearest surface is the shape seen through the
pixel centre (the sky counting as one): every silhouette, against the sky or another surface,
is an edge of it. The models compute it with the same rule
(:func:`raster_models.aa.common.front_coverage`), so the two compare directly; on silhouettes
against the sky it is the geometry coverage where the centre sees geometry and one minus it
where the centre sees the sky, with the same absolute errors.

The centre's shape is traced once per pixel (exact, no noise), so each sample is a Bernoulli
trial: the estimate's standard error is the binomial one, floored as ``coverage``'s is.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend
from ...scenes.raycast import trace_film_dr

__all__ = ["centre_shapes", "front_hits"]

#: Pixel centres per Dr.Jit launch.
CENTRE_CHUNK = 1 << 22


def centre_shapes(loaded) -> np.ndarray:
    """``(H*W,)`` int32 shape index seen through each pixel centre (-1: sky)."""
    mi = backend.mitsuba()
    import drjit as dr

    w, h = loaded.width, loaded.height
    out = np.empty(w * h, dtype=np.int32)
    for start in range(0, w * h, CENTRE_CHUNK):
        idx = dr.arange(mi.UInt32, start, min(w * h, start + CENTRE_CHUNK))
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(loaded, x, y, color=False, albedo=False)
        out[start : start + dr.width(idx)] = np.array(res["shape"], dtype=np.int32)
    return out


def front_hits(shape, centre: np.ndarray, block: int):
    """Dr.Jit ``1.0`` where a sample's shape (``shape``, Int32, ``block`` consecutive samples
    per pixel) is its pixel's centre shape (``centre``: per pixel of the launch), else 0."""
    mi = backend.mitsuba()
    import drjit as dr

    pixel = dr.arange(mi.UInt32, dr.width(shape)) // block
    same = dr.gather(mi.Int32, mi.Int32(centre), pixel) == shape
    return dr.select(same, 1.0, 0.0)
