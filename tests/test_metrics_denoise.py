"""Denoiser metrics: lag after an event and penumbra width in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.metrics.denoise import (
    CI_Z,
    event_lag,
    frame_error_with_floor,
    penumbra_width,
)
from raster_oracle.metrics.validate import MetricError


def _ramp(width_px: float, h=20, w=60, centre=30.0):
    """A vertical edge whose profile rises linearly from 0 to 1 over ``width_px / 0.8``
    pixels (so 10 % to 90 % spans ``width_px``)."""
    x = np.arange(w) + 0.5
    full = width_px / 0.8
    row = np.clip((x - centre) / full + 0.5, 0.0, 1.0)
    return np.broadcast_to(row, (h, w)).copy()


@pytest.mark.parametrize("width", [4.0, 8.0, 12.0])
def test_penumbra_width_of_a_linear_ramp(width):
    t = _ramp(width)
    mask = np.ones(t.shape, bool)
    got = penumbra_width(t, t, mask=mask, band=3)
    assert abs(got - width) <= 1.0  # pixel counting: within one pixel
    wider = penumbra_width(_ramp(2 * width), t, mask=mask, band=int(width))
    assert wider > got + 0.5 * width


def test_penumbra_width_without_an_edge_is_none():
    flat = np.ones((8, 8))
    assert penumbra_width(flat, flat, mask=np.ones((8, 8), bool)) is None
    with pytest.raises(MetricError, match="must match"):
        penumbra_width(flat, np.ones((8, 7)), mask=np.ones((8, 8), bool))


def test_event_lag_counts_frames_until_the_steady_error():
    err = np.array([0.1, 0.1, 0.1, 0.1, 0.9, 0.6, 0.3, 0.12, 0.1, 0.1])
    floor = np.full(10, 0.05)
    assert event_lag(err, floor, event=4) == 3
    assert event_lag(err, np.full(10, 1.0), event=4) == 0
    assert event_lag(np.r_[err[:5], [0.9] * 5], floor, event=4) is None
    # judged against a given steady state (the lit one after a light comes back on)
    assert event_lag(err, floor, event=4, steady=0.26) == 2
    assert event_lag(err, floor, event=4, steady=0.0) is None
    with pytest.raises(MetricError, match="baseline"):
        event_lag(err, floor, event=2)


def test_error_with_floor_closed_form():
    truth = np.full((2, 4, 4), 0.5)
    cand = np.full((2, 4, 4), 0.25)
    se = np.full((2, 4, 4), 0.1)
    mask = np.zeros((4, 4), bool)
    mask[:2] = True
    err, floor = frame_error_with_floor(truth, cand, se, mask)
    assert np.allclose(err, 0.25) and np.allclose(floor, CI_Z * 0.1)
    # all samples alike (truth 0 or 1): a bound, not an estimate; no floor there
    _, floor = frame_error_with_floor(np.ones((2, 4, 4)), cand, se, mask)
    assert np.allclose(floor, 0.0)
