"""The perceptual sequence score (issue 36): ColorVideoVDP's JOD through ``metrics.video``,
its catalogue entry, and the torchvision stand-in's blur. The tests that run cvvdp are
skipped when the extra ``raster-oracle[video]`` is not installed."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.metrics import catalog
from raster_oracle.metrics import video as V

WHY = V.unavailable()
needs_cvvdp = pytest.mark.skipif(WHY is not None, reason=WHY or "")


def test_catalogue_entry_and_its_error():
    m = catalog.metric("cvvdp_jod")
    assert m.direction == "higher" and m.min_frames == 2 and m.kinds == ("color",)
    assert catalog.error_of("cvvdp_jod", 10.0) == 0.0
    assert catalog.error_of("cvvdp_jod", 8.5) == 1.5
    # a JOD 0.3 below the baseline's, with floors of 0.05 each: a regression
    assert catalog.regressed("cvvdp_jod", 9.2, 9.95, 9.5, 9.95)
    assert not catalog.regressed("cvvdp_jod", 9.45, 9.95, 9.5, 9.95)


def test_missing_extra_is_one_line():
    assert "\n" not in V.MISSING and "raster-oracle[video]" in V.MISSING


def _frames(t=4, h=36, w=64):
    y, x = np.mgrid[0:h, 0:w]
    base = 0.5 + 0.3 * np.sin(x / 5.0)[..., None] * np.ones(3)
    return np.stack([np.roll(base, k, axis=1) for k in range(t)]).astype(np.float32)


@needs_cvvdp
def test_identical_sequences_score_ten_and_noise_lowers_it():
    ref = _frames()
    rng = np.random.default_rng(3)
    assert V.cvvdp_jod(ref, ref, ppd=40.0) == pytest.approx(10.0, abs=1e-4)
    jods = [
        V.cvvdp_jod(ref, np.clip(ref + s * rng.standard_normal(ref.shape), 0, 1), ppd=40.0)
        for s in (0.01, 0.04, 0.12)
    ]
    assert 10.0 > jods[0] > jods[1] > jods[2]


def test_shape_mismatch_and_single_pixels_are_value_errors():
    with pytest.raises(ValueError, match="cvvdp_jod"):
        V.cvvdp_jod(np.zeros((2, 4, 4, 3)), np.zeros((2, 4, 5, 3)), ppd=40.0)
    with pytest.raises(ValueError, match="2x2"):  # the package fails on one pixel
        V.cvvdp_jod(np.zeros((2, 1, 1, 3)), np.zeros((2, 1, 1, 3)), ppd=40.0)


def test_torchvision_standin_blur_is_the_sampled_gaussian():
    torch = pytest.importorskip("torch")
    from scipy.ndimage import gaussian_filter

    saved = {k: v for k, v in __import__("sys").modules.items() if k.startswith("torchvision")}
    try:
        V._torchvision_standin()
        from torchvision.transforms import GaussianBlur

        img = np.random.default_rng(0).random((2, 1, 20, 30))
        got = GaussianBlur(13, 3).forward(torch.from_numpy(img)).numpy()
    finally:
        import sys

        for k in [k for k in sys.modules if k.startswith("torchvision")]:
            del sys.modules[k]
        sys.modules.update(saved)
    # torchvision: kernel 13 = radius 6 = 2 sigma, reflect padding without edge repeat
    want = gaussian_filter(img, sigma=(0, 0, 3, 3), truncate=2.0, mode="mirror")
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("extra", ["installed", "absent"])
def test_smaa_t2x_sequence_is_scored_with_ghosting_and_jod(tmp_path, capsys, monkeypatch, extra):
    # SMAA T2x over `slide` scored like the taa family: the temporal metrics, and JOD with
    # its noise floor when the extra is installed, else null and one line (a gate on it: 2)
    from raster_oracle.oracle.cli.app import main

    if extra == "installed" and WHY is not None:
        pytest.skip(WHY)
    if extra == "absent":
        monkeypatch.setattr(V, "unavailable", lambda: V.MISSING)
    out = tmp_path / "t2x"
    args = ["score", "slide", "--width", "32", "--height", "18", "--spp", "4", "--frames", "3",
            "--technique", "smaa", "--set", "mode=t2x", "--out", str(out)]  # fmt: skip
    code = main([*args, "--fail-below", "cvvdp_jod=1"])
    err = capsys.readouterr().err
    if extra == "absent":
        assert code == 2 and err.count(V.MISSING) >= 1
        assert main(args) == 0
    else:
        assert code == 0
    rec = json.loads((out / "metrics.json").read_text())
    for key in ("steady_error", "ghosting_error", "history_error", "flicker_ratio"):
        assert rec[key] is not None, key
    if extra == "installed":
        assert 1.0 < rec["cvvdp_jod"] <= 10.0
        assert rec["cvvdp_jod"] < rec["noise_floor"]["cvvdp_jod"] <= 10.0
    else:
        assert rec["cvvdp_jod"] is None
