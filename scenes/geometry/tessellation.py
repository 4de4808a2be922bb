"""Tessellation of a Mitsuba scene's shapes: world-space triangles of every shape kind.

:func:`shape_mesh` gives a shape's triangles: a mesh's own, a rectangle's two, and analytic
spheres, cylinders and disks tessellated finely (512 x 256 and 512 segments), as ``export``
writes them and as exact coverage (:mod:`.exact_coverage`) starts from;
:func:`tessellate_sphere` is the sphere's latitude-longitude grid at any resolution.
"""

from __future__ import annotations

import numpy as np

from . import meshes

__all__ = ["shape_mesh", "tessellate_sphere"]


def tessellate_sphere(center, radius, n_phi=512, n_theta=256) -> tuple[np.ndarray, np.ndarray]:
    """A sphere as ``n_theta`` rings of ``n_phi`` segments: vertices on the sphere (poles
    repeated per segment) and faces (F, 3) wound clockwise seen from outside (the mesh's
    signed volume is negative; consumers take the triangles two-sided)."""
    theta = np.linspace(0, np.pi, n_theta + 1)
    phi = np.linspace(0, 2 * np.pi, n_phi, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    pts = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1)
    verts = (np.asarray(center) + radius * pts).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_phi), indexing="ij")
    a = i * n_phi + j
    b = i * n_phi + (j + 1) % n_phi
    c = a + n_phi
    d = b + n_phi
    faces = np.concatenate(
        [np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)]
    )
    return verts, faces.astype(np.uint32)


def shape_mesh(mi, shape) -> tuple[np.ndarray, np.ndarray]:
    """World-space triangles (vertices (V, 3) float64, faces (F, 3)) of a Mitsuba shape."""
    params = mi.traverse(shape)
    keys = set(params.keys())
    if "vertex_positions" in keys:
        v = np.array(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
        f = np.array(params["faces"], dtype=np.uint32).reshape(-1, 3)
        return v, f
    kind = shape.class_name()
    m = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    if kind == "Sphere":
        radius = float(np.linalg.norm(m[:3, 0]))
        return tessellate_sphere(m[:3, 3], radius)
    if kind == "Cylinder":
        p0 = m[:3, 3]
        p1 = m[:3, 3] + m[:3, 2]
        radius = float(np.linalg.norm(m[:3, 0]))
        return meshes.tube(p0, p1, radius, sides=512)
    if kind == "Rectangle":
        corners = np.array([[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1]]) @ m.T
        return meshes.quad(corners[:, :3])
    if kind == "Disk":
        ang = np.linspace(0, 2 * np.pi, 512, endpoint=False)
        ring = np.stack([np.cos(ang), np.sin(ang), 0 * ang, 1 + 0 * ang], -1) @ m.T
        verts = np.concatenate([m[None, :3, 3], ring[:, :3]])
        k = np.arange(512)
        faces = np.stack([np.zeros(512), 1 + k, 1 + (k + 1) % 512], -1).astype(np.uint32)
        return verts, faces
    raise ValueError(f"shape {shape.id()!r} of type {kind} cannot be exported as a mesh")
