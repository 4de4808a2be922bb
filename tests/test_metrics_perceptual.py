"""FLIP, SSIM, PSNR and CIEDE2000: agreement with the libraries and published values."""

import math

import flip_evaluator
import numpy as np
import pytest
from raster_oracle.metrics import (
    DEFAULT_PPD,
    MetricError,
    delta_e2000,
    delta_e2000_lab,
    exposure_from_reference,
    flip,
    hdr_exposure_range,
    psnr_db,
    ssim,
    tonemap,
)
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

# Our wrapper and a direct flip_evaluator call run the same code on the same float32
# arrays; means agree to float32 summation order.
FLIP_MEAN_RTOL = 1e-6
# FLIP computes its exposure bracket in float32; ours in float64.
EXPOSURE_ATOL = 1e-5
# Sharma et al. publish Delta E 00 rounded to 4 decimals: half a unit in the last place.
SHARMA_ATOL = 5e-5
# White (L* = 100) vs black (L* = 0): Delta E 00 = 100 up to the sRGB white point's
# rounding in colour-science (a* of white ~ 2e-3).
WHITE_BLACK_ATOL = 1e-2

SIZE = (64, 64)


@pytest.fixture(scope="module")
def hdr_pair():
    rng = np.random.default_rng(42)
    ref = rng.lognormal(-0.5, 1.0, (*SIZE, 3)).astype(np.float32)
    cand = (ref * rng.lognormal(0.0, 0.2, ref.shape)).astype(np.float32)
    return ref, cand


# Sharma, Wu, Dalal (2005), Table 1: (Lab1, Lab2, Delta E 00). Pair 14, exactly on the
# |dh'| = 180 degree discontinuity (resolved by float rounding), is left out.
SHARMA_PAIRS = [
    ((50.0000, 2.6772, -79.7751), (50.0000, 0.0000, -82.7485), 2.0425),
    ((50.0000, 3.1571, -77.2803), (50.0000, 0.0000, -82.7485), 2.8615),
    ((50.0000, 2.8361, -74.0200), (50.0000, 0.0000, -82.7485), 3.4412),
    ((50.0000, -1.3802, -84.2814), (50.0000, 0.0000, -82.7485), 1.0000),
    ((50.0000, 0.0000, 0.0000), (50.0000, -1.0000, 2.0000), 2.3669),
    ((50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0009), 7.1792),
    ((50.0000, 2.4900, -0.0010), (50.0000, -2.4900, 0.0011), 7.2195),
    ((50.0000, -0.0010, 2.4900), (50.0000, 0.0009, -2.4900), 4.8045),
    ((50.0000, -0.0010, 2.4900), (50.0000, 0.0011, -2.4900), 4.7461),
    ((50.0000, 2.5000, 0.0000), (50.0000, 0.0000, -2.5000), 4.3065),
    ((50.0000, 2.5000, 0.0000), (73.0000, 25.0000, -18.0000), 27.1492),
    ((50.0000, 2.5000, 0.0000), (61.0000, -5.0000, 29.0000), 22.8977),
    ((50.0000, 2.5000, 0.0000), (56.0000, -27.0000, -3.0000), 31.9030),
    ((50.0000, 2.5000, 0.0000), (58.0000, 24.0000, 15.0000), 19.4535),
    ((50.0000, 2.5000, 0.0000), (50.0000, 3.1736, 0.5854), 1.0000),
    ((60.2574, -34.0099, 36.2677), (60.4626, -34.1751, 39.4387), 1.2644),
    ((63.0109, -31.0961, -5.8663), (62.8187, -29.7946, -4.0864), 1.2630),
    ((61.2901, 3.7196, -5.3901), (61.4292, 2.2480, -4.9620), 1.8731),
    ((35.0831, -44.1164, 3.7933), (35.0232, -40.0716, 1.5901), 1.8645),
    ((22.7233, 20.0904, -46.6940), (23.0331, 14.9730, -42.5619), 2.0373),
    ((36.4612, 47.8580, 18.3852), (36.2715, 50.5065, 21.2231), 1.4146),
    ((90.8027, -2.0831, 1.4410), (91.1528, -1.6435, 0.0447), 1.4441),
    ((90.9257, -0.5406, -0.9208), (88.6381, -0.8985, -0.7239), 1.5381),
    ((6.7747, -0.2908, -2.4247), (5.8714, -0.0985, -2.2286), 0.6377),
    ((2.0776, 0.0795, -1.1350), (0.9033, -0.0636, -0.5514), 0.9082),
]


