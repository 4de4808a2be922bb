"""The multisample models' coverage is unbiased (issue 28): averaged over random sub-pixel
translations of the scene it equals the exact box coverage.

A translation ``t`` of the film moves the world point seen at film ``f`` to ``f + t``, so a
model's sample at ``x + s_k`` sees the point the untranslated camera shows at ``x + s_k - t``.
For ``t`` uniform over ``[0, 1)^2`` its expected coverage is the exact coverage of the box
``[x + s_k - 1, x + s_k)``: the exact channel on the pixel grid offset by ``s_k - 1``
(:func:`scenes.geometry.exact_coverage.exact_coverage_of`), averaged over the pattern's samples.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from raster_oracle.metrics.stats import binomial_stderr_floor
from raster_oracle.raster_models import registry
from raster_oracle.scenes.geometry.exact_coverage import exact_coverage_of, scene_triangle_set
from raster_oracle.scenes.loader import load

#: Translations per model: a 4 x 4 jittered grid over the pixel (stratified, so the plain
#: standard error of their mean below over-states the error: the test is conservative).
GRID = 4
#: Standard errors of the translation average within which it must equal the exact value,
#: and the fraction of pixels that must (a 4-sigma event has probability 6e-5 a pixel).
Z_LIMIT = 4.0
AGREE_FRACTION = 0.999
SCENE, W, H = "star", 32, 18
SAMPLES = 4


def _translated(loaded, tx: float, ty: float):
    """``loaded`` seen through a film moved by ``(tx, ty)`` pixels: a shear of the perspective
    camera's local frame (rays through film ``x`` leave as the old camera's at ``x - t``)."""
    cam = loaded.camera
    shear = np.eye(4)
    shear[0, 2] = 2.0 * cam.tan_half_x * tx / cam.width
    shear[1, 2] = 2.0 * cam.tan_half_x * ty / (cam.height * cam.aspect)
    return dataclasses.replace(loaded, camera=cam.with_to_world(cam.to_world @ shear))


def test_translation_moves_the_film_by_t():
    loaded = load(SCENE, width=W, height=H)
    moved = _translated(loaded, 0.3, -0.7)
    p = np.array([[0.4, 0.1, 5.0], [-0.3, 0.2, 4.0]]) @ loaded.camera.to_world[:3, :3].T
    p += loaded.camera.position
    d = moved.camera.project(p) - loaded.camera.project(p)
    np.testing.assert_allclose(d, [[0.3, -0.7], [0.3, -0.7]], atol=1e-9)


@pytest.mark.parametrize("technique", ["msaa", "acaa", "agaa"])
def test_expected_model_coverage_is_exact_coverage(technique):
    loaded = load(SCENE, width=W, height=H)
    rng = np.random.default_rng(28)
    cells = np.stack(np.meshgrid(np.arange(GRID), np.arange(GRID)), -1).reshape(-1, 2) + 0.5
    shifts = (cells + rng.uniform(-0.5, 0.5, cells.shape)) / GRID
    runs, offsets = [], None
    for tx, ty in shifts:  # a loop over translations (passes), not pixels
        res = registry.run(technique, _translated(loaded, tx, ty), samples=SAMPLES)
        runs.append(np.asarray(res.outputs["coverage"], np.float64).reshape(H, W))
        offsets = np.asarray(res.diagnostics.get("sample_positions", offsets), np.float64)
    runs = np.stack(runs)
    assert offsets is not None and offsets.shape == (SAMPLES, 2)
    tset = scene_triangle_set(loaded)
    centre = np.zeros((H, W), int)
    expected = np.mean(
        [
            exact_coverage_of(loaded.camera, tset, centre, grid_offset=tuple(s - 1.0)).coverage
            for s in offsets
        ],
        axis=0,
    )
    mean = runs.mean(axis=0)
    se = np.maximum(runs.std(axis=0, ddof=1) / np.sqrt(len(runs)), binomial_stderr_floor(len(runs)))
    z = np.abs(mean - expected) / se
    assert np.mean(z <= Z_LIMIT) >= AGREE_FRACTION, float(z.max())
    # the average is not trivially right: many pixels are fractional
    assert np.count_nonzero((expected > 0.05) & (expected < 0.95)) > 20


#: Float32 vertices (Mitsuba's, the exact channel's) against the float64 corners of the hand
#: computation: about 1e-7 of the 320-pixel film.
HAND_ABS = 1e-5


@pytest.mark.slow
def test_straight_edge_error_against_the_exact_channel():
    """The squares of the straight-edge test (tests/test_aa_models.py): the exact channel
    equals the hand-computed polygon area wherever one square touches a pixel, and MSAA's
    straight-edge RMS against it reproduces the floor table (docs/models.md) with no
    reference noise (the exact truth's noise floor is 0)."""
    import math

    from raster_oracle.oracle.reference.coverage import centre_shapes
    from raster_oracle.oracle.scoring.score import COVERAGE_FLOOR_RMS
    from raster_oracle.scenes.catalogue.builtin import BuiltinScene
    from raster_oracle.scenes.geometry.exact_coverage import exact_coverage

    from raster_oracle import scenes
    from tests._geometry import polygon_coverage
    from tests.test_aa_models import FLOOR_RTOL, _squares, _squares_scene

    w, h = 320, 180
    scene = scenes.load(BuiltinScene("aa-squares", _squares_scene, "squares"), width=w, height=h)
    ex = exact_coverage(scene, centre_shapes(scene))
    assert ex.valid.all()
    hand = np.zeros((h, w))
    touched = np.zeros((h, w), int)
    near_corner = np.zeros((h, w), bool)
    for q in _squares():
        film = scene.camera.project(q)
        cov = polygon_coverage(film, w, h)
        hand += cov
        touched += cov > 0
        for fx, fy in film:
            x0, y0 = int(math.floor(fx)), int(math.floor(fy))
            near_corner[max(y0 - 1, 0) : y0 + 2, max(x0 - 1, 0) : x0 + 2] = True
    one = touched <= 1
    np.testing.assert_allclose(ex.coverage[one], hand[one], atol=HAND_ABS)
    single = (ex.coverage > 0) & (ex.coverage < 1) & ~near_corner & (touched == 1)
    cov = registry.run("msaa", scene, samples=4).outputs["coverage"]
    rms = float(np.sqrt(np.mean((cov - ex.coverage)[single] ** 2)))
    assert rms == pytest.approx(COVERAGE_FLOOR_RMS[4], rel=FLOOR_RTOL)
