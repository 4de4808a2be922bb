"""Depth as a scored kind (metrics/depth.py): relative error of linear view depth, the
hyperbolic buffer's rounding (the near-plane precision case), and no score from nothing."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.metrics.depth import (
    depth_metrics,
    float32_linearization_limit,
    hyperbolic_rounding,
)
from raster_oracle.metrics.validate import MetricError

NEAR, FAR = 0.01, 1000.0


def _through_d24(z, near=NEAR, far=FAR, bits=24):
    """Linear depth stored in a UNORM hyperbolic buffer and linearized again (float64)."""
    q = 2.0**bits - 1.0
    d = np.round(far * (z - near) / (z * (far - near)) * q) / q
    return near * far / (far - d * (far - near))


def test_identity_and_a_uniform_relative_error():
    z = np.geomspace(0.5, 900.0, 64 * 48).reshape(48, 64)
    valid = np.ones_like(z, bool)
    same = depth_metrics(z, z.copy(), valid=valid)
    assert same["depth_rel_error_max"] == 0.0 and same["depth_pixels"] == z.size
    short = depth_metrics(z, z * (1 - 0.0011), valid=valid)  # the 4-km ground, 0.11 % short
    assert short["depth_rel_error_mean"] == pytest.approx(0.0011, rel=1e-9)


def test_near_plane_precision_is_named_not_failed():
    z = np.geomspace(0.5, 900.0, 64 * 48).reshape(48, 64)
    valid = np.ones_like(z, bool)
    cand = _through_d24(z)
    rel = np.abs(cand - z) / z
    # the rounding grows with distance: far pixels lose far more than near ones
    assert rel[-1].mean() > 100 * rel[0].mean()
    assert np.all(rel <= hyperbolic_rounding(z, near=NEAR, far=FAR, bits=24) * 1.0001)
    got = depth_metrics(z, cand, valid=valid, near=NEAR, far=FAR, bits=24)
    assert got["depth_beyond_precision_fraction"] == 0.0
    assert got["depth_rel_error_max"] > 1e-3  # large, yet all of it the buffer's rounding
    wrong = depth_metrics(z, cand * 1.01, valid=valid, near=NEAR, far=FAR, bits=24)
    assert wrong["depth_beyond_precision_fraction"] > 0.5


def test_empty_support_and_bad_input():
    z = np.ones((4, 5))
    got = depth_metrics(z, z, valid=np.zeros((4, 5), bool))
    assert got["depth_pixels"] == 0 and got["depth_rel_error_mean"] is None
    with pytest.raises(MetricError, match="one shape"):
        depth_metrics(z, z[:, :4], valid=np.ones((4, 5), bool))
    with pytest.raises(MetricError, match="give all three"):
        depth_metrics(z, z, valid=z > 0, near=0.1)
    with pytest.raises(MetricError, match="finite and > 0"):
        depth_metrics(z, -z, valid=z > 0)
    with pytest.raises(MetricError, match="near < far"):
        hyperbolic_rounding(z, near=2.0, far=1.0, bits=24)


@pytest.mark.parametrize(
    "near, far, bits", [(0.01, 1000.0, 24), (0.1, 100.0, 24), (0.1, 1000.0, 16), (0.1, 100.0, 32)]
)
def test_a_float32_linearization_stays_within_the_limit(near, far, bits):
    """An engine linearizes its buffer in float32, which at 24 and 32 bits loses about as
    much as the buffer's own rounding: that too is precision, not error."""
    z = np.geomspace(near * 1.001, far * 0.999, 200_000)
    d = far * (z - near) / (z * (far - near))
    stored = (np.round(d * (2.0**bits - 1)) / (2.0**bits - 1)).astype(np.float32)
    lin = np.float32(near * far) / (np.float32(far) - stored * np.float32(far - near))
    rel = np.abs(lin.astype(np.float64) - z) / z
    assert np.all(rel <= float32_linearization_limit(z, near=near, far=far, bits=bits))
    valid = np.ones((1, z.size), bool)
    got = depth_metrics(z[None], lin[None], valid=valid, near=near, far=far, bits=bits)
    assert got["depth_beyond_precision_fraction"] == 0.0
    wrong = depth_metrics(z[None], lin[None] * 1.01, valid=valid, near=near, far=far, bits=bits)
    assert wrong["depth_beyond_precision_fraction"] > 0.8
