"""Mipmapped alpha (scenes.shading.alpha_mips): box and coverage-preserving (NVTT) chains, the
OpenGL level of detail and trilinear sampling."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.scenes.shading.alpha import AlphaError, checker_texture, sample_np
from raster_oracle.scenes.shading.alpha_mips import (
    box_mips,
    coverage_mips,
    mip_level,
    nvtt_alpha_test_coverage,
    nvtt_scale_alpha_to_coverage,
    sample_mips,
)


def _thin_features():
    """A 64 x 64 alpha with a 1-texel line, a 2-texel band and a block (alpha 0 or 1)."""
    a = np.zeros((64, 64), np.float32)
    a[:, 10] = 1.0
    a[:, 30:32] = 1.0
    a[20:40, 40:60] = 1.0
    return a


def test_box_chain_sizes_and_means():
    rng = np.random.default_rng(1)
    a = rng.uniform(0, 1, (8, 4)).astype(np.float32)
    chain = box_mips(a)
    assert [m.shape for m in chain] == [(8, 4), (4, 2), (2, 1), (1, 1)]
    for m in chain:  # power-of-two sizes: every level keeps the mean
        assert float(m.mean()) == pytest.approx(float(a.mean()), abs=1e-6)
    assert chain[1][0, 0] == pytest.approx(a[:2, :2].mean())
    assert [m.shape for m in box_mips(np.ones((5, 3)))] == [(5, 3), (2, 1), (1, 1)]
    with pytest.raises(AlphaError, match="finite"):
        box_mips(np.array([[np.nan]]))


def test_nvtt_coverage_of_the_checker_cell():
    # one cell, 4 x 4 sub-samples at f = 1/8, 3/8, 5/8, 7/8: alpha = 1/2 + 2 (fx-1/2)(fy-1/2)
    # > 1/2 on the 8 same-sign samples; > 0.7 needs (fx-1/2)(fy-1/2) > 0.1: only 3/8 x 3/8
    assert nvtt_alpha_test_coverage(checker_texture(), 0.5) == 0.5
    assert nvtt_alpha_test_coverage(checker_texture(), 0.7) == 2 / 16
    # strictly greater: a constant alpha equal to the reference covers nothing
    assert nvtt_alpha_test_coverage(np.full((3, 3), 0.5), 0.5) == 0.0  # dyadic: exact
    assert nvtt_alpha_test_coverage(np.full((3, 3), 0.5), 0.4999) == 1.0
    # the scale applies before the test, saturated
    assert nvtt_alpha_test_coverage(np.full((3, 3), 0.3), 0.5, 2.0) == 1.0
    assert math.isnan(nvtt_alpha_test_coverage(np.ones((1, 4)), 0.5))  # NVTT's 0 / 0


def test_scale_to_coverage_bisection():
    # a constant 0.3 must rise above 0.5: the first step (scale 1) covers nothing, the
    # bisection over [1, 4] finds a scale > 5/3, and the texture is clamped to [0, 1]
    out = nvtt_scale_alpha_to_coverage(np.full((4, 4), 0.3), 1.0, 0.5)
    assert np.all(out > 0.5) and np.all(out <= 1.0)
    # already at the desired coverage: unchanged (the first step is equal: early stop)
    a = _thin_features()
    same = nvtt_scale_alpha_to_coverage(a, nvtt_alpha_test_coverage(a, 0.5), 0.5)
    assert np.array_equal(same, a)
    # a level one texel high has no coverage (NaN): scale 1 kept
    row = np.array([[0.2, 0.6]], np.float32)
    assert np.array_equal(nvtt_scale_alpha_to_coverage(row, 0.9, 0.5), row)


def test_coverage_mips_keep_what_box_mips_lose():
    a = _thin_features()
    cut = 0.5
    box, kept = box_mips(a), coverage_mips(a, cut)
    want = nvtt_alpha_test_coverage(a, cut)
    assert np.array_equal(kept[0], a)
    for k in range(1, len(box) - 1):  # every level with a cell (the 1 x 1 level has none)
        err_box = abs(nvtt_alpha_test_coverage(box[k], cut) - want)
        err_kept = abs(nvtt_alpha_test_coverage(kept[k], cut) - want)
        assert err_kept <= err_box
    # the 4 x 4 level: box filtering has lost nearly all the foliage, NVTT's scaling keeps it
    assert nvtt_alpha_test_coverage(box[4], cut) < 0.01
    assert nvtt_alpha_test_coverage(kept[4], cut) == pytest.approx(want, abs=0.01)


def test_mip_level_follows_opengl():
    # one texel per pixel: level 0; four: level 2; the larger axis decides
    assert mip_level(1 / 64, 0, 0, 1 / 64, width=64, height=64) == pytest.approx(0.0)
    assert mip_level(4 / 64, 0, 0, 1 / 64, width=64, height=64) == pytest.approx(2.0)
    assert mip_level(0, 3 / 32, 4 / 64, 0, width=64, height=32) == pytest.approx(math.log2(4))
    assert mip_level(1 / 64, 0, 0, 1 / 64, width=64, height=64, bias=-0.5) == -0.5
    assert mip_level(0, 0, 0, 0, width=8, height=8) == -math.inf


def test_trilinear_sampling():
    rng = np.random.default_rng(2)
    a = rng.uniform(0, 1, (16, 16)).astype(np.float32)
    chain = box_mips(a)
    u, v = rng.uniform(-1, 2, 500), rng.uniform(-1, 2, 500)
    # magnification: the base level with the magnification filter
    for nearest in (True, False):
        got = sample_mips(chain, u, v, np.full(500, -0.3), mag_nearest=nearest)
        assert np.array_equal(got, sample_np(a, u, v, nearest=nearest))
    # integer level: that level, bilinear
    assert np.allclose(sample_mips(chain, u, v, 2.0), sample_np(chain[2], u, v))
    # between levels: the blend
    mid = sample_mips(chain, u, v, 1.25)
    assert np.allclose(mid, 0.75 * sample_np(chain[1], u, v) + 0.25 * sample_np(chain[2], u, v))
    # beyond the last level (and an infinite footprint): the 1 x 1 level, the texture's mean
    far = sample_mips(chain, u, v, np.r_[np.full(499, 40.0), np.inf])
    assert np.allclose(far, a.mean(), atol=1e-6)
