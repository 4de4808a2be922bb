"""Temporal metrics: hand cases and property tests."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from raster_oracle.metrics import MetricError, flicker, temporal_error

# Adding a constant to float64 values of magnitude <= 1e3 changes differences by rounding
# only: a few ulps of 1e3.
SHIFT_ATOL = 1e-9


def test_alternating_candidate_flickers():
    ref = np.full((4, 3, 3), 0.5)
    cand = np.zeros((4, 3, 3))
    cand[1::2] = 1.0  # 0, 1, 0, 1: every change is 1
    assert flicker(ref, cand) == 1.0
    assert temporal_error(ref, cand) == 1.0
    assert flicker(cand, ref) == -1.0


def test_static_bias_is_not_temporal_error():
    rng = np.random.default_rng(0)
    ref = rng.random((5, 6, 7, 3))
    assert temporal_error(ref, ref + 0.25) == pytest.approx(0.0, abs=SHIFT_ATOL)
    assert flicker(ref, ref + 0.25) == pytest.approx(0.0, abs=SHIFT_ATOL)


def test_mask_restricts_pixels():
    ref = np.zeros((3, 2, 2))
    cand = ref.copy()
    cand[1, 0, 0] = 1.0  # changes 0 -> 1 -> 0 at pixel (0, 0)
    mask = np.zeros((2, 2), bool)
    mask[0, 0] = True
    assert flicker(ref, cand, mask=mask) == 1.0
    assert flicker(ref, cand, mask=~mask) == 0.0
    assert flicker(ref, cand, mask=np.zeros((2, 2), bool)) == 0.0


@pytest.mark.parametrize(
    ("shape", "match"),
    [
        ((1, 4, 4), r"sequences must have at least 2 frames, got shape \(1, 4, 4\)"),
        ((4, 4), r"reference_frames must be a 3-D or 4-D array, got shape \(4, 4\)"),
    ],
)
def test_rejects_bad_shapes(shape, match):
    with pytest.raises(MetricError, match=match):
        flicker(np.zeros(shape), np.zeros(shape))


def test_rejects_mismatched_sequences():
    with pytest.raises(MetricError, match=r"reference_frames and candidate_frames must have"):
        temporal_error(np.zeros((3, 4, 4)), np.zeros((2, 4, 4)))


_values = st.floats(-1e3, 1e3, allow_nan=False)
_shapes = st.tuples(st.integers(2, 5), st.integers(1, 6), st.integers(1, 6))


@st.composite
def _pairs(draw):
    shape = draw(_shapes)
    return draw(arrays(np.float64, shape, elements=_values)), draw(
        arrays(np.float64, shape, elements=_values)
    )


@settings(max_examples=100, deadline=None)
@given(_pairs(), st.floats(-1e3, 1e3))
def test_temporal_properties(pair, shift):
    ref, cand = pair
    assert flicker(ref, ref) == 0.0
    assert temporal_error(ref, ref) == 0.0
    assert temporal_error(ref, cand) >= 0.0
    # A constant added to every frame changes no frame-to-frame difference.
    assert flicker(ref, cand + shift) == pytest.approx(flicker(ref, cand), abs=SHIFT_ATOL)
    assert flicker(ref + shift, cand) == pytest.approx(flicker(ref, cand), abs=SHIFT_ATOL)
    assert temporal_error(ref + shift, cand + shift) == pytest.approx(
        temporal_error(ref, cand), abs=SHIFT_ATOL
    )
    # Antisymmetry of flicker, symmetry of temporal error.
    assert flicker(cand, ref) == pytest.approx(-flicker(ref, cand), abs=SHIFT_ATOL)
    assert temporal_error(cand, ref) == pytest.approx(temporal_error(ref, cand), abs=SHIFT_ATOL)
