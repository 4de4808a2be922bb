"""Z-test against a Monte Carlo reference: power on a planted bias, calibration under the null
hypothesis, and the noise floor."""

import math

import numpy as np
import pytest
from raster_oracle.metrics import MetricError, noise_floor, shadow_metrics, z_test
from scipy import stats as sps

SHAPE = (64, 64, 3)
SIGMA = 0.05
# Binomial counts are checked within this many standard deviations of their expectation:
# a false failure then has probability ~6e-5 per check.
BINOMIAL_SIGMAS = 4.0


def _reference(seed, shape=SHAPE):
    """Truth, a noisy reference estimate of it, and the reference's standard error."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(0.2, 0.8, shape)
    stderr = np.full(shape, SIGMA)
    return truth, truth + rng.normal(0.0, SIGMA, shape), stderr


def test_planted_bias_is_flagged():
    truth, ref, stderr = _reference(1)
    biased = truth + 10 * SIGMA  # 10 sigma: p ~ 1e-23, far below the Sidak alpha ~ 8e-7
    r = z_test(ref, stderr, biased)
    assert r["significant_fraction"] > 0.99
    partial = truth.copy()
    partial[:8] += 10 * SIGMA  # an 8-row band of the image is biased
    r = z_test(ref, stderr, partial)
    assert r["significant_fraction"] == pytest.approx(8 / 64, abs=0.01)


def test_unbiased_candidate_passes_and_sidak_alpha():
    truth, ref, stderr = _reference(2)
    r = z_test(ref, stderr, truth, full=True)
    n = math.prod(SHAPE)
    assert r["n_tests"] == n
    assert r["alpha_per_pixel"] == pytest.approx(1 - 0.99 ** (1 / n), rel=1e-9)
    assert r["significant_count"] == 0
    assert r["p_value"].shape == SHAPE
    assert 0.0 <= r["p_value"].min() and r["p_value"].max() <= 1.0


def test_uncorrected_rate_is_nominal():
    # Under the null hypothesis p is uniform: the flagged fraction is alpha.
    truth, ref, stderr = _reference(3)
    alpha = 0.05
    r = z_test(ref, stderr, truth, alpha=alpha, correction="none")
    n = r["n_tests"]
    sd = math.sqrt(alpha * (1 - alpha) / n)
    assert abs(r["significant_fraction"] - alpha) <= BINOMIAL_SIGMAS * sd


def test_sidak_family_wise_rate_is_nominal():
    # The chance that an unbiased image has any significant pixel is alpha.
    alpha, repeats = 0.2, 200
    hits = sum(
        z_test(ref, se, truth, alpha=alpha)["significant_count"] > 0
        for truth, ref, se in (_reference(100 + i, (16, 16)) for i in range(repeats))
    )
    sd = math.sqrt(repeats * alpha * (1 - alpha))
    assert abs(hits - repeats * alpha) <= BINOMIAL_SIGMAS * sd


def test_candidate_stderr_welch_style():
    # Two independent noisy estimates of the same truth: the combined variance keeps the
    # test calibrated; ignoring the candidate's noise would flag ~16 % at alpha 5 %.
    truth, ref, stderr = _reference(4)
    cand = truth + np.random.default_rng(5).normal(0.0, SIGMA, SHAPE)
    alpha = 0.05
    r = z_test(ref, stderr, cand, alpha=alpha, correction="none", candidate_stderr=stderr)
    sd = math.sqrt(alpha * (1 - alpha) / r["n_tests"])
    assert abs(r["significant_fraction"] - alpha) <= BINOMIAL_SIGMAS * sd
    naive = z_test(ref, stderr, cand, alpha=alpha, correction="none")
    expected_naive = 2 * sps.norm.sf(sps.norm.isf(alpha / 2) / math.sqrt(2))
    assert naive["significant_fraction"] == pytest.approx(expected_naive, abs=0.02)


def test_stderr_floor_and_exact_agreement():
    ref = np.ones((4, 4))
    zero = np.zeros((4, 4))
    assert z_test(ref, zero, ref)["significant_count"] == 0
    r = z_test(ref, zero, ref - 1e-5, full=True)  # 0.1 floor units: not significant
    assert r["significant_count"] == 0
    assert r["z"] == pytest.approx(np.full((4, 4), 0.1))
    assert z_test(ref, zero, ref - 1e-2)["significant_fraction"] == 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"alpha": 1.0}, r"alpha must be in \(0, 1\), got 1.0"),
        ({"stderr_floor": -1.0}, "stderr_floor must be a finite number >= 0"),
        ({"correction": "bonferroni"}, "correction must be one of sidak, none"),
    ],
)
def test_rejects_bad_options(kwargs, match):
    img = np.ones((4, 4))
    with pytest.raises(MetricError, match=match):
        z_test(img, img, img, **kwargs)


def test_rejects_negative_stderr_and_shape_mismatch():
    img = np.ones((4, 4))
    with pytest.raises(MetricError, match="reference_stderr must be non-negative"):
        z_test(img, -img, img)
    with pytest.raises(MetricError, match="reference_stderr and reference must have the same"):
        z_test(img, np.ones((4, 5)), img)


def test_noise_floor_calls_the_metric():
    a = np.zeros((4, 4))
    b = np.zeros((4, 4))
    b[0, 0] = 1.0
    rec = np.ones((4, 4), bool)
    floor = noise_floor(shadow_metrics, a, b, receivers=rec)
    assert floor == shadow_metrics(a, b, receivers=rec)
    assert floor["misclassified_fraction"] == 1 / 16
    with pytest.raises(MetricError, match="metric must be callable, got str"):
        noise_floor("flip", a, b)
