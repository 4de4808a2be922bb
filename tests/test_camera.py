"""Our float64 camera against Mitsuba's sensors, and the exported matrices."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.scenes.camera import look_at

from raster_oracle import scenes

# float32 rays from Mitsuba against float64 ones: agreement to ~1e-6 relative
RAY_TOL = 2e-5


def _mitsuba_rays(mi, sensor, x, y, w, h):
    ray, _ = sensor.sample_ray(
        0.0, 0.5, mi.Point2f(mi.Float(x / w), mi.Float(y / h)), mi.Point2f(0.5, 0.5)
    )
    n = len(x)
    o = np.broadcast_to(np.array(ray.o).T, (n, 3))
    d = np.broadcast_to(np.array(ray.d).T, (n, 3))
    return o, d, np.broadcast_to(np.array(ray.maxt), (n,))


@pytest.mark.parametrize("kind", ["perspective", "orthographic"])
def test_rays_match_mitsuba_sensor(mi, kind):
    w, h = 64, 40
    to_world = look_at((1, 3, -4), (0.2, 0, 0.5), (0, 1, 0))
    if kind == "orthographic":
        to_world = to_world @ np.diag([2.0, 2.0, 1.0, 1.0])
    d = {
        "type": kind,
        "near_clip": 0.3,
        "far_clip": 50.0,
        "to_world": mi.ScalarTransform4f(to_world.tolist()),
        "film": {"type": "hdrfilm", "width": w, "height": h},
    }
    if kind == "perspective":
        d["fov"] = 47.0
    sensor = mi.load_dict(d)
    cam = scenes.Camera(kind, to_world, w, h, 0.3, 50.0, 47.0)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0, w, 200), rng.uniform(0, h, 200)
    o_ref, d_ref, t_ref = _mitsuba_rays(mi, sensor, x, y, w, h)
    o, dd, t = cam.rays(x, y)
    np.testing.assert_allclose(dd, d_ref, atol=RAY_TOL)
    np.testing.assert_allclose(o, o_ref, atol=RAY_TOL * 10)
    np.testing.assert_allclose(t, t_ref, rtol=RAY_TOL)


def test_project_inverts_rays():
    cam = scenes.load("plate").camera
    rng = np.random.default_rng(2)
    x, y = rng.uniform(0, cam.width, 50), rng.uniform(0, cam.height, 50)
    o, d, _ = cam.rays(x, y)
    pts = o + d * 5.0
    np.testing.assert_allclose(cam.project(pts), np.stack([x, y], 1), atol=1e-9)


@pytest.mark.parametrize("convention", ["opengl", "direct3d"])
def test_exported_matrices_project_like_the_camera(convention):
    cam = scenes.load("city", width=200, height=100).camera
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, cam.width, 20), rng.uniform(0, cam.height, 20)
    o, d, _ = cam.rays(x, y)
    pts = o + d * rng.uniform(1, 100, (20, 1))
    clip = (
        cam.projection(convention) @ cam.world_to_view(convention) @ np.c_[pts, np.ones(20)].T
    ).T
    ndc = clip[:, :3] / clip[:, 3:]
    film_x = (ndc[:, 0] + 1) / 2 * cam.width
    film_y = (1 - ndc[:, 1]) / 2 * cam.height
    np.testing.assert_allclose(np.c_[film_x, film_y], np.c_[x, y], atol=1e-5)
    depth = cam.view_depth(pts)
    z_lo = -1.0 if convention == "opengl" else 0.0
    assert np.all((ndc[:, 2] > z_lo) & (ndc[:, 2] < 1))
    # NDC depth is monotone in view depth
    order = np.argsort(depth)
    assert np.all(np.diff(ndc[order, 2]) > 0)
