"""The ray grids of many coherent-shadow-map projections at once.

:func:`ray_table` gives, for every map, the affine ray description
(:meth:`Projection.grid_rays`) of the orthographic map over the bounding sphere that
:class:`raster_models.coherent.directions.Projections` builds one map at a time
(:func:`make_frame` with the ``world_y`` hint, the ortho :class:`Projection`, its
``grid_rays`` from the near plane). Each step is the same NumPy operation applied to a stack
of maps: element-wise arithmetic and cross products stay element-wise, matrix products and
inverses run per map through NumPy's stacked ``matmul`` / ``inv`` (the same BLAS/LAPACK call
per matrix), and vector norms of all rows at once (``np.linalg.norm(axis=1)``, whose
summation may differ from one vector's by an ulp), so every value equals the
one-map-at-a-time path's within a few ulps (``tests/test_coherent_dr.py``,
``RAY_TABLE_TOL``). Maps whose frame would need another up hint (direction within
``PARALLEL_TOLERANCE`` of +-Y) are built one at a time.
"""

from __future__ import annotations

import numpy as np

from ..light_frame import PARALLEL_TOLERANCE

__all__ = ["TABLE_COLUMNS", "ray_table"]

#: Columns of :func:`ray_table`: ray origin ``A`` at texture (0, 0), texture-space steps
#: ``U`` and ``V`` (world units), unit direction ``D`` and the ray length ``span``.
TABLE_COLUMNS = ("Ax", "Ay", "Az", "Ux", "Uy", "Uz", "Vx", "Vy", "Vz", "Dx", "Dy", "Dz", "span")


def ray_table(projs, ids) -> np.ndarray:
    """``(len(ids), 13)`` float64 ray descriptions of maps ``ids`` (see module docstring and
    :data:`TABLE_COLUMNS`); ``projs``: the maps'
    :class:`~raster_models.coherent.directions.Projections`."""
    ids = np.asarray(ids, dtype=np.int64)
    k = len(ids)
    out = np.zeros((k, 13))
    if k == 0:
        return out
    f = projs.directions[ids]
    f = f / np.linalg.norm(f, axis=1)[:, None]
    up = np.array([0.0, 1.0, 0.0])
    c = np.cross(up[None, :], f)
    c_norm = np.linalg.norm(c, axis=1)
    fast = np.isfinite(c_norm) & (c_norm >= PARALLEL_TOLERANCE)
    for row in np.nonzero(~fast)[0]:  # directions along +-Y: another up hint (rare)
        out[row] = _one_map(projs, int(ids[row]))
    if not np.any(fast):
        return out
    f, c, c_norm = f[fast], c[fast], c_norm[fast]
    x = c / c_norm[:, None]
    y = np.cross(f, x)
    rot = np.stack([x, y, f], axis=1)  # rows x, y, z per map
    origin = np.zeros(3)
    centre = (projs.centre[None, :] - origin)[None, :, :]  # (1, 1, 3)
    cl = np.matmul(centre, rot.transpose(0, 2, 1))[:, 0, :]
    rad = projs.radius
    x0, x1 = cl[:, 0] - rad, cl[:, 0] + rad
    y0, y1 = cl[:, 1] - rad, cl[:, 1] + rad
    z0, z1 = cl[:, 2] - rad, cl[:, 2] + rad
    n = len(f)
    view = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    view[:, :3, :3] = rot
    view[:, :3, 3] = -rot @ origin
    proj = np.zeros((n, 4, 4))
    proj[:, 0, 0] = 1.0 / (x1 - x0)
    proj[:, 0, 3] = -x0 / (x1 - x0)
    proj[:, 1, 1] = -1.0 / (y1 - y0)
    proj[:, 1, 3] = y1 / (y1 - y0)
    proj[:, 2, 2] = 1.0 / (z1 - z0)
    proj[:, 2, 3] = -z0 / (z1 - z0)
    proj[:, 3, 3] = 1.0
    inv = np.linalg.inv(proj @ view)
    a = inv @ np.array([0.0, 0.0, 0.0, 1.0])
    u_vec = inv @ np.array([1.0, 0.0, 0.0, 0.0])
    v_vec = inv @ np.array([0.0, 1.0, 0.0, 0.0])
    zdir = inv @ np.array([0.0, 0.0, 1.0, 0.0])
    depth_axis = zdir[:, :3] / np.linalg.norm(zdir[:, :3], axis=1)[:, None]
    # The rays start on the sphere's near plane: z_start = z0.
    z_start, z_end = z0, z1
    rows = out[fast]
    rows[:, 0:3] = a[:, :3] + depth_axis * (z_start - z0)[:, None]
    rows[:, 3:6] = u_vec[:, :3]
    rows[:, 6:9] = v_vec[:, :3]
    rows[:, 9:12] = depth_axis
    rows[:, 12] = z_end - z_start
    out[fast] = rows
    return out


def _one_map(projs, m: int) -> np.ndarray:
    p = projs[m]
    grid = p.grid_rays(float(p.extent[4]), float(p.extent[5]))
    row = np.empty(13)
    row[0:3], row[3:6], row[6:9], row[9:12] = grid["A"], grid["U"], grid["V"], grid["D"]
    row[12] = grid["z_end"] - grid["z_start"]
    return row
