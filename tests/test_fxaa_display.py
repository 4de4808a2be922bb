"""FXAA in display space (issue 18): FXAA 3.11 runs on the tone-mapped, gamma-encoded LDR
image, never on HDR radiance; the LDR filter itself is unchanged."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from raster_oracle.metrics.tonemap import srgb_encode, tonemap, tonemap_inverse
from raster_oracle.raster_models.aa.fxaa import display_fxaa
from raster_oracle.raster_models.aa.fxaa_filter import fxaa

from raster_oracle import raster_models, scenes

#: Sub-pixel blend of a straight step edge: 0.75 (7/27)^2 (derivation: test_fxaa.test_step_edge).
SUBPIX_H = 0.75 * (7.0 / 27.0) ** 2
#: sha256 of ``fxaa(_fixed_ldr_image())`` computed with the filter before issue 18's change.
LDR_DIGEST = "c9d44f2b4c2fea2011c494b7d630d6cff232993a5902ed1fa3e83df5fc1810d4"


def _fixed_ldr_image() -> np.ndarray:
    """Slanted edges, a thin line and smooth waves, every value in [0, 1]."""
    h, w = 24, 32
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.zeros((h, w, 3), np.float32)
    img[..., 0] = (x * 0.37 + y > 11.0).astype(np.float32) * 0.9
    img[..., 1] = np.where(np.abs(x - 0.6 * y - 8.0) < 0.7, 0.8, 0.15)
    img[..., 2] = 0.5 + 0.5 * np.sin(x * 0.9) * np.cos(y * 0.7)
    return img


def test_ldr_filter_is_bit_exact_with_the_previous_filter():
    img = _fixed_ldr_image()
    out = fxaa(img)
    assert np.any(out != img, axis=2).sum() == 169  # the image has edges FXAA acts on
    assert hashlib.sha256(out.tobytes()).hexdigest() == LDR_DIGEST


def test_straight_hdr_edge_blends_in_display_space():
    """Vertical step, radiance 0.02 | 20, exposure 0, ACES: the display values are
    D(0.02) = srgb(aces(0.02)) and D(20) = 1 (clipped). FXAA's gamma luma of grey is the
    value itself (weights sum to 1); the sub-pixel term blends each edge column with its
    neighbour across the edge by SUBPIX_H, in display values:
    dark column D + h (1 - D), bright column 1 - h (1 - D). In HDR the dark column would
    have become 0.02 + h (20 - 0.02) = 1.03, brighter than the display's white."""
    dark, bright = 0.02, 20.0
    img = np.full((16, 12, 3), dark, np.float32)
    img[:, 6:] = bright
    fx = display_fxaa(img, exposure=0.0, tone_mapper="aces")
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    d_dark = float(srgb_encode(np.float64(dark * (a * dark + b) / (dark * (c * dark + d) + e))))
    assert fx["input"][0, 0, 0] == pytest.approx(d_dark, abs=1e-6)
    assert fx["input"][0, 11, 0] == pytest.approx(1.0, abs=1e-6)
    expected = np.where(np.arange(12) < 6, d_dark, 1.0)
    expected[5] = d_dark + SUBPIX_H * (1.0 - d_dark)
    expected[6] = 1.0 - SUBPIX_H * (1.0 - d_dark)
    for ch in range(3):
        np.testing.assert_allclose(fx["display"][..., ch], np.tile(expected, (16, 1)), atol=2e-6)
    assert fx["changed"].sum() == 2 * 16
    # the linear output is what the pipeline maps to the display output
    again = tonemap(fx["linear"], exposure=0.0, method="aces")
    np.testing.assert_allclose(again, fx["display"], atol=2e-6)
    assert fx["linear"][0, 5, 0] < 1.0 < dark + SUBPIX_H * (bright - dark)


@pytest.fixture(scope="module")
def hdr_edge():
    return scenes.load("hdr-edge", width=80, height=45)


def test_hdr_edge_fxaa_blends_only_display_values(hdr_edge):
    r = raster_models.run("fxaa", hdr_edge)
    noaa = raster_models.run("noaa", hdr_edge).outputs["color"]
    tm = r.diagnostics["tone_mapping"]
    # the scene is HDR: exposed radiance well above 1 where FXAA acts
    assert float(noaa.max()) * 2.0 ** tm["exposure_stops"] > 4.0
    src, out = r.outputs["fxaa_input"], r.outputs["color_display"]
    changed = r.outputs["fxaa_changed"] > 0
    assert changed.sum() > 100
    assert src.min() >= 0.0 and src.max() <= 1.0
    assert out.min() >= 0.0 and out.max() <= 1.0
    # every pixel FXAA blends reads inputs in [0, 1], and its output lies within its 3x3
    pad = np.pad(src, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = src.shape[:2]
    win = np.stack([pad[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3)])
    lo, hi = win.min(axis=0)[changed], win.max(axis=0)[changed]
    assert lo.min() >= 0.0 and hi.max() <= 1.0
    assert np.all(out[changed] >= lo - 1e-6) and np.all(out[changed] <= hi + 1e-6)
    # unchanged pixels keep noaa's radiance bit for bit; changed ones map to the display output
    np.testing.assert_array_equal(r.outputs["color"][~changed], noaa[~changed])
    mapped = tonemap(r.outputs["color"], exposure=tm["exposure_stops"], method="aces")
    np.testing.assert_allclose(mapped, out, atol=2e-6)


def test_tonemap_inverse_round_trip():
    rng = np.random.default_rng(3)
    x = rng.random((6, 5, 3)) * 4.0
    for method in ("aces", "reinhard", "clip"):
        disp = tonemap(x, exposure=0.7, method=method)
        back = tonemap_inverse(disp, exposure=0.7, method=method)
        np.testing.assert_allclose(tonemap(back, exposure=0.7, method=method), disp, atol=2e-7)
    # unclipped ACES values come back to their radiance
    small = x * 0.05
    back = tonemap_inverse(tonemap(small, exposure=0.0), exposure=0.0)
    np.testing.assert_allclose(back, small, rtol=1e-5, atol=1e-7)
