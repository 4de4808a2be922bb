"""Camera frustum slices in world space, the way engines compute them.

The corners of the view frustum are the NDC cube's corners (``x, y = +-1``, D3D ``z = 0, 1``)
transformed by an inverse camera matrix; a slice ``[z_a, z_b]`` of view depth interpolates
linearly along each corner ray (MJP's ``frustumCornersWS[i] + cornerRay * splitDist``).

``precision="float32"`` builds the view and projection matrices in float32 and does every
step in float32, as engines do. ``inverse="combined"`` inverts ``projection @ view`` as one
float32 matrix, which is ill-conditioned when far/near is large: the corners then wander by
more than the 1/16-unit rounding of stabilized cascades and the cascades shimmer
(TheRealMJP/Shadows issue #6 at far >= 1000; Falcor PR #330). ``"separate"`` inverts the
rigid view matrix and the projection separately.
"""

from __future__ import annotations

import numpy as np

__all__ = ["NDC_CORNERS", "frustum_slice"]

#: NDC corners: near plane (z = 0) then far plane (z = 1), same (x, y) order.
NDC_CORNERS = np.array(
    [
        [-1.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [1.0, -1.0, 0.0],
        [-1.0, -1.0, 0.0],
        [-1.0, 1.0, 1.0],
        [1.0, 1.0, 1.0],
        [1.0, -1.0, 1.0],
        [-1.0, -1.0, 1.0],
    ]
)


def _inverse_view_projection(camera, dtype, inverse: str) -> np.ndarray:
    view = camera.world_to_view("direct3d").astype(dtype)
    proj = camera.projection("direct3d").astype(dtype)
    if inverse == "combined":
        return np.linalg.inv((proj @ view).astype(dtype)).astype(dtype)
    inv_view = np.linalg.inv(view).astype(dtype)
    inv_proj = np.linalg.inv(proj).astype(dtype)
    return (inv_view @ inv_proj).astype(dtype)


def frustum_slice(
    camera, z_a: float, z_b: float, *, precision: str = "float64", inverse: str = "separate"
) -> np.ndarray:
    """World-space corners ``(8, 3)`` of the view-depth slice ``[z_a, z_b]`` (first the four
    corners at ``z_a``). Computed in ``precision``; returned in that dtype."""
    dtype = np.float32 if precision == "float32" else np.float64
    inv = _inverse_view_projection(camera, dtype, inverse)
    h = np.concatenate([NDC_CORNERS, np.ones((8, 1))], axis=1).astype(dtype)
    p = h @ inv.T
    world = (p[:, :3] / p[:, 3:4]).astype(dtype)
    near, far = camera.near, camera.far
    span = dtype(far - near)
    a = dtype(z_a - near) / span
    b = dtype(z_b - near) / span
    ray = world[4:] - world[:4]
    out = np.empty((8, 3), dtype=dtype)
    out[:4] = world[:4] + ray * a
    out[4:] = world[:4] + ray * b
    return out
