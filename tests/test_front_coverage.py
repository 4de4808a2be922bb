"""Coverage of the front-most primitive: a straight edge of a quad in front of a backdrop.

Plain coverage (samples on any geometry) is 1 on every pixel of such a scene; the front-most
primitive's coverage is the area of each pixel on the side of the edge its centre is on (the
quad's or the backdrop's): a closed form for a straight edge. The reference must match it
within its standard error, and each model must match the count of its own sample positions on
that side exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.raster_models.aa import samples as aa_samples
from raster_oracle.scenes.catalogue.aa_scenes import ortho_camera
from raster_oracle.scenes.catalogue.builtin import BuiltinScene
from raster_oracle.scenes.catalogue.factories import mesh, sun
from raster_oracle.scenes.geometry import meshes

from raster_oracle import raster_models as rm
from raster_oracle import scenes

W, H = 48, 27
#: The quad's left edge: from (X0, -3) to (X1, 3) in world units (about 11 degrees off the
#: vertical: no pixel column is aligned with it).
X0, X1 = -0.7123, 0.4871


def _factory(width, height):
    edge = [[X0, -3.0, 0.0], [X1, 3.0, 0.0], [6.0, 3.0, 0.0], [6.0, -3.0, 0.0]]
    back = [[-8.0, -5.0, 1.0], [8.0, -5.0, 1.0], [8.0, 5.0, 1.0], [-8.0, 5.0, 1.0]]
    return {
        "type": "scene",
        "camera": ortho_camera(width, height, 4.0),
        "sun": sun((0.1, -0.2, 1.0)),
        "front": mesh(meshes.quad(np.array(edge)), (0.8, 0.5, 0.2)),
        "backdrop": mesh(meshes.quad(np.array(back)), (0.2, 0.3, 0.6)),
    }


@pytest.fixture(scope="module")
def scene():
    return scenes.load(BuiltinScene("edge-on-backdrop", _factory, "test", W, H))


def _front_area(scene) -> np.ndarray:
    """Per pixel, the area on the side of the edge its centre lies on (x of the edge is
    linear in film y: integrated over 4,096 rows of the pixel, exact to 1e-4)."""
    a, b = scene.camera.project(np.array([[X0, -3.0, 0.0], [X1, 3.0, 0.0]]))
    ys = np.arange(H)[:, None] + (np.arange(4096) + 0.5) / 4096  # (H, 4096)
    x_edge = a[0] + (ys - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    cols = np.arange(W)[None, :, None]
    # fraction of each pixel row on the edge's larger-x side
    right = np.clip(cols + 1 - x_edge[:, None, :], 0.0, 1.0).mean(axis=2)  # (H, W)
    front_is_right = _side_of_quad(scene, a, b)
    quad_area = right if front_is_right else 1.0 - right
    yc = np.arange(H)[:, None] + 0.5
    xc_edge = a[0] + (yc - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    centre_right = (np.arange(W)[None, :] + 0.5) > xc_edge
    centre_on_quad = centre_right if front_is_right else ~centre_right
    return np.where(centre_on_quad, quad_area, 1.0 - quad_area)


def _side_of_quad(scene, a, b) -> bool:
    """Whether the quad (x > the edge in world) lies at larger film x than its edge."""
    inside = scene.camera.project(np.array([[5.0, 0.0, 0.0]]))[0]
    x_at = a[0] + (inside[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    return bool(inside[0] > x_at)


def test_reference_front_coverage_is_the_area_on_the_centre_side(scene):
    ch, _ = render_reference(scene, ReferenceSettings(spp=64, channels=("coverage",)), quiet=True)
    assert (ch["coverage"] == 1.0).all()  # geometry everywhere: no edge in plain coverage
    truth = _front_area(scene)
    edge = truth < 1.0
    assert edge.sum() >= H  # the edge crosses every row
    err = np.abs(ch["front_coverage"] - truth)
    assert (err <= 4.0 * ch["front_coverage_stderr"] + 1e-6).all(), err.max()
    assert err[edge].mean() < 0.05


@pytest.mark.parametrize(
    ("technique", "params"),
    [
        ("msaa", {"samples": 4}),
        ("msaa", {"samples": 8}),
        ("ssaa", {"samples": 4}),
        ("acaa", {"samples": 8}),
        ("agaa", {"samples": 8}),
        ("noaa", {}),
        ("fxaa", {}),
    ],
)
def test_model_front_coverage_counts_its_samples_on_the_centre_side(scene, technique, params):
    r = rm.run(technique, scene, **params)
    n = params.get("samples", 1)
    offsets = aa_samples.positions(n)
    a, b = scene.camera.project(np.array([[X0, -3.0, 0.0], [X1, 3.0, 0.0]]))
    sx = np.arange(W)[None, :, None] + offsets[None, None, :, 0]
    sy = np.arange(H)[:, None, None] + offsets[None, None, :, 1]
    right = sx > a[0] + (sy - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    yc = np.arange(H)[:, None] + 0.5
    centre = (np.arange(W)[None, :] + 0.5) > a[0] + (yc - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
    expected = (right == centre[:, :, None]).mean(axis=2)
    assert (r.outputs["coverage"] == 1.0).all()
    np.testing.assert_array_equal(r.outputs["front_coverage"], expected.astype(np.float32))
    if n > 1:
        assert (expected < 1).sum() >= H // 2  # the edge is seen by the samples
