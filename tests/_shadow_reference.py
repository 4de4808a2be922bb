"""NumPy references of the shadow-map Dr.Jit kernels, used only by the tests."""

from __future__ import annotations

import numpy as np

__all__ = ["projection_derivative"]


def projection_derivative(proj, u, v, z, w) -> np.ndarray:
    """``d(u, v, z) / dP`` of a :class:`raster_models.light_frame.Projection` at world points:
    ``(N, 3, 3)`` (rows u, v, z), float64, from the points' projected ``(u, v, z, w)``: the
    reference of the shading-geometry kernel."""
    m = proj.matrix
    t = np.stack([u, v, z], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (m[None, :3, :3] - t[:, :, None] * m[None, 3:4, :3]) / w[:, None, None]
