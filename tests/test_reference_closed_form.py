"""Reference visibility and coverage against exact image-space polygon areas."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference

from raster_oracle import scenes
from tests._geometry import polygon_coverage

# A jittered 8x8 grid estimates a straight edge's area with an error of a few cells at worst:
# the RMS over edge pixels stays well under 1/16 and the mean over the image far lower.
EDGE_RMS_TOL_64SPP = 0.05
MEAN_ABS_TOL_64SPP = 0.004


def _plate_exact(loaded):
    d = np.asarray(loaded.light.direction)
    corners = np.array([[-1, 1.5, -1], [-1, 1.5, 1], [1, 1.5, 1], [1, 1.5, -1]], float)
    shadow = corners - d[None, :] * (corners[:, 1:2] / d[1])
    cam = loaded.camera
    shadow_cov = polygon_coverage(cam.project(shadow), cam.width, cam.height)
    plate_cov = polygon_coverage(cam.project(corners), cam.width, cam.height)
    return shadow_cov, plate_cov


@pytest.fixture(scope="module")
def plate():
    return scenes.load("plate", width=96, height=54)


def test_plate_shadow_matches_exact_area(plate):
    shadow_cov, plate_cov = _plate_exact(plate)
    assert shadow_cov.sum() > 50, "the shadow must be in view"
    assert np.sum(shadow_cov * plate_cov) == 0, "test geometry: shadow and plate must not overlap"
    exact = 1.0 - shadow_cov
    ch, _ = render_reference(plate, ReferenceSettings(spp=64, channels=("visibility",)), quiet=True)
    err = ch["visibility"] - exact
    edge = (exact > 0) & (exact < 1)
    assert np.abs(err).mean() < MEAN_ABS_TOL_64SPP
    assert np.sqrt(np.mean(err[edge] ** 2)) < EDGE_RMS_TOL_64SPP
    # pixels wholly inside or outside the shadow (and their neighbours) are exact
    from scipy.ndimage import binary_dilation

    interior = ~binary_dilation(edge, iterations=1)
    assert np.array_equal(ch["visibility"][interior], exact[interior])


def test_plate_error_falls_with_samples(plate):
    shadow_cov, _ = _plate_exact(plate)
    exact = 1.0 - shadow_cov
    errs = []
    for spp in (4, 64, 256):
        ch, _ = render_reference(
            plate, ReferenceSettings(spp=spp, channels=("visibility",)), quiet=True
        )
        errs.append(np.abs(ch["visibility"] - exact).sum())
    assert errs[0] > errs[1] > errs[2]


def test_star_coverage_matches_exact_area():
    loaded = scenes.load("star", width=128, height=72)
    cam = loaded.camera
    exact = np.zeros((cam.height, cam.width))
    for verts, faces in loaded.mesh_data.values():
        for tri in faces:  # a few dozen triangles: the per-pixel work is vectorized
            exact += polygon_coverage(
                cam.project(verts[tri].astype(np.float64)), cam.width, cam.height
            )
    assert exact.max() <= 1.0 + 1e-9
    ch, stats = render_reference(
        loaded, ReferenceSettings(spp=64, channels=("coverage",)), quiet=True
    )
    err = ch["coverage"] - exact
    edge = (exact > 0) & (exact < 1)
    assert edge.sum() > 200
    assert np.abs(err).mean() < MEAN_ABS_TOL_64SPP
    assert np.sqrt(np.mean(err[edge] ** 2)) < EDGE_RMS_TOL_64SPP
    assert stats["primary_rays"] == 64 * cam.width * cam.height


def test_shadow_survives_far_from_the_origin(tmp_path):
    """1e5 units from the origin the oracle's shadow rays must still hit a caster 1.5 above
    the receiver (Mitsuba's own spawn_ray offset there jumps over it)."""
    from tests.test_models_xml import quad, write_scene

    shadowed = {}
    for offset in (0.0, 1e5):
        o = np.array([offset, 0.0, offset])
        path = write_scene(
            tmp_path / f"o{int(offset)}",
            origin=o + (0, 6, 7),
            target=o + (0.8, 0, 0),
            sun=(0.55, -1.0, 0.2),
            shapes=[quad(o, (15, 0, 0), (0, 0, -15)), quad(o + (0, 1.5, 0), (1, 0, 0), (0, 0, -1))],
            width=64,
            height=36,
        )
        ch, _ = render_reference(
            scenes.load(str(path)), ReferenceSettings(spp=4, channels=("visibility",)), quiet=True
        )
        shadowed[offset] = float((1 - ch["visibility"]).sum())
    assert shadowed[0.0] > 50
    # float32 positions 1e5 from the origin are 8 mm apart: the shadow area agrees to a few %
    assert abs(shadowed[1e5] - shadowed[0.0]) < 0.1 * shadowed[0.0]
