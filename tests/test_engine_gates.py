"""The engine teams' gates (issue 25): Unreal's screenshot comparison, Unity's average
delta E and the edge-aware tolerance, on closed-form images."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.metrics import engine_gates as G

#: A flat grey image: no pixel is anti-aliased by Unreal's neighbour test.
GREY = 100 / 255


def _flat(h=100, w=100, value=GREY):
    return np.full((h, w, 3), value)


def test_unreal_tolerances_are_the_published_ones():
    low, medium, high = (G.UNREAL_TOLERANCES[k] for k in ("low", "medium", "high"))
    assert (low.red, low.min_brightness, low.max_brightness) == (16, 16, 240)
    assert (medium.red, medium.min_brightness, medium.max_brightness) == (24, 24, 220)
    assert (high.red, high.min_brightness, high.max_brightness) == (32, 64, 96)
    assert low.maximum_local_error == 0.10 and low.maximum_global_error == 0.02


def test_unreal_identical_and_within_tolerance_pass():
    tol = G.UNREAL_TOLERANCES["low"]
    same = G.unreal_comparison(_flat(), _flat(), tolerance=tol)
    assert same["global_error"] == 0 and same["local_error"] == 0 and same["passed"]
    near = G.unreal_comparison(_flat(), _flat(value=(100 + 16) / 255), tolerance=tol)
    assert near["global_error"] == 0  # 16 levels is within Low's 16
    far = G.unreal_comparison(_flat(), _flat(value=(100 + 17) / 255), tolerance=tol)
    assert far["global_error"] == 1.0 and not far["passed"]


def test_unreal_local_error_is_the_worst_block():
    """A 10x10 square changed by 50 levels in a 100x100 image: 1 % of the image (global
    passes 0.02), all of one block of the 10x10 grid (local fails 0.10)."""
    cand = _flat()
    cand[20:30, 40:50] = 150 / 255
    found = G.unreal_comparison(_flat(), cand, tolerance=G.UNREAL_TOLERANCES["low"])
    assert found["global_error"] == pytest.approx(0.01)
    assert found["local_error"] == pytest.approx(1.0)
    assert not found["passed"]


def test_unreal_ignores_anti_aliasing_within_brightness():
    """A pixel on a high-contrast edge (anti-aliased by Unreal's test) may differ by more
    than the channel tolerance when its luminance is within MinBrightness."""
    ref = _flat(value=0.0)
    ref[:, 50:] = 1.0
    cand = ref.copy()
    # the black column beside the edge gets 20 levels of red: off by more than 16 in red,
    # its luminance by 0.2126 x 20 = 4.3 levels (within 16)
    cand[:, 49] = np.array([20, 0, 0]) / 255
    found = G.unreal_comparison(ref, cand, tolerance=G.UNREAL_TOLERANCES["low"])
    assert found["global_error"] == 0.0
    strict = G.UnrealTolerance(16, 16, 16, 16, 16, 240, ignore_anti_aliasing=False)
    assert G.unreal_comparison(ref, cand, tolerance=strict)["global_error"] == pytest.approx(0.01)


def test_unity_delta_e_identity_symmetry_and_threshold():
    rng = np.random.default_rng(3)
    a = rng.random((16, 16, 3))
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1)
    assert G.unity_delta_e(a, a)["average"] == 0.0 and G.unity_delta_e(a, a)["max"] == 0.0
    ab, ba = G.unity_delta_e(a, b), G.unity_delta_e(b, a)
    assert ab["average"] == pytest.approx(ba["average"], rel=1e-9)
    expected = np.maximum(ab["map"] - G.UNITY_PER_PIXEL_THRESHOLD, 0).mean()
    assert ab["average"] == pytest.approx(expected)
    # a grey level step is a lightness difference only: the larger step, the larger dE
    small = G.unity_delta_e(_flat(), _flat(value=101 / 255))["max"]
    large = G.unity_delta_e(_flat(), _flat(value=110 / 255))["max"]
    assert 0 < small < large


def test_edge_aware_relaxes_fractional_truth_only():
    ref = np.array([[0.5, 1.0, 0.0]])
    se = np.zeros_like(ref)
    ok = G.edge_aware_error(ref, np.array([[0.7, 1.0, 0.0]]), reference_stderr=se)
    assert ok["fraction"] == 0.0  # 0.2 <= 0.25 at the fractional pixel
    edge = G.edge_aware_error(ref, np.array([[0.8, 1.0, 0.0]]), reference_stderr=se)
    assert edge["count"] == 1
    inside = G.edge_aware_error(ref, np.array([[0.5, 0.99, 0.0]]), reference_stderr=se)
    assert inside["count"] == 1  # an all-lit pixel gets no position allowance
    noisy = G.edge_aware_error(
        ref, np.array([[0.5, 0.99, 0.0]]), reference_stderr=np.full_like(ref, 0.004)
    )
    assert noisy["count"] == 0  # 0.01 <= 3 x 0.004


def test_a_prepared_reference_gives_the_same_comparisons():
    """The reference's side computed once (a sweep worker keeps it for the next case) gives
    the same Unreal and Unity results as computing it with each candidate."""
    rng = np.random.default_rng(3)
    ref = rng.random((23, 31, 3))
    cand = np.clip(ref + rng.normal(0.0, 0.05, ref.shape), 0.0, 1.0)
    ready = G.prepare_reference(ref)
    a = G.unreal_comparisons(ref, cand, tolerances=G.UNREAL_TOLERANCES)
    b = G.unreal_comparisons(None, cand, tolerances=G.UNREAL_TOLERANCES, prepared=ready)
    assert max(found["global_error"] for found in a.values()) > 0
    for level in a:
        assert a[level]["global_error"] == b[level]["global_error"]
        assert a[level]["local_error"] == b[level]["local_error"]
        assert np.array_equal(a[level]["mismatch"], b[level]["mismatch"])
    u, v = G.unity_delta_e(ref, cand), G.unity_delta_e(None, cand, prepared=ready)
    assert u["average"] == v["average"] > 0 and np.array_equal(u["map"], v["map"])
