"""The 32 fixed sub-pixel points of frustum-traced IZB shadows, on the tangent plane.

FTIZB (Wyman, Hoetzlein, Lefohn 2015) tests 32 fixed points of each pixel's footprint on the
tangent plane of the visible surface, ``P + a dP/dx + b dP/dy``, and keeps a 32-bit mask
(the paper's table is "developer specified (currently a lookup table)" and not published).
Both the ``izb`` model and the oracle's ``visibility_tangent32`` reference read the table and
the derivatives from here, so the model and its reference test the same points.

The table (:data:`TANGENT_POINTS_32`) is the 32-point Hammersley set in base 2 with cell
centres, ``x_k = (k + 1/2) / 32``, ``y_k = phi_2(k) + 1/64`` (``phi_2``: the base-2 radical
inverse): one point in each of the 32 columns and 32 rows of the pixel, and one in each
elementary 2^-i x 2^-(5-i) box (a (0, 5, 2)-net). Coordinates follow the package's sub-pixel
convention: ``[0, 1)^2`` from the pixel's upper-left corner, y down; the offsets on the
tangent plane are ``a = x - 1/2``, ``b = y - 1/2`` pixels.

References
----------
.. [1] C. Wyman, R. Hoetzlein, A. Lefohn, "Frustum-Traced Raster Shadows: Revisiting
   Irregular Z-Buffers", I3D 2015. DOI: 10.1145/2699276.2699282
.. [2] J. M. Hammersley, D. C. Handscomb, "Monte Carlo Methods", 1964 (the point set).
"""

from __future__ import annotations

import numpy as np

__all__ = ["TANGENT_POINTS_32", "tangent_derivatives_dr", "tangent_offsets"]


def _hammersley(n_bits: int) -> np.ndarray:
    n = 1 << n_bits
    k = np.arange(n)
    rev = np.zeros(n, dtype=np.int64)
    for bit in range(n_bits):  # bits of the index, not a loop over samples
        rev |= ((k >> bit) & 1) << (n_bits - 1 - bit)
    return np.stack([(k + 0.5) / n, (rev + 0.5) / n], axis=1)


#: ``(32, 2)`` float64: FTIZB's sub-pixel points, ``[0, 1)^2`` from the upper-left, y down.
TANGENT_POINTS_32 = _hammersley(5)
TANGENT_POINTS_32.setflags(write=False)


def tangent_offsets() -> tuple[np.ndarray, np.ndarray]:
    """``(a, b)``: the 32 points as offsets from the pixel centre, in pixels (x right, y down)."""
    return TANGENT_POINTS_32[:, 0] - 0.5, TANGENT_POINTS_32[:, 1] - 0.5


def tangent_derivatives_dr(camera, x, y, p, n):
    """``dP/dx``, ``dP/dy`` (world units per pixel, Dr.Jit ``Vector3f``) of the visible point.

    Exact on the tangent plane of the surface at ``p`` (normal ``n``) by ray differentials:
    the intersection of the rays through film positions ``(x + dx, y + dy)`` with that plane,
    differentiated (what a GPU's ``ddx``/``ddy`` of the interpolated position gives on a
    planar triangle). ``x, y``: Dr.Jit ``Float`` film positions in pixels.
    """
    from .. import backend

    mi = backend.mitsuba()
    import drjit as dr

    m = np.asarray(camera.to_world, dtype=np.float64)
    rot = m[:3, :3]
    dd_x, dd_y, do_x, do_y = camera.film_derivatives()

    def vec(a):
        return mi.Vector3f(*(dr.opaque(mi.Float, float(a[k])) for k in range(3)))

    (ox, oy, oz), (dx, dy, dz) = camera.local_ray(x, y)
    r = [[dr.opaque(mi.Float, float(rot[i, j])) for j in range(3)] for i in range(3)]

    def to_world(v):
        return mi.Vector3f(
            r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z,
            r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
            r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z,
        )

    d = to_world(mi.Vector3f(dx, dy, dz))
    o = to_world(mi.Vector3f(ox, oy, oz)) + vec(m[:3, 3])
    nd = dr.dot(n, d)
    nd = dr.select(dr.abs(nd) > 1e-12, nd, 1e-12)
    tau = dr.dot(n, p - o) / nd
    out = []
    for do, dd in ((do_x, dd_x), (do_y, dd_y)):
        do_v, dd_v = vec(do), vec(dd)
        dtau = -(dr.dot(n, do_v) + tau * dr.dot(n, dd_v)) / nd
        out.append(do_v + d * dtau + dd_v * tau)
    return out[0], out[1]
