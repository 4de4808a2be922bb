"""scenes.geometry.tessellation: a shape's triangles against closed forms (an inscribed sphere's
vertices on the sphere, one winding, its volume converging to 4/3 pi r^3 from below; a
Mitsuba rectangle's two triangles on its corners)."""

from __future__ import annotations

import math

import numpy as np
from raster_oracle.scenes import backend
from raster_oracle.scenes.geometry.tessellation import shape_mesh, tessellate_sphere


def _volume(verts: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume of a closed triangle mesh (positive when its faces wind counter-clockwise
    seen from outside)."""
    a, b, c = (verts[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_sphere_is_inscribed_with_one_winding():
    center, radius = np.array([1.0, -2.0, 0.5]), 0.75
    verts, faces = tessellate_sphere(center, radius, n_phi=32, n_theta=16)
    assert verts.shape == (17 * 32, 3) and faces.shape == (2 * 16 * 32, 3)
    assert faces.dtype == np.uint32 and faces.max() < len(verts)
    np.testing.assert_allclose(np.linalg.norm(verts - center, axis=1), radius, rtol=1e-12)
    exact = 4.0 / 3.0 * math.pi * radius**3
    volumes = [
        -_volume(*tessellate_sphere(center, radius, n_phi=n, n_theta=n // 2)) for n in (8, 32, 128)
    ]
    assert all(0.0 < v < exact for v in volumes)  # inscribed; every face wound clockwise
    errors = [exact - v for v in volumes]
    assert errors[0] > errors[1] > errors[2] and errors[2] < 2e-3 * exact
    assert 14.0 < errors[1] / errors[2] < 18.0  # second order: 4x the segments, 1/16 the error


def test_rectangle_is_two_triangles_on_its_corners():
    mi = backend.mitsuba()
    to_world = mi.ScalarTransform4f().translate([0.0, 1.0, 0.0]).scale([2.0, 3.0, 1.0])
    rect = mi.load_dict({"type": "rectangle", "to_world": to_world})
    verts, faces = shape_mesh(mi, rect)
    assert faces.shape == (2, 3)
    expected = {(-2.0, -2.0, 0.0), (2.0, -2.0, 0.0), (2.0, 4.0, 0.0), (-2.0, 4.0, 0.0)}
    assert {tuple(np.round(v, 12)) for v in verts} == expected


def test_a_mesh_keeps_its_own_triangles():
    mi = backend.mitsuba()
    verts, faces = shape_mesh(mi, mi.load_dict({"type": "cube"}))
    assert faces.shape == (12, 3)
    np.testing.assert_array_equal(np.abs(verts), 1.0)  # the unit cube's corners, in [-1, 1]^3
