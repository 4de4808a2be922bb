"""Shadow metrics: an exact hand-built case, invariants, property tests, errors."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from raster_oracle.metrics import SHADOW_KEYS, MetricError, shadow_edges, shadow_metrics

# Fractions are ratios of integer counts; a sum of two such ratios may differ from the
# ratio of the summed counts by an ulp.
FRACTION_RTOL = 1e-12


def _half_shadow(h=6, w=8):
    """Reference: columns 0..3 shadowed (0), 4..7 lit (1)."""
    ref = np.zeros((h, w), np.float32)
    ref[:, w // 2 :] = 1.0
    return ref


def test_hand_built_case_is_exact():
    ref = _half_shadow()
    receivers = np.ones(ref.shape, bool)
    receivers[0, :] = False  # one row of sky: 40 receivers remain
    cand = ref.copy()
    cand[2, 1] = 0.75  # false lit (shadow side, >= 0.5), error +0.75
    cand[3, 6] = 0.25  # false shadow (lit side), error -0.75
    cand[4, 3] = 0.4  # wrong but not misclassified (< 0.5), error +0.4
    cand[0, 0] = 1.0  # not a receiver: ignored
    r = shadow_metrics(ref, cand, receivers=receivers, edge_band=1, full=True)
    assert r["receiver_count"] == 40
    assert r["false_lit_fraction"] == 1 / 40
    assert r["false_shadow_fraction"] == 1 / 40
    assert r["misclassified_fraction"] == 2 / 40
    assert r["visibility_mae"] == pytest.approx((0.75 + 0.75 + 0.4) / 40)
    assert r["visibility_rmse"] == pytest.approx(math.sqrt((0.75**2 * 2 + 0.4**2) / 40))
    # Edge at columns 3|4; band of 1 pixel: columns 2..5 of the 5 receiver rows.
    assert r["edge_band_count"] == 20
    np.testing.assert_array_equal(np.nonzero(r["edge_band"].any(axis=0))[0], [2, 3, 4, 5])
    assert r["edge_band_mae"] == pytest.approx(0.4 / 20)
    assert r["edge_band_misclassified_fraction"] == 0.0
    assert r["misclassified"][2, 1] == 1 and r["misclassified"][3, 6] == -1
    assert int(np.abs(r["misclassified"]).sum()) == 2
    assert r["signed_error"][2, 1] == pytest.approx(0.75)
    assert r["signed_error"][0, 0] == 0.0


def test_edge_band_zero_is_the_edge_pixels():
    ref = _half_shadow()
    rec = np.ones(ref.shape, bool)
    r = shadow_metrics(ref, ref, receivers=rec, edge_band=0, full=True)
    np.testing.assert_array_equal(np.nonzero(r["edge_band"].any(axis=0))[0], [3, 4])


def test_receiver_boundaries_are_not_shadow_edges():
    lit = np.zeros((4, 4), bool)
    lit[:, 2:] = True
    rec = np.ones((4, 4), bool)
    rec[:, 2] = False  # the class change happens across a non-receiver column
    assert not shadow_edges(lit, rec).any()


def test_identity_and_empty_receivers():
    ref = _half_shadow()
    r = shadow_metrics(ref, ref, receivers=np.ones(ref.shape, bool))
    assert all(r[k] == 0.0 for k in SHADOW_KEYS if not k.endswith("_count"))
    empty = shadow_metrics(ref, 1 - ref, receivers=np.zeros(ref.shape, bool))
    assert empty["receiver_count"] == 0
    assert all(empty[k] == 0.0 for k in SHADOW_KEYS)
    assert set(SHADOW_KEYS) <= set(empty)


def test_threshold_classification_is_inclusive():
    ref = np.array([[0.0, 1.0]])
    cand = np.array([[0.5, 1.0]])
    r = shadow_metrics(ref, cand, receivers=np.ones((1, 2), bool), threshold=0.5)
    assert r["false_lit_fraction"] == 0.5


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"receivers": np.ones((4, 4))}, "receivers must be a boolean array, got dtype float64"),
        ({"receivers": np.ones((4, 5), bool)}, r"receivers must have shape \(4, 4\)"),
        ({"edge_band": -1}, "edge_band must be a non-negative integer, got -1"),
        ({"edge_band": 1.5}, "edge_band must be a non-negative integer"),
        ({"threshold": 0.0}, r"threshold must be in \(0, 1\], got 0.0"),
    ],
)
def test_rejects_bad_options(kwargs, match):
    vis = np.ones((4, 4))
    kwargs = {"receivers": np.ones((4, 4), bool), **kwargs}
    with pytest.raises(MetricError, match=match):
        shadow_metrics(vis, vis, **kwargs)


def test_rejects_visibility_out_of_range():
    vis = np.ones((4, 4))
    rec = np.ones((4, 4), bool)
    bright = vis.copy()
    bright[1, 2] = 1.5
    with pytest.raises(MetricError, match="candidate must be at most 1, got 1 larger"):
        shadow_metrics(vis, bright, receivers=rec)
    with pytest.raises(MetricError, match=r"reference must be a 2-D array, got shape \(4, 4, 1\)"):
        shadow_metrics(vis[..., None], vis[..., None], receivers=rec)


# --------------------------------------------------------------------------- properties

_shapes = st.tuples(st.integers(1, 12), st.integers(1, 12))
_unit = st.floats(0.0, 1.0, allow_nan=False, width=32)


@st.composite
def _cases(draw):
    shape = draw(_shapes)
    ref = draw(arrays(np.float32, shape, elements=_unit))
    cand = draw(arrays(np.float32, shape, elements=_unit))
    rec = draw(arrays(np.bool_, shape))
    band = draw(st.integers(0, 3))
    threshold = draw(st.floats(0.01, 1.0))
    return ref, cand, rec, band, threshold


@settings(max_examples=150, deadline=None)
@given(_cases())
def test_shadow_properties(case):
    ref, cand, rec, band, threshold = case
    r = shadow_metrics(ref, cand, receivers=rec, edge_band=band, threshold=threshold, full=True)
    for key in SHADOW_KEYS:
        assert math.isfinite(r[key])
    for key in (
        "misclassified_fraction",
        "false_lit_fraction",
        "false_shadow_fraction",
        "edge_band_misclassified_fraction",
        "visibility_mae",
        "edge_band_mae",
    ):
        assert 0.0 <= r[key] <= 1.0
    assert math.isclose(
        r["false_lit_fraction"] + r["false_shadow_fraction"],
        r["misclassified_fraction"],
        rel_tol=FRACTION_RTOL,
        abs_tol=0.0,
    )
    assert r["visibility_mae"] <= r["visibility_rmse"] + 1e-12
    assert r["receiver_count"] == int(rec.sum())
    assert r["edge_band_count"] <= r["receiver_count"]
    assert not (r["edge_band"] & ~rec).any()
    # Swapping the images swaps false lit and false shadow.
    s = shadow_metrics(cand, ref, receivers=rec, edge_band=band, threshold=threshold)
    assert s["false_lit_fraction"] == r["false_shadow_fraction"]
    assert s["visibility_mae"] == pytest.approx(r["visibility_mae"])


@settings(max_examples=60, deadline=None)
@given(_cases())
def test_non_receivers_do_not_matter(case):
    ref, cand, rec, band, threshold = case
    scrambled = np.where(rec, cand, 1.0 - cand)
    a = shadow_metrics(ref, cand, receivers=rec, edge_band=band, threshold=threshold)
    b = shadow_metrics(ref, scrambled, receivers=rec, edge_band=band, threshold=threshold)
    assert a == b
