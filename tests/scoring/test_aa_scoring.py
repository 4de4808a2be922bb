"""Scoring anti-aliasing output: colour + coverage of AA techniques, engine coverage masks.

A stand-in AA technique is registered for these tests (the AA models' contract: ``color``
``(H, W, 3)``, ``coverage`` ``(H, W)``, a ``samples`` parameter and a ``cost`` record). It
returns the oracle's own reference (``exact``: every error is 0) or that reference's
coverage rounded to 0/1 (``binary``: one sample at the pixel centre would give at best this),
whose errors follow from the reference by hand.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.cache import ReferenceCache
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.oracle.reference.render import ReferenceSettings
from raster_oracle.oracle.reference.store import get_reference
from raster_oracle.oracle.scoring.score import (
    COVERAGE_FLOOR_RMS,
    COVERAGE_KEYS,
    METRIC_KEYS,
    coverage_metrics,
    coverage_truth,
)
from raster_oracle.raster_models import params, registry
from raster_oracle.raster_models.result import ModelResult

from raster_oracle import raster_models

SCENE = "star"  # spokes against the sky: fractional coverage on hundreds of pixels
W, H = 48, 27
SIZE = ["--width", str(W), "--height", str(H)]
SPP = 16
#: float32 images against float64 sums in the metrics.
TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class FakeAAParams:
    samples: int = params.param(8, source="test", help="samples per pixel", lo=1, hi=16)
    mode: str = params.param(
        "exact", source="test", help="what to return", choices=("exact", "binary")
    )


def _reference(scene, channels):
    settings = ReferenceSettings(spp=SPP, seed=0, channels=channels)
    return get_reference(scene, settings, cache=ReferenceCache(), quiet=True).channels()


def _fake_run(scene, p):
    color_ch = _reference(scene, ("color", "edge", "id"))
    # the truth the scorer uses: the exact channel where valid (issue 28)
    cov_ch = _reference(scene, ("coverage", "coverage_exact", "edge", "id"))
    cov = coverage_truth(cov_ch, "front_coverage")[0]
    color = np.stack([color_ch[f"color.{c}"] for c in "RGB"], -1).astype(np.float32)
    if p.mode == "binary":
        cov = (cov >= 0.5).astype(np.float32)
    n = p.samples
    return ModelResult(
        technique="fake-aa",
        outputs={
            "color": color,
            "coverage": np.ones_like(cov, dtype=np.float32),  # not what models are scored on
            "front_coverage": cov.astype(np.float32),
            "shading_events": np.ones((scene.height, scene.width), np.float32),
            "ties": np.zeros((scene.height, scene.width), np.float32),
        },
        cost={
            "framebuffer_bytes": scene.width * scene.height * n * 8,
            "framebuffer_bytes_by_buffer": {
                "color": scene.width * scene.height * n * 4,
                "depth": scene.width * scene.height * n * 4,
            },
            "shading_events_histogram": [0, scene.width * scene.height],
            "samples": n,
            "width": scene.width,
            "height": scene.height,
        },
        diagnostics={},
        params=dataclasses.asdict(p),
        wall_seconds=0.0,
    )


@dataclasses.dataclass(frozen=True)
class _FakeTechnique(registry.Technique):
    family: str = "aa"


@pytest.fixture
def fake_aa(monkeypatch):
    tech = _FakeTechnique(
        "fake-aa",
        "stand-in AA technique (tests)",
        (),
        FakeAAParams,
        _fake_run,
        ("directional", "spot", "point"),
    )
    monkeypatch.setitem(registry.TECHNIQUES, "fake-aa", tech)
    assert raster_models.TECHNIQUES["fake-aa"] is tech
    return tech


def _score(tmp_path, *args, out="s"):
    out_dir = tmp_path / out
    rc = main(["score", SCENE, *SIZE, "--spp", str(SPP), "--out", str(out_dir), "--quiet", *args])
    return rc, out_dir


def test_coverage_metrics_closed_form():
    """Three edge pixels (fractional reference) and three interior ones, by hand."""
    ref = np.array([[0.0, 0.25, 0.5], [1.0, 0.75, 1.0]], np.float32)
    cand = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.5]], np.float32)
    edge = np.array([[False, False, False], [False, False, True]])
    m = coverage_metrics(ref, cand, edge=edge, aa_samples=4)
    # edge pixels: 0.25 (-0.25), 0.5 (+0.5), 0.75 (+0.25) and the flagged (1, 2) (-0.5)
    edge_rmse = np.sqrt((0.25**2 + 0.5**2 + 0.25**2 + 0.5**2) / 4)
    assert m["coverage_edge_rmse"] == pytest.approx(edge_rmse)
    assert m["coverage_interior_mae"] == 0.0
    assert m["coverage_mae"] == pytest.approx(1.5 / 6)
    assert m["coverage_bias"] == pytest.approx(0.0)
    assert m["coverage_floor_rms"] == COVERAGE_FLOOR_RMS[4] == 0.092
    assert m["coverage_edge_rmse_over_floor"] == pytest.approx(edge_rmse / 0.092)
    none = coverage_metrics(ref, cand, edge=edge, aa_samples=None)
    assert none["coverage_floor_rms"] is None and none["coverage_edge_rmse_over_floor"] is None


def test_exact_aa_technique_scores_zero(tmp_path, fake_aa):
    rc, out = _score(tmp_path, "--technique", "fake-aa", "--set", "samples=8")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["channel"] == "color"
    assert set(METRIC_KEYS) <= set(m)
    for key in ("coverage_mae", "coverage_rmse", "coverage_edge_rmse", "coverage_bias"):
        assert m[key] == 0.0, key
    assert m["coverage_floor_rms"] == 0.057
    assert m["coverage_edge_rmse_over_floor"] == 0.0
    assert m["flip_mean"] == pytest.approx(0.0, abs=TOL)
    assert m["delta_e2000_mean"] == pytest.approx(0.0, abs=TOL)
    assert m["visibility_mae"] is None
    assert m["cost"]["framebuffer_bytes"] == W * H * 8 * 8
    assert m["params"] == {"samples": 8, "mode": "exact"}
    assert {k for k in m["noise_floor"] if k.startswith("coverage_")} >= {"coverage_mae"}
    assert m["coverage_reference"]["channels"] == ["coverage", "coverage_exact", "edge", "id"]
    # star is a triangle scene: scored against the exact coverage, whose noise floor is 0
    assert m["coverage_reference"]["coverage_truth"] == {"truth": "exact", "exact_fraction": 1.0}
    assert m["noise_floor"]["coverage_mae"] == 0.0
    cand = read_exr(out / "candidate.exr")
    assert {"color.R", "color.G", "color.B"} <= set(cand)
    maps = read_exr(out / "error_maps.exr")
    assert "coverage_error" in maps and np.abs(maps["coverage_error"]).max() == 0.0
    assert (out / "coverage_error.png").is_file() and (out / "report.html").is_file()


def test_report_restates_framebuffer_memory(tmp_path, fake_aa):
    """8 samples of RGBA8 colour + D32 depth: 8 * (4 + 4) = 64 bytes a pixel, so
    1280 x 736 * 64 = 60,293,120 bytes (57.5 MiB) and 1920 x 1080 * 64 = 132,710,400 bytes,
    restated from the model's own ``framebuffer_bytes`` at 48 x 27."""
    rc, out = _score(tmp_path, "--technique", "fake-aa", "--set", "samples=8")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["framebuffer_bytes_restated"] == {
        "framebuffer_1280x736_bytes": 60_293_120,
        "framebuffer_1920x1080_bytes": 132_710_400,
    }
    assert m["cost"]["shading_events_histogram"] == [0, W * H]
    case = json.loads((out / "report.json").read_text())["cases"][0]
    assert case["cost"]["framebuffer_1280x736_bytes"] == 60_293_120
    assert case["cost"]["color framebuffer_bytes"] == W * H * 8 * 4
    assert "shading_events_histogram" not in case["cost"]
    assert "57.5 MiB" in (out / "report.html").read_text()