# --------------------------------------------------------------------------- FLIP


def test_flip_ldr_equals_flip_evaluator(hdr_pair):
    ref, cand = hdr_pair
    e = exposure_from_reference(ref)
    ours, error_map = flip(ref, cand, mode="LDR", full=True)
    expected_map, expected, _ = flip_evaluator.evaluate(
        tonemap(ref, exposure=e),
        tonemap(cand, exposure=e),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        parameters={"ppd": DEFAULT_PPD},
    )
    assert ours == pytest.approx(expected, rel=FLIP_MEAN_RTOL)
    assert error_map.shape == SIZE and error_map.dtype == np.float32
    assert float(error_map.mean()) == pytest.approx(ours, rel=1e-5)
    np.testing.assert_allclose(error_map, expected_map[..., 0], atol=1e-4)


def test_flip_hdr_equals_flip_evaluator_with_fixed_bracket(hdr_pair):
    ref, cand = hdr_pair
    bracket = hdr_exposure_range(ref)
    ours = flip(ref, cand, mode="HDR", exposure_range=bracket)
    _, expected, used = flip_evaluator.evaluate(
        ref,
        cand,
        "HDR",
        applyMagma=False,
        parameters={"ppd": DEFAULT_PPD, "startExposure": bracket[0], "stopExposure": bracket[1]},
    )
    assert ours == pytest.approx(expected, rel=FLIP_MEAN_RTOL)
    assert used["startExposure"] == pytest.approx(bracket[0], abs=EXPOSURE_ATOL)


@pytest.mark.parametrize("shape", [(64, 64, 3), (33, 31, 3), (10, 10, 3), (5, 7, 3)])
def test_hdr_exposure_range_matches_flip(shape):
    # FLIP's own automatic bracket: start from the maximum, stop from the upper median.
    rng = np.random.default_rng(sum(shape))
    ref = (rng.random(shape) ** 3 * 10).astype(np.float32)
    _, _, used = flip_evaluator.evaluate(ref, ref, "HDR", applyMagma=False)
    start, stop = hdr_exposure_range(ref)
    assert start == pytest.approx(used["startExposure"], abs=EXPOSURE_ATOL)
    assert stop == pytest.approx(used["stopExposure"], abs=EXPOSURE_ATOL)


def test_hdr_exposure_range_mostly_black_and_black():
    ref = np.zeros((8, 8, 3), np.float32)
    assert hdr_exposure_range(ref) == (0.0, 0.0)
    ref[0, :3] = np.array([1.0, 2.0, 4.0])[:, None]  # 3 grey pixels of 64 lit
    start, stop = hdr_exposure_range(ref)
    # Start from the maximum (4), stop from the median of the lit pixels (2): one stop apart.
    assert stop - start == pytest.approx(1.0)


def test_flip_identity_is_zero_and_grey_is_accepted(hdr_pair):
    ref, _ = hdr_pair
    assert flip(ref, ref, mode="HDR") == 0.0
    assert flip(ref[..., 1], ref[..., 1]) == 0.0


