"""Models of the shipped alpha-test rules (raster_models.alpha): the rules' transcriptions and
the rasterized coverage against closed forms and the alpha-tested truth."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.alpha.model import AlphaRasterParams, alpha_raster
from raster_oracle.raster_models.alpha.rules import (
    a2c_samples,
    apply_rule,
    filament_a2c,
    hashed_threshold,
    smoothstep,
    threejs_a2c,
)
from raster_oracle.raster_models.errors import ModelError
from raster_oracle.scenes.camera import Camera
from raster_oracle.scenes.catalogue.factories import look_at
from raster_oracle.scenes.geometry.uv_mesh import QUAD_FACES, uv_mesh
from raster_oracle.scenes.shading.alpha import AlphaMask, AlphaTable, AlphaTexture, checker_texture

RES = 32


def test_threejs_a2c_half_coverage_sits_half_a_ramp_inside():
    t, fw = 0.5, 0.2
    v, gone = threejs_a2c(np.array([0.5, 0.6, 0.7, 0.8]), fw, t)
    assert v.tolist() == pytest.approx([0.0, 0.5, 1.0, 1.0])
    assert gone.tolist() == [True, False, False, False]  # a == t: value 0, discarded
    # no derivative (a flat alpha): a step at the cutoff, as the plain test
    v, gone = threejs_a2c(np.array([0.49, 0.5]), 0.0, 0.5)
    assert v.tolist() == [0.0, 1.0] and gone.tolist() == [True, False]
    assert smoothstep(0.0, 1.0, 0.25) == pytest.approx(0.15625)


def test_filament_a2c_is_centred_and_discards_on_the_remapped_alpha():
    v, gone = filament_a2c(np.array([0.4]), 0.2)  # default threshold 0.4
    assert v[0] == 0.5 and not gone[0]
    # discarded where (a - t) / fw + 1/2 <= t: a <= t + (t - 1/2) fw = 0.38
    _, gone = filament_a2c(np.array([0.3799, 0.3801]), 0.2)
    assert gone.tolist() == [True, False]
    v, _ = filament_a2c(np.array([0.5, 0.2]), 0.0)  # fwidth floored at 1e-3: a hard step
    assert v.tolist() == [1.0, 0.0]


def test_plain_test_and_samples():
    v, gone = apply_rule("test", np.array([0.49, 0.5]), cutoff=0.5)
    assert v.tolist() == [0.0, 1.0] and gone.tolist() == [True, False]
    assert a2c_samples([0.0, 0.124, 0.125, 0.5, 1.0, 1.5], 4).tolist() == [0, 0, 1, 2, 4, 4]
    with pytest.raises(ValueError, match="unknown alpha rule"):
        apply_rule("dither", np.array([0.5]), cutoff=0.5)
    with pytest.raises(ModelError, match="rule must be one of"):
        AlphaRasterParams(rule="dither")
    with pytest.raises(ModelError, match="samples must be one of"):
        AlphaRasterParams(samples=3)


def test_hashed_threshold_is_uniform_and_deterministic():
    rng = np.random.default_rng(3)
    p = rng.uniform(-50, 50, (200000, 3))
    dx = np.tile([0.01, 0.0, 0.0], (len(p), 1)) * rng.uniform(0.5, 2, (len(p), 1))
    dy = np.tile([0.0, 0.01, 0.0], (len(p), 1))
    tau = hashed_threshold(p, dx, dy)
    assert np.all((tau >= 1e-6) & (tau <= 1.0))
    assert np.array_equal(tau, hashed_threshold(p, dx, dy))
    # the CDF step makes the blend of two hashes uniform: deciles within 1 %
    q = np.quantile(tau, np.linspace(0.1, 0.9, 9))
    assert np.allclose(q, np.linspace(0.1, 0.9, 9), atol=0.01)


def _quad_scene(mi):
    corners = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
    uvs = [[0, 0], [1, 0], [1, 1], [0, 1]]
    return mi.load_dict({"type": "scene", "quad": uv_mesh(mi, "quad", corners, QUAD_FACES, uvs)})


def _ortho():
    """An orthographic view down -Z whose film spans the quad exactly."""
    return Camera("orthographic", look_at((0, 0, 5), (0, 0, 0)), RES, RES, 0.1, 10.0)


def test_model_constant_alpha_and_cutoff(mi):
    scene = _quad_scene(mi)
    table = AlphaTable([AlphaMask(factor=0.6)], np.array([0]))
    cover = alpha_raster(scene, table, _ortho(), AlphaRasterParams())["coverage"]
    assert np.all(cover == 1.0)
    cut = alpha_raster(scene, table, _ortho(), AlphaRasterParams(cutoff=0.7))["coverage"]
    assert np.all(cut == 0.0)


@pytest.mark.parametrize("rule", ["test", "hashed", "threejs-a2c", "filament-a2c"])
def test_model_on_a_magnified_binary_checker(mi, rule):
    # 2 x 2 NEAREST texels, 16 pixels each across: every rule keeps exactly the opaque half
    # (binary alpha: the hash threshold lies in (0, 1]; inside a texel fwidth is 0, and the
    # pixels on a texel edge straddle it by whole pixels: no partial pixel)
    scene = _quad_scene(mi)
    tex = AlphaTexture(checker_texture(), "clamp", "clamp", nearest=True)
    table = AlphaTable([AlphaMask(texture=tex)], np.array([0]))
    out = alpha_raster(scene, table, _ortho(), AlphaRasterParams(rule=rule, samples=4))
    cover = out["coverage"]
    assert cover.mean() == pytest.approx(0.5, abs=2 * RES / RES**2)
    assert np.all(cover[: RES // 2 - 1, : RES // 2 - 1] == cover[0, 0])
    assert cover[0, 0] != cover[0, -1]
