"""Which differences from a Monte Carlo reference are significant, and the reference's own
noise floor.

The reference is an estimate with a per-pixel standard error (from the ``moment``
integrator or per-pixel sample variance / spp). A per pixel-channel two-sided Z-test with a
Sidak correction over pixels says which differences noise cannot explain, as Mitsuba 3's
render regression tests do.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import special

from .validate import MetricError, check_images

__all__ = [
    "CORRECTIONS",
    "FRACTION_FLOOR_Z",
    "binomial_stderr_floor",
    "exact_surrogate",
    "fraction_floor",
    "noise_floor",
    "z_test",
]

#: Standard errors in a fraction's noise floor (:func:`fraction_floor`): two runs' floors
#: add up to 4 standard errors of each, 2.8 of their difference (a false regression in about
#: 1 comparison of 200).
FRACTION_FLOOR_Z = 2.0

#: Multiple-comparison corrections accepted by :func:`z_test`.
CORRECTIONS = ("sidak", "none")


def binomial_stderr_floor(samples, scale=1.0):
    """Smallest standard error a pixel estimated from ``samples`` samples can honestly claim.

    A pixel whose ``N`` samples all agree has sample variance 0, yet a feature covering a
    fraction ``p`` of it is missed with probability ``(1 - p)^N``: the estimate is not exact.
    The Jeffreys prior Beta(1/2, 1/2) gives, after ``N`` agreeing samples, the posterior mean
    ``p = 0.5 / (N + 1)`` for the unseen outcome; its binomial standard error
    ``sqrt(p (1 - p) / N)`` is the floor (0.042 at N = 16, 0.011 at 64, 0.0014 at 1024).
    ``scale`` converts it to the image's units (1 for visibility and coverage; for radiance
    the range a missed feature could have).

    References
    ----------
    .. [1] L. D. Brown, T. T. Cai, A. DasGupta, "Interval Estimation for a Binomial
       Proportion", Statistical Science 16(2), 2001. doi:10.1214/ss/1009213286
    """
    n = np.maximum(np.asarray(samples, dtype=np.float64), 1.0)
    p = 0.5 / (n + 1.0)
    return np.sqrt(p * (1.0 - p) / n) * np.asarray(scale, dtype=np.float64)


def fraction_floor(fraction: float, n: int, *, z: float = FRACTION_FLOOR_Z) -> float:
    """Noise floor of a fraction of ``n`` pixels flagged by a test against a Monte Carlo
    reference (``significant_fraction``): ``z * sqrt(f (1 - f) / n)``, at least ``z / n``.

    Re-rendering the reference with another seed (or on another backend) flips the pixels
    whose test statistic is near the threshold. The flagged count is a sum of ``n``
    independent Bernoulli indicators with mean ``n f``, whose variance is at most the
    binomial ``n f (1 - f)`` (equality when every pixel has the same chance); so this is an
    upper bound of the fraction's seed-to-seed standard error, times ``z``. The ``z / n``
    lower bound lets a run with no flagged pixel gain one without a regression.

    References
    ----------
    .. [1] W. Hoeffding, "On the distribution of the number of successes in independent
       trials", Annals of Mathematical Statistics 27(3), 1956. doi:10.1214/aoms/1177728178
    """
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    f = min(max(float(fraction), 0.0), 1.0)
    return float(z * max(np.sqrt(f * (1.0 - f) / n), 1.0 / n))


def exact_surrogate(reference_a, reference_b):
    """An image that differs from ``reference_a`` as an exact candidate would.

    Two independent references ``A`` and ``B`` of the same settings differ by noise of
    variance ``2 sigma^2``; an exact candidate (the truth ``T``) differs from ``A`` by noise of
    variance ``sigma^2``. ``A + (B - A) / sqrt(2)`` differs from ``A`` by ``(B - A) / sqrt(2)``,
    which has variance ``sigma^2``: scoring it gives the metrics an exact candidate would get
    (in distribution), where scoring ``B`` itself overstates them by about ``sqrt(2)``.
    """
    a = np.asarray(reference_a, dtype=np.float64)
    b = np.asarray(reference_b, dtype=np.float64)
    return (a + (b - a) / np.sqrt(2.0)).astype(np.float32)


def z_test(
    reference,
    reference_stderr,
    candidate,
    *,
    alpha: float = 0.01,
    stderr_floor: float = 1e-4,
    samples=None,
    floor_scale=1.0,
    binary: bool = False,
    candidate_stderr=None,
    correction: str = "sidak",
    full: bool = False,
) -> dict:
    """Per pixel-channel two-sided Z-test of candidate against a Monte Carlo reference.

    ``z = |candidate - reference| / sigma`` with ``sigma = max(reference_stderr,
    stderr_floor, binomial_stderr_floor(samples, floor_scale))`` (or
    ``sqrt(max(s_ref, floor)^2 + s_cand^2)`` when the candidate is itself a Monte Carlo
    estimate with ``candidate_stderr``), ``p = 2 (1 - Phi(z))`` (or the exact binomial test,
    ``binary``). A pixel-channel is significant when ``p < alpha_per_pixel``; with the Sidak
    correction
    ``alpha_per_pixel = 1 - (1 - alpha)^(1/n)`` over the ``n`` tested values, so that the
    probability that any value of a candidate equal in expectation to the reference is
    flagged is ``alpha``.

    Parameters
    ----------
    reference : array_like
        Reference estimate, ``(H, W)`` or ``(H, W, C)``, linear.
    reference_stderr : array_like
        Its standard error (standard deviation of the estimate, i.e. ``sqrt(var / spp)``),
        same shape, >= 0.
    candidate : array_like
        Image to test, same shape.
    alpha : float, keyword-only
        Significance level in (0, 1): family-wise with ``"sidak"``, per value with
        ``"none"``.
    stderr_floor : float, keyword-only
        Lower bound of the reference's standard error, >= 0, in the images' units: pixels
        where every sample agreed (zero sample variance) would otherwise make any
        difference, down to float rounding, infinitely significant. The default 1e-4 is
        the standard error of a 50 % pixel at 2.5e7 spp (0.5 / sqrt(spp)), so it rarely
        binds where the sample variance is non-zero, and is far above float32 rounding of
        values near 1 (6e-8).
    candidate_stderr : array_like or None, keyword-only
        Standard error of a noisy candidate (same shape); its variance is added.
    correction : {"sidak", "none"}, keyword-only
    full : bool, keyword-only
        Also return the p-value and z maps.

    Returns
    -------
    dict
        ``significant_fraction`` (in [0, 1]), ``significant_count``, ``n_tests``,
        ``alpha_per_pixel``, ``alpha``, ``correction``, ``stderr_floor``; with
        ``full=True`` also ``p_value`` and ``z`` (float64 maps of the input's shape).

    References
    ----------
    .. [1] Z. Sidak, "Rectangular confidence regions for the means of multivariate normal
       distributions", J. Amer. Statist. Assoc. 62(318), 1967.
       DOI: 10.1080/01621459.1967.10482935
    .. [2] A. Jung, J. Hanika, C. Dachsbacher, "Detecting Bias in Monte Carlo Renderers
       using Welch's t-test", JCGT 9(2), 2020. https://jcgt.org/published/0009/02/01/
    .. [3] W. Jakob et al., "Mitsuba 3 renderer", 2022 (its render regression tests,
       ``mitsuba.testing``). https://mitsuba-renderer.org
    """
    if not 0.0 < alpha < 1.0:
        raise MetricError(f"alpha must be in (0, 1), got {alpha!r}")
    if not (np.isfinite(stderr_floor) and stderr_floor >= 0.0):
        raise MetricError(f"stderr_floor must be a finite number >= 0, got {stderr_floor!r}")
    if correction not in CORRECTIONS:
        raise MetricError(f"correction must be one of {', '.join(CORRECTIONS)}, got {correction!r}")
    ref, cand = check_images("reference", reference, "candidate", candidate)
    stderr, _ = check_images(
        "reference_stderr", reference_stderr, "reference", ref, allow_negative=False
    )
    sigma = np.maximum(stderr, stderr_floor)
    if samples is not None:
        floor = binomial_stderr_floor(samples, floor_scale)
        if not np.all(np.isfinite(floor)):
            raise MetricError("samples and floor_scale must be finite")
        sigma = np.maximum(sigma, floor)
    variance = np.square(sigma)
    if candidate_stderr is not None:
        cand_stderr, _ = check_images(
            "candidate_stderr", candidate_stderr, "candidate", cand, allow_negative=False
        )
        variance = variance + np.square(cand_stderr)

    if binary and samples is not None and candidate_stderr is None:
        p_value = _binomial_p_value(ref, cand, samples)
        z = special.erfcinv(np.clip(p_value, 1e-300, 1.0)) * np.sqrt(2.0)
    else:
        diff = np.abs(cand - ref)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(diff == 0, 0.0, diff / np.sqrt(variance))
        # 2 (1 - Phi(z)) = erfc(z / sqrt 2), without the cancellation of 1 - Phi for large z.
        p_value = special.erfc(z / np.sqrt(2.0))
    n = int(p_value.size)
    if correction == "sidak":
        alpha_per_pixel = float(-np.expm1(np.log1p(-alpha) / n))
    else:
        alpha_per_pixel = float(alpha)
    significant = int(np.count_nonzero(p_value < alpha_per_pixel))
    result = {
        "significant_fraction": significant / n,
        "significant_count": significant,
        "n_tests": n,
        "alpha_per_pixel": alpha_per_pixel,
        "alpha": float(alpha),
        "correction": correction,
        "stderr_floor": float(stderr_floor),
    }
    if full:
        result["p_value"] = p_value
        result["z"] = z
    return result


def _binomial_p_value(ref, cand, samples) -> np.ndarray:
    """Two-sided exact binomial p-value of ``k = round(ref * N)`` under ``Binomial(N, cand)``."""
    from scipy import stats

    n = np.broadcast_to(np.rint(np.asarray(samples, dtype=np.float64)), ref.shape)
    k = np.clip(np.rint(ref * n), 0, n)
    # a hypothesised truth of exactly 0 or 1 would make one stray sample infinitely
    # significant; differences below the Jeffreys floor p = 0.5 / (N + 1) carry no meaning
    delta = 0.5 / (n + 1.0)
    c = np.clip(cand, delta, 1.0 - delta)
    lower = stats.binom.cdf(k, n, c)
    upper = stats.binom.sf(k - 1, n, c)
    return np.minimum(1.0, 2.0 * np.minimum(lower, upper))


def noise_floor(metric: Callable, reference_a, reference_b, **kw):
    """A metric's value for a second, independently seeded reference against the first.

    Any candidate score closer to the reference than this is within the reference's own
    Monte Carlo noise. This is ``metric(reference_a, reference_b, **kw)``, named so that
    reports say what the number is.

    Parameters
    ----------
    metric : callable
        A metric of this package, ``metric(reference, candidate, **kw)``.
    reference_a, reference_b : array_like
        Two references rendered with the same settings and different seeds.
    **kw
        Keyword options of ``metric`` (e.g. ``receivers=...`` for shadow metrics).

    Returns
    -------
    object
        Whatever ``metric`` returns.

    References
    ----------
    .. [1] A. Jung, J. Hanika, C. Dachsbacher, "Detecting Bias in Monte Carlo Renderers
       using Welch's t-test", JCGT 9(2), 2020. https://jcgt.org/published/0009/02/01/
    """
    if not callable(metric):
        raise MetricError(f"metric must be callable, got {type(metric).__name__}")
    return metric(reference_a, reference_b, **kw)
