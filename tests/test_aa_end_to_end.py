"""Anti-aliasing end to end through the CLI: model, score, engine candidates, frames, bad input.

``score --technique msaa --set samples=8`` on the star scene scores colour and coverage; the
model's own images, handed back as an engine's EXR (``--candidate FILE --channel color`` or
``coverage``), score exactly the same; ``--frames`` along ``subpixel-pan`` measures flicker,
which 8x MSAA cuts well below no AA. Bad parameters and candidates with the wrong channels
are one line on stderr, exit 2, nothing written.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import scenes
from oracle.cache import ReferenceCache
from oracle.cli import main
from oracle.exr import read_exr, write_exr
from oracle.pipeline import get_reference
from oracle.reference import ReferenceSettings

SCENE = "star"
W, H = 48, 27
SPP = 16
SIZE = ["--width", str(W), "--height", str(H)]
REF = [*SIZE, "--spp", str(SPP), "--quiet"]
#: float32 images against float64 sums in the metrics.
TOL = 1e-6
#: The 8x standard pattern's straight-edge coverage floor (RMS), TECHNIQUES.md.
FLOOR_8X = 0.057
COLOR_KEYS = ("flip_mean", "ssim", "psnr_db", "delta_e2000_mean", "edge_mae", "interior_mae")
COVERAGE_KEYS = ("coverage_mae", "coverage_rmse", "coverage_bias", "coverage_edge_rmse")


def _metrics(folder):
    return json.loads((folder / "metrics.json").read_text())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One model run and the scores built on it (shared by the tests of this module)."""
    base = tmp_path_factory.mktemp("aa_e2e")
    out = {"base": base}
    assert (
        main(["model", "msaa", SCENE, *SIZE, "--set", "samples=8", "--out", str(base / "m")]) == 0
    )
    out["model"] = read_exr(base / "m" / "output.exr")
    for name, args in {
        "msaa8": ["--technique", "msaa", "--set", "samples=8"],
        "noaa": ["--technique", "noaa"],
    }.items():
        assert main(["score", SCENE, *REF, *args, "--out", str(base / name)]) == 0
        out[name] = _metrics(base / name)
    # the model's images handed back as an engine's own EXRs
    col = {f"color.{c}": out["model"][f"color.{c}"] for c in "RGB"}
    write_exr(base / "engine_color.exr", col)
    write_exr(base / "engine_coverage.exr", {"coverage": out["model"]["coverage"]})
    for name, (file, channel) in {
        "engine_color": ("engine_color.exr", "color"),
        "engine_coverage": ("engine_coverage.exr", "coverage"),
    }.items():
        args = ["--candidate", str(base / file), "--channel", channel]
        assert main(["score", SCENE, *REF, *args, "--out", str(base / name)]) == 0
        out[name] = _metrics(base / name)
    return out


def test_msaa_8x_scores_colour_and_coverage(runs):
    m = runs["msaa8"]
    assert m["channel"] == "color" and m["technique"] == "msaa"
    assert m["params"]["samples"] == 8
    assert all(m[k] is not None for k in COLOR_KEYS + COVERAGE_KEYS)
    assert m["coverage_floor_rms"] == FLOOR_8X
    # the scored candidate is the model's output, bit for bit
    cand = read_exr(runs["base"] / "msaa8" / "candidate.exr")
    for c in ("color.R", "color.G", "color.B"):
        assert np.array_equal(cand[c], runs["model"][c]), c
    # coverage error by hand from the reference coverage (same scene, spp and seed)
    loaded = scenes.load(SCENE, width=W, height=H)
    settings = ReferenceSettings(spp=SPP, seed=0, channels=("coverage", "edge", "id"))
    ref = get_reference(loaded, settings, cache=ReferenceCache(), quiet=True).channels()
    err = runs["model"]["coverage"].astype(np.float64) - ref["coverage"]
    assert m["coverage_mae"] == pytest.approx(np.abs(err).mean(), rel=TOL)
    assert m["coverage_bias"] == pytest.approx(err.mean(), abs=TOL)
    # 8x beats the one-sample floor and no AA on every aliasing and colour measure
    n = runs["noaa"]
    assert m["coverage_edge_rmse"] < 0.25 < n["coverage_edge_rmse"]
    for k in ("coverage_mae", "coverage_edge_rmse", "flip_mean", "delta_e2000_mean", "edge_mae"):
        assert m[k] < n[k], k
    assert m["psnr_db"] > n["psnr_db"]
    # memory restated from the model's own accounting: 8 x (RGBA8 + D32) = 64 B/px
    assert m["framebuffer_bytes_restated"]["framebuffer_1280x736_bytes"] == 64 * 1280 * 736


def test_engine_images_score_like_the_model(runs):
    m, col, cov = runs["msaa8"], runs["engine_color"], runs["engine_coverage"]
    assert col["channel"] == "color" and cov["channel"] == "coverage"
    for k in COLOR_KEYS:
        assert col[k] == pytest.approx(m[k], rel=TOL, abs=TOL), k
    assert col["tone_mapping"] == m["tone_mapping"]
    for k in COVERAGE_KEYS:
        assert cov[k] == pytest.approx(m[k], rel=TOL, abs=TOL), k
    assert cov["coverage_floor_rms"] is None  # an engine's sample count is not known


def test_frames_on_subpixel_pan_measure_flicker(tmp_path):
    flicker = {}
    for name, args in {
        "noaa": ["--technique", "noaa"],
        "msaa8": ["--technique", "msaa", "--set", "samples=8"],
    }.items():
        out = tmp_path / name
        rc = main(
            ["score", SCENE, *REF, *args, "--frames", "3", "--camera-path", "subpixel-pan"]
            + ["--out", str(out)]
        )
        assert rc == 0
        m = _metrics(out)
        assert m["camera_path"] == "subpixel-pan" and len(m["frames"]) == 3
        assert m["flicker"] is not None and m["flicker"] >= 0
        flicker[name] = m["flicker"]
    # a quarter-pixel pan flips no-AA edge pixels between 0 and 1; 8 samples flip by 1/8
    assert flicker["msaa8"] < 0.5 * flicker["noaa"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--technique", "msaa", "--set", "samples=3"], "samples must be one of 1, 2, 4, 8, 16"),
        (["--technique", "msaa", "--set", "samples=nan"], "samples"),
        (["--technique", "msaa", "--set", "resolve=sinc"], "resolve"),
        (["--technique", "msaa", "--set", "foo=1"], "unknown parameter 'foo'"),
        (["--technique", "msaa2"], "unknown technique 'msaa2'"),
        (["--technique", "msaa", "--channel", "visibility"], "produces color and coverage"),
        (["--candidate", "{color}", "--channel", "coverage"], "no channel 'coverage'"),
        (["--candidate", "{coverage}", "--channel", "color"], "no channel 'color'"),
    ],
)
def test_bad_parameters_and_candidate_channels_exit_2(tmp_path, capsys, args, message):
    write_exr(tmp_path / "color.exr", {f"color.{c}": np.zeros((H, W), np.float32) for c in "RGB"})
    write_exr(tmp_path / "coverage.exr", {"coverage": np.zeros((H, W), np.float32)})
    args = [
        a.format(color=tmp_path / "color.exr", coverage=tmp_path / "coverage.exr") for a in args
    ]
    out = tmp_path / "out"
    rc = main(["score", SCENE, *REF, *args, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert message in err and len(err.splitlines()) == 1 and err.startswith("raster-oracle: error:")
    assert not out.exists() or not any(out.iterdir())