def test_binary_coverage_errors_match_hand_computation(tmp_path, fake_aa):
    rc, out = _score(
        tmp_path, "--technique", "fake-aa", "--set", "samples=1", "--set", "mode=binary"
    )
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    from raster_oracle import scenes

    groups = ("coverage", "coverage_exact", "edge", "id")
    ref = _reference(scenes.load(SCENE, width=W, height=H), groups)
    cov = coverage_truth(ref, "front_coverage")[0]
    err = (cov >= 0.5) - cov
    edge = (ref["edge"] > 0.5) | ((cov > 0) & (cov < 1))
    assert edge.sum() > 50
    edge_rmse = float(np.sqrt(np.mean(err[edge] ** 2)))
    assert m["coverage_edge_rmse"] == pytest.approx(edge_rmse, rel=1e-5)
    assert m["coverage_interior_mae"] == 0.0  # interior pixels are 0 or 1 and stay so
    assert m["coverage_mae"] == pytest.approx(float(np.abs(err).mean()), rel=1e-5)
    assert m["coverage_floor_rms"] == 0.25
    assert m["coverage_edge_rmse_over_floor"] == pytest.approx(edge_rmse / 0.25, rel=1e-5)
    assert m["coverage_edge_rmse"] > 0.05


def test_frames_on_subpixel_pan_add_flicker(tmp_path, fake_aa):
    rc, out = _score(
        tmp_path,
        "--technique",
        "fake-aa",
        "--frames",
        "2",
        "--camera-path",
        "subpixel-pan",
    )
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["flicker"] is not None and m["temporal_error"] is not None
    assert len(m["frames"]) == 2
    assert all(f["coverage_mae"] == 0.0 for f in m["frames"])