def test_flip_rgba_scores_rgb_only(hdr_pair):
    ref, cand = hdr_pair
    alpha = np.random.default_rng(0).random((*SIZE, 1)).astype(np.float32)
    with_alpha = flip(np.concatenate([ref, alpha], -1), np.concatenate([cand, 1 - alpha], -1))
    assert with_alpha == flip(ref, cand)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"mode": "hdr"}, "mode must be one of LDR, HDR, got 'hdr'"),
        ({"ppd": 0.0}, "ppd must be a positive number"),
        ({"mode": "HDR", "exposure_range": (2.0, 1.0)}, "start <= stop"),
        ({"mode": "HDR", "exposure_range": 3.0}, "exposure_range must be a pair"),
        ({"tone_mapper": "hable"}, "tone_mapper must be one of aces, reinhard, clip"),
        ({"exposure_range": (0.0, 1.0)}, "exposure_range is used with mode='HDR' only"),
        ({"mode": "HDR", "exposure": 1.0}, "exposure is used with mode='LDR' only"),
    ],
)
def test_flip_rejects_bad_options(kwargs, match):
    img = np.ones((16, 16, 3), np.float32)
    with pytest.raises(MetricError, match=match):
        flip(img, img, **kwargs)


def test_flip_system_exit_becomes_metric_error(capsys, monkeypatch):
    """flip_evaluator prints its complaint and exits: flip() raises it as one MetricError."""

    def rejects(*args, **kwargs):
        print("Invalid tone mapper:\n bogus")
        raise SystemExit(1)

    monkeypatch.setattr(flip_evaluator, "evaluate", rejects)
    img = np.ones((16, 16, 3), np.float32)
    with pytest.raises(MetricError, match="flip_evaluator rejected its arguments: Invalid tone"):
        flip(img, img)
    assert capsys.readouterr().out == ""


def test_flip_hdr_rejects_negative_radiance():
    img = np.ones((16, 16, 3), np.float32)
    bad = img.copy()
    bad[0, 0, 0] = -1.0
    with pytest.raises(MetricError, match="candidate must be non-negative, got 1 negative"):
        flip(img, bad, mode="HDR")


# --------------------------------------------------------------------------- SSIM, PSNR


def test_ssim_equals_skimage(hdr_pair):
    ref, cand = hdr_pair
    e = exposure_from_reference(ref)
    a, b = tonemap(ref, exposure=e), tonemap(cand, exposure=e)
    expected, expected_map = structural_similarity(
        a,
        b,
        data_range=1.0,
        channel_axis=-1,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        full=True,
    )
    value, ssim_map = ssim(ref, cand, full=True)
    assert value == pytest.approx(expected, rel=1e-12)
    np.testing.assert_array_equal(ssim_map, expected_map.astype(np.float32))
    assert ssim(ref, ref) == pytest.approx(1.0)


def test_ssim_and_psnr_symmetric_with_fixed_exposure(hdr_pair):
    ref, cand = hdr_pair
    assert ssim(ref, cand, exposure=0.0) == pytest.approx(ssim(cand, ref, exposure=0.0))
    assert psnr_db(ref, cand, exposure=0.0) == pytest.approx(psnr_db(cand, ref, exposure=0.0))


def test_psnr_equals_skimage_and_identity_is_inf(hdr_pair):
    ref, cand = hdr_pair
    e = exposure_from_reference(ref)
    expected = peak_signal_noise_ratio(
        tonemap(ref, exposure=e), tonemap(cand, exposure=e), data_range=1.0
    )
    assert psnr_db(ref, cand) == pytest.approx(expected, rel=1e-12)
    assert psnr_db(ref, ref) == math.inf


def test_psnr_closed_form():
    # clip + exposure 0 on values already in [0, 1]: MSE of the sRGB-encoded images.
    a = np.zeros((8, 8), np.float32)
    b = np.full((8, 8), 1.0, np.float32)
    b[:4] = 0.0  # half the pixels differ by 1 -> MSE 0.5 -> 10 log10(2) dB
    assert psnr_db(a, b, exposure=0.0, tone_mapper="clip") == pytest.approx(10 * math.log10(2))


def test_ssim_small_image_is_a_metric_error():
    img = np.ones((5, 5, 3), np.float32)
    with pytest.raises(MetricError, match="at least 11 x 11"):
        ssim(img, img)


# --------------------------------------------------------------------------- CIEDE2000


@pytest.mark.parametrize(("lab1", "lab2", "expected"), SHARMA_PAIRS)
def test_delta_e2000_lab_sharma(lab1, lab2, expected):
    assert float(delta_e2000_lab(lab1, lab2)) == pytest.approx(expected, abs=SHARMA_ATOL)


