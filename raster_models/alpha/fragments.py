"""What a rasterizer's fragment shader sees of an alpha-tested triangle: its attributes at the
pixel centre and at the neighbouring pixel centres of the 2 x 2 quad, extrapolated on the
triangle's plane (helper lanes), which give the screen derivatives of the texture
coordinates (the mip level) and of the alpha (``fwidth``); the vertex alpha (glTF
``COLOR_0``) is interpolated the same way.

Triangles are read from the Mitsuba meshes themselves (``vertex_positions``, ``faces``,
``vertex_texcoords``, the vertex alpha attribute), so the model and the truth share one
geometry.
"""

from __future__ import annotations

import numpy as np

from ...scenes.shading.alpha import ALPHA_ATTRIBUTE

__all__ = ["MeshTable", "plane_attributes"]


class MeshTable:
    """Vertex positions, faces, texture coordinates and vertex alphas
    (:data:`scenes.shading.alpha.ALPHA_ATTRIBUTE`, glTF ``COLOR_0``'s alpha) of a Mitsuba
    scene's meshes, by shape index (``shapes()`` order); a shape without texture coordinates
    gets zeros, one without vertex alpha ones. The texture coordinates carry the vertex
    alpha as a third column, interpolated with them."""

    def __init__(self, mi, shapes):
        self.positions, self.faces, self.uvs = [], [], []
        for shape in shapes:  # a scene's shapes, not its triangles
            if not shape.is_mesh():
                self.positions.append(None)
                self.faces.append(None)
                self.uvs.append(None)
                continue
            p = mi.traverse(shape)
            keys = set(p.keys())
            v = np.asarray(p["vertex_positions"], np.float64).reshape(-1, 3)
            f = np.asarray(p["faces"], np.int64).reshape(-1, 3)
            uva = np.ones((len(v), 3))
            uva[:, :2] = 0.0
            # a mesh without texture coordinates lists an empty array under their key
            uv = np.asarray(p["vertex_texcoords"] if "vertex_texcoords" in keys else [])
            if uv.size == 2 * len(v):
                uva[:, :2] = uv.astype(np.float64).reshape(-1, 2)
            va = np.asarray(p[ALPHA_ATTRIBUTE] if ALPHA_ATTRIBUTE in keys else [])
            if va.size == len(v):
                uva[:, 2] = va.astype(np.float64).ravel()
            self.positions.append(v)
            self.faces.append(f)
            self.uvs.append(uva)

    def triangles(self, shape: np.ndarray, prim: np.ndarray):
        """``(P (N, 3, 3), UVA (N, 3, 3))`` of triangles ``prim`` of shapes ``shape``: the
        vertices' positions and their texture coordinates with the vertex alpha."""
        n = len(shape)
        tri_p = np.zeros((n, 3, 3))
        tri_uv = np.ones((n, 3, 3))
        for s in np.unique(shape):  # shapes, not triangles
            if s < 0 or self.faces[s] is None:
                continue
            sel = shape == s
            f = self.faces[s][prim[sel]]
            tri_p[sel] = self.positions[s][f]
            tri_uv[sel] = self.uvs[s][f]
        return tri_p, tri_uv


def plane_attributes(tri_p, tri_uv, o, d):
    """Position and texture coordinates where rays ``o + t d`` ((N, 3)) meet the planes of
    triangles ``tri_p`` ((N, 3, 3)), extrapolated beyond the triangle as a rasterizer's
    attribute interpolation is: ``(p (N, 3), uv (N, K))`` (``K``: the columns of
    ``tri_uv``, texture coordinates and vertex alpha from :class:`MeshTable`); a ray
    parallel to its plane gets the triangle's first vertex."""
    p0, p1, p2 = tri_p[:, 0], tri_p[:, 1], tri_p[:, 2]
    e1, e2 = p1 - p0, p2 - p0
    n = np.cross(e1, e2)
    denom = np.einsum("ij,ij->i", d, n)
    ok = np.abs(denom) > 1e-300
    t = np.einsum("ij,ij->i", p0 - o, n) / np.where(ok, denom, 1.0)
    p = np.where(ok[:, None], o + t[:, None] * d, p0)
    # barycentrics of p in the triangle's plane
    w = p - p0
    d00, d01, d11 = (np.einsum("ij,ij->i", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
    d20, d21 = np.einsum("ij,ij->i", w, e1), np.einsum("ij,ij->i", w, e2)
    det = d00 * d11 - d01 * d01
    det = np.where(np.abs(det) > 0, det, 1.0)
    b1 = (d11 * d20 - d01 * d21) / det
    b2 = (d00 * d21 - d01 * d20) / det
    b0 = 1.0 - b1 - b2
    uv = b0[:, None] * tri_uv[:, 0] + b1[:, None] * tri_uv[:, 1] + b2[:, None] * tri_uv[:, 2]
    return p, uv