def test_engine_coverage_mask(tmp_path):
    from raster_oracle import scenes

    ref = _reference(
        scenes.load(SCENE, width=W, height=H), ("coverage", "coverage_exact", "edge", "id")
    )
    ref["coverage"] = coverage_truth(ref, "coverage")[0].astype(np.float32)  # the truth used
    write_exr(tmp_path / "mask.exr", {"coverage": ref["coverage"]})
    rc, out = _score(tmp_path, "--candidate", str(tmp_path / "mask.exr"), "--channel", "coverage")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["channel"] == "coverage"
    assert m["coverage_mae"] == 0.0 and m["coverage_edge_rmse"] == 0.0
    assert m["coverage_floor_rms"] is None  # an engine's sample count is not known
    assert m["tone_mapping"] is None
    assert "coverage" in read_exr(out / "candidate.exr")
    # a one-sample engine: rounding moves every fractional pixel
    write_exr(tmp_path / "mask1.exr", {"coverage": (ref["coverage"] >= 0.5).astype(np.float32)})
    rc, out1 = _score(
        tmp_path, "--candidate", str(tmp_path / "mask1.exr"), "--channel", "coverage", out="s1"
    )
    assert rc == 0
    assert json.loads((out1 / "metrics.json").read_text())["coverage_edge_rmse"] > 0.05
    # the same 0/1 mask as an 8-bit grey PNG (data, not sRGB-decoded) scores the same
    from PIL import Image

    grey = ((ref["coverage"] >= 0.5) * 255).astype(np.uint8)
    Image.fromarray(grey).save(tmp_path / "mask1.png")
    rc, out2 = _score(
        tmp_path, "--candidate", str(tmp_path / "mask1.png"), "--channel", "coverage", out="s2"
    )
    assert rc == 0
    m1 = json.loads((out1 / "metrics.json").read_text())
    m2 = json.loads((out2 / "metrics.json").read_text())
    assert m2["coverage_edge_rmse"] == pytest.approx(m1["coverage_edge_rmse"], rel=1e-6)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--technique", "fake-aa", "--channel", "visibility"], "produces color and coverage"),
        (["--technique", "shadow-map", "--channel", "coverage"], "produces visibility"),
        (["--technique", "shadow-map", "--channel", "color"], "produces visibility"),
        (["--technique", "fake-aa", "--set", "samples=0"], "samples"),
        (["--technique", "fake-aa", "--set", "mode=sharp"], "mode"),
    ],
)
def test_wrong_channel_or_parameter_exit_2(tmp_path, capsys, fake_aa, args, message):
    rc, out = _score(tmp_path, *args)
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists() or not any(out.iterdir())


def test_bad_coverage_mask_exit_2(tmp_path, capsys):
    mask = np.full((H, W), 1.5, np.float32)
    write_exr(tmp_path / "bad.exr", {"coverage": mask})
    rc, out = _score(tmp_path, "--candidate", str(tmp_path / "bad.exr"), "--channel", "coverage")
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "coverage must be in [0, 1]" in err and len(err.splitlines()) == 1
    assert not out.exists() or not any(out.iterdir())


def test_model_writes_color_rgb(tmp_path, fake_aa):
    out = tmp_path / "m"
    assert main(["model", "fake-aa", SCENE, *SIZE, "--out", str(out)]) == 0
    ch = read_exr(out / "output.exr")
    assert {"color.R", "color.G", "color.B", "coverage", "shading_events", "ties"} <= set(ch)
    assert ch["color.R"].shape == (H, W)
    assert json.loads((out / "model.json").read_text())["cost"]["samples"] == 8


def test_coverage_keys_are_metric_keys():
    assert set(COVERAGE_KEYS) <= set(METRIC_KEYS)
