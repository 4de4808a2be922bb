"""The shared tone-mapping pipeline: closed-form values, invariants, errors."""

import math

import numpy as np
import pytest
from raster_oracle.metrics import (
    MetricError,
    exposure_from_reference,
    luminance,
    srgb_decode,
    srgb_encode,
)
from raster_oracle.metrics import tonemap as tonemap_fn

# float32 round trip of the sRGB curve: a few ulps of values in [0, 1].
SRGB_ROUNDTRIP_ATOL = 1e-6
# Outputs are float32: compare closed forms to float32 precision.
FLOAT32_ATOL = 1e-6


def _aces(x):
    return x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)


def test_srgb_known_values():
    # IEC 61966-2-1: the two segments meet at 0.0031308 -> 0.04045; 0 and 1 are fixed.
    x = np.array([0.0, 0.0031308, 0.5, 1.0], np.float32)
    enc = srgb_encode(x)
    assert enc.dtype == np.float32
    np.testing.assert_allclose(enc, [0.0, 0.04045, 0.735357, 1.0], atol=1e-5)
    np.testing.assert_allclose(srgb_decode(np.float32([0.5])), [0.214041], atol=1e-6)


def test_srgb_roundtrip():
    x = np.linspace(0, 1, 1001, dtype=np.float32)
    np.testing.assert_allclose(srgb_decode(srgb_encode(x)), x, atol=SRGB_ROUNDTRIP_ATOL)


def test_tonemap_aces_closed_form():
    img = np.full((4, 5, 3), 0.5, np.float32)
    out = tonemap_fn(img, exposure=1.0)  # exposed value 1.0
    assert out.dtype == np.float32 and out.shape == (4, 5, 3)
    np.testing.assert_allclose(out, srgb_encode(np.float32(_aces(1.0))), atol=FLOAT32_ATOL)


def test_tonemap_reinhard_grey_and_clip():
    grey = np.full((3, 3), 3.0, np.float32)
    out = tonemap_fn(grey, exposure=0.0, method="reinhard")
    np.testing.assert_allclose(out, srgb_encode(np.float32(0.75)), atol=FLOAT32_ATOL)
    ramp = np.linspace(0, 2, 12, dtype=np.float32).reshape(3, 4)
    clipped = tonemap_fn(ramp, exposure=0.0, method="clip")
    np.testing.assert_allclose(clipped, srgb_encode(np.clip(ramp, 0, 1)), atol=FLOAT32_ATOL)


def test_tonemap_drops_alpha_clamps_negative_and_stays_in_range():
    rng = np.random.default_rng(0)
    img = rng.normal(1.0, 3.0, (8, 8, 4)).astype(np.float32)
    out = tonemap_fn(img, exposure=2.0)
    assert out.shape == (8, 8, 3)
    assert out.min() >= 0.0 and out.max() <= 1.0
    np.testing.assert_array_equal(out, tonemap_fn(np.maximum(img[..., :3], 0), exposure=2.0))


def test_tonemap_monotonic_in_exposure():
    img = np.geomspace(1e-3, 1e3, 64, dtype=np.float32).reshape(8, 8)
    for method in ("aces", "reinhard", "clip"):
        low = tonemap_fn(img, exposure=-1.0, method=method)
        high = tonemap_fn(img, exposure=1.0, method=method)
        assert np.all(high >= low)


def test_exposure_from_reference_constant_image():
    # Log-average of a constant image is the constant (+ Reinhard's delta 1e-4).
    img = np.full((6, 6, 3), 0.5, np.float32)
    assert exposure_from_reference(img) == pytest.approx(math.log2(0.18 / (0.5 + 1e-4)))
    assert exposure_from_reference(np.zeros((4, 4))) == 0.0


def test_exposure_brings_key_to_middle_grey():
    rng = np.random.default_rng(1)
    img = rng.lognormal(0.0, 1.5, (32, 32, 3)).astype(np.float32)
    e = exposure_from_reference(img)
    y = luminance(img) * 2.0**e
    assert math.exp(np.mean(np.log(y + 1e-4 * 2.0**e))) == pytest.approx(0.18, rel=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"exposure": 0.0, "method": "filmic"}, "method must be one of aces, reinhard, clip"),
        ({"exposure": math.nan}, "exposure must be a finite number of stops"),
    ],
)
def test_tonemap_rejects_bad_options(kwargs, match):
    with pytest.raises(MetricError, match=match):
        tonemap_fn(np.ones((2, 2)), **kwargs)


def test_tonemap_rejects_two_channels():
    with pytest.raises(MetricError, match=r"image must have 3 \(RGB\) or 4 \(RGBA\) channels"):
        tonemap_fn(np.ones((2, 2, 2)), exposure=0.0)


def test_exposure_rejects_negative_reference():
    with pytest.raises(MetricError, match="reference must be non-negative, got 1 negative"):
        exposure_from_reference(np.array([[1.0, -1.0]]))
