"""A Mitsuba triangle mesh with texture coordinates from NumPy arrays (the alpha-tested
cards of the studies and tests; scenes themselves load through :mod:`scenes.loader`)."""

from __future__ import annotations

import numpy as np

__all__ = ["QUAD_FACES", "uv_mesh"]

#: The two triangles of a quad whose corners are listed around it.
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)


def uv_mesh(mi, name: str, vertices, faces, uvs, *, bsdf=None):
    """A ``mitsuba.Mesh`` of ``vertices`` (V, 3), ``faces`` (F, 3) and texture coordinates
    ``uvs`` (V, 2), stored as float32 / uint32; ``bsdf``: a Mitsuba BSDF object for it
    (default: Mitsuba's diffuse)."""
    v = np.asarray(vertices, np.float32).reshape(-1, 3)
    f = np.asarray(faces, np.uint32).reshape(-1, 3)
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    mesh = mi.Mesh(name, len(v), len(f), props, has_vertex_texcoords=True)
    p = mi.traverse(mesh)
    p["vertex_positions"] = v.ravel()
    p["faces"] = f.ravel()
    p["vertex_texcoords"] = np.asarray(uvs, np.float32).ravel()
    p.update()
    return mesh