def test_delta_e2000_lab_vectorized_and_symmetric():
    a = np.array([p[0] for p in SHARMA_PAIRS])
    b = np.array([p[1] for p in SHARMA_PAIRS])
    expected = np.array([p[2] for p in SHARMA_PAIRS])
    np.testing.assert_allclose(delta_e2000_lab(a, b), expected, atol=SHARMA_ATOL)
    np.testing.assert_allclose(delta_e2000_lab(b, a), delta_e2000_lab(a, b), rtol=1e-12)
    assert np.all(delta_e2000_lab(a, a) == 0)


def test_delta_e2000_white_black_and_identity(hdr_pair):
    white = np.ones((4, 4, 3), np.float32)
    black = np.zeros((4, 4, 3), np.float32)
    value, de_map = delta_e2000(white, black, exposure=0.0, tone_mapper="clip", full=True)
    assert value == pytest.approx(100.0, abs=WHITE_BLACK_ATOL)
    assert de_map.shape == (4, 4) and de_map.dtype == np.float32
    ref, _ = hdr_pair
    assert delta_e2000(ref, ref) == 0.0


def test_delta_e2000_lab_rejects_bad_shapes():
    with pytest.raises(MetricError, match=r"lab_a and lab_b must have shape \(\.\.\., 3\)"):
        delta_e2000_lab(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(MetricError, match="lab_a and lab_b must have the same shape"):
        delta_e2000_lab(np.zeros((4, 3)), np.zeros((5, 3)))


# ---------------------------------------------------------------------- the reference's side
def _sides_cleared(monkeypatch):
    from raster_oracle.metrics import perceptual

    monkeypatch.setattr(perceptual, "_SIDES", type(perceptual._SIDES)())
    return perceptual


def test_a_kept_reference_side_gives_the_bytes_of_a_fresh_one(monkeypatch):
    """Each candidate judged against a kept reference side scores exactly as with the side
    computed afresh (the memo cleared before every call), and the side is kept once."""
    perceptual = _sides_cleared(monkeypatch)
    rng = np.random.default_rng(7)
    ref = (rng.random((24, 32, 4)) * 3.0).astype(np.float32)[..., :3]  # a strided view
    cands = [ref * 1.05, np.clip(ref + rng.normal(0, 0.1, ref.shape), 0, None)]

    def scores(cand):
        de, de_map = delta_e2000(ref, cand, full=True)
        fl, fl_map = flip(ref, cand, full=True)
        return (de, de_map.tobytes(), fl, fl_map.tobytes(), ssim(ref, cand), psnr_db(ref, cand))

    kept = [scores(c) for c in cands]
    assert len(perceptual._SIDES) == 1
    (side,) = perceptual._SIDES.values()
    assert "lab" in side and not side["display"].flags.writeable
    fresh = []
    for c in cands:
        perceptual._SIDES.clear()
        fresh.append(scores(c))
    assert kept == fresh


def test_reference_sides_are_keyed_by_content_and_trimmed_to_their_budget(monkeypatch):
    perceptual = _sides_cleared(monkeypatch)
    a = np.full((16, 16, 3), 0.25)
    b = a.copy()
    b[3, 4, 1] = 0.5  # one value apart: another reference
    assert perceptual._reference_side(a, None, "aces") is perceptual._reference_side(
        a.copy(), None, "aces"
    )
    side_b = perceptual._reference_side(b, None, "aces")
    assert (
        side_b["display"].tobytes()
        != perceptual._reference_side(a, None, "aces")["display"].tobytes()
    )
    assert perceptual._reference_side(a, 1.0, "aces") is not perceptual._reference_side(
        a, None, "aces"
    )
    assert len(perceptual._SIDES) == 3
    one = perceptual._side_bytes(side_b)
    monkeypatch.setattr(perceptual, "REFERENCE_SIDE_BYTES", 2 * one)
    perceptual._reference_side(np.zeros((16, 16, 3)), None, "aces")
    assert len(perceptual._SIDES) == 2  # the oldest dropped
