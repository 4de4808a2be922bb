"""The Python API (``raster_oracle.api``): keyword functions over the library, documented
exceptions instead of exits, records equal to the command line's."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from raster_oracle.oracle.cli import main

import raster_oracle as ro

W, H, SPP = 48, 27, 8
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def scene():
    return ro.load_scene("plate", width=W, height=H)


def test_import_is_cheap_and_lazy():
    """``import raster_oracle`` loads neither Mitsuba nor Dr.Jit; the API names resolve on
    first use."""
    code = (
        "import sys, raster_oracle as r; heavy = {'mitsuba', 'drjit'} & set(sys.modules); "
        "assert not heavy, heavy; assert callable(r.score_image); "
        "assert issubclass(r.InputError, ValueError) and issubclass(r.ModelError, ValueError); "
        "assert {'reference', 'score_image', 'run_model', 'check'} <= set(dir(r))"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    with pytest.raises(AttributeError):
        ro.no_such_function  # noqa: B018


def test_reference_images(scene):
    ref = ro.reference(scene, spp=SPP, channels=["visibility", "color"])
    assert ref.visibility.shape == ref.visibility_stderr.shape == (H, W)
    assert ref.color.shape == ref.color_stderr.shape == (H, W, 3)
    assert np.array_equal(ref.color[..., 1], ref["color.G"])
    assert ref.meta["spp"] == SPP and ref.meta["seed"] == 0
    assert "coverage" not in ref.channels
    # the same settings give the same bytes, cached or not
    again = ro.reference("plate", width=W, height=H, spp=SPP, channels="visibility", cache=False)
    assert np.array_equal(again.visibility, ref.visibility)


def test_reference_is_the_cli_reference(scene, tmp_path):
    from raster_oracle.oracle.reference.exr import read_exr

    argv = ["reference", "plate", "--width", str(W), "--height", str(H), "--spp", str(SPP)]
    assert main([*argv, "--channels", "visibility", "--out", str(tmp_path)]) == 0
    cli = read_exr(tmp_path / "reference.exr")
    assert np.array_equal(cli["visibility"], ro.reference(scene, spp=SPP).visibility)


def test_exact_candidate_scores_zero_error(scene):
    """The reference itself, scored against itself (same spp and seed): zero error, SSIM 1,
    PSNR at its cap, nothing significant: closed-form values."""
    ref = ro.reference(scene, spp=SPP, channels=["visibility"])
    rec = ro.score_image(scene, ref.visibility, spp=SPP)
    assert rec["schema"] == "raster-oracle/metrics/1" and rec["channel"] == "visibility"
    for key in ("visibility_mae", "visibility_rmse", "misclassified_fraction", "flip_mean"):
        assert rec[key] == 0.0
    assert rec["ssim"] == pytest.approx(1.0) and rec["psnr_db"] == 100.0
    assert rec["significant_fraction"] == 0.0
    assert rec["noise_floor"]["visibility_mae"] > 0.0
    assert rec["delta_e2000_mean"] is None  # a colour metric on a shadow mask
    cov = ro.reference(scene, spp=SPP, channels=["coverage"]).coverage
    rec = ro.score_image(scene, cov, channel="coverage", spp=SPP)
    assert rec["channel"] == "coverage" and rec["coverage_mae"] == 0.0
    assert rec["visibility_mae"] is None


def test_array_candidate_is_the_cli_record(scene, tmp_path):
    """An in-memory candidate gives the record ``score --candidate`` writes for the same
    image in a file (the API writes and scores it through the same code)."""
    from raster_oracle.oracle.reference.exr import write_exr

    mask = ro.run_model("shadow-map", scene, resolution=128).outputs["visibility"]
    rec = ro.score_image(scene, mask, spp=SPP, out=tmp_path / "api")
    write_exr(tmp_path / "mask.exr", {"visibility": mask})
    argv = ["score", "plate", "--width", str(W), "--height", str(H), "--spp", str(SPP)]
    argv += ["--candidate", str(tmp_path / "mask.exr"), "--channel", "visibility"]
    assert main([*argv, "--out", str(tmp_path / "cli")]) == 0
    cli = json.loads((tmp_path / "cli" / "metrics.json").read_text())
    for key in ("visibility_mae", "misclassified_fraction", "ssim", "flip_mean", "noise_floor"):
        assert rec[key] == cli[key]
    assert rec["visibility_mae"] > 0.0
    assert json.loads((tmp_path / "api" / "metrics.json").read_text()) == rec


def test_colour_and_technique_scores(scene):
    ref = ro.reference(scene, spp=SPP, channels=["color"])
    rec = ro.score_image(scene, ref.color * 0.5, spp=SPP)  # half as bright: clearly wrong
    assert rec["channel"] == "color" and rec["visibility_mae"] is None
    assert rec["delta_e2000_mean"] > 1.0 and rec["ssim"] < 1.0
    tech = ro.score_technique("msaa", "star", params={"samples": 2}, width=W, height=H, spp=SPP)
    assert tech["technique"] == "msaa" and tech["params"]["samples"] == 2
    assert tech["coverage_floor_rms"] == 0.159 and tech["cost"]["framebuffer_bytes"] > 0


def _record(**values) -> dict:
    """A minimal visibility record of one frame with noise floors."""
    base = {"schema": "raster-oracle/metrics/1", "channel": "visibility", "frames": None}
    base["reference"] = {"scene": {"name": "plate", "resolution": [W, H], "light_index": 0}}
    base["noise_floor"] = {"visibility_mae": 0.001, "ssim": 0.999}
    return {**base, "delta_e2000_mean": None, **values}


def test_check_closed_form(tmp_path):
    """``check`` is the CLI's gate: closed-form passes, failures, regressions, refusals, and
    the JUnit file of its verdicts."""
    import xml.etree.ElementTree as ET

    record = _record(visibility_mae=0.03, ssim=0.9)
    assert ro.check(record, fail_above={"visibility_mae": 0.05}).exit_code == 0
    verdict = ro.check(record, fail_above={"visibility_mae": 0.02})
    assert verdict.exit_code == 1
    assert verdict.lines == ["FAIL visibility_mae 0.03 > 0.02 (noise floor 0.001)"]
    assert ro.check(record, fail_below={"ssim": 0.95}).failed == ["ssim >= 0.95"]
    assert ro.check(record, fail_below={"ssim": 0.9}).exit_code == 0  # at the bar passes
    # worse than the previous run by more than both floors: a regression; equal: none
    better = _record(visibility_mae=0.01, ssim=0.95)
    assert ro.check(record, baseline=better).failed == ["baseline visibility_mae", "baseline ssim"]
    assert ro.check(record, baseline=record).exit_code == 0
    for bad, why in (
        ({"fail_above": {"delta_e2000_mean": 1.0}}, "applies to color"),
        ({"fail_above": {"ssim": 0.9}}, "--fail-below"),
        ({"fail_above": {"nonsense": 1.0}}, "unknown metric"),
        ({"baseline": _record(visibility_mae=0.01, channel="color")}, "another run"),
    ):
        with pytest.raises(ro.InputError, match=why):
            ro.check(record, **bad)
    ro.write_junit(tmp_path / "junit.xml", [verdict, ro.check(better, fail_below={"ssim": 0.9})])
    root = ET.parse(tmp_path / "junit.xml").getroot()
    assert root.get("tests") == "2" and root.get("failures") == "1"
    ro.write_junit(tmp_path / "one.xml", verdict)
    assert ET.parse(tmp_path / "one.xml").getroot().get("tests") == "1"


def test_errors_are_exceptions_not_exits(scene):
    with pytest.raises(ro.InputError, match="unknown scene"):
        ro.load_scene("no-such-scene")
    with pytest.raises(ro.InputError, match="10x10"):
        ro.score_image(scene, np.zeros((10, 10)), spp=SPP)
    with pytest.raises(ro.InputError, match="NaN"):
        ro.score_image(scene, np.full((H, W), np.nan), spp=SPP)
    with pytest.raises(ro.InputError, match="shape"):
        ro.score_image(scene, np.zeros((H, W, 2)), spp=SPP)
    with pytest.raises(ro.InputError, match="visibility, color or coverage"):
        ro.score_image(scene, np.ones((H, W)), channel="shadow", spp=SPP)
    with pytest.raises(ro.InputError, match="unknown camera path"):
        ro.score_image(scene, [np.ones((H, W))] * 2, camera_path="nope", spp=SPP)
    with pytest.raises(ro.InputError, match="frames=3"):
        ro.score_image(scene, [np.ones((H, W))] * 2, frames=3, spp=SPP)
    with pytest.raises(ro.InputError, match="load_scene"):
        ro.reference(scene, width=10)
    with pytest.raises(ro.InputError, match="seed"):
        ro.reference(scene, seed=-1)
    with pytest.raises(ro.ModelError, match="unknown technique"):
        ro.run_model("no-such-technique", scene)
    with pytest.raises(ro.ModelError):
        ro.score_technique("shadow-map", scene, params={"resolution": -1}, spp=SPP)


def test_uncached_work_leaves_no_scratch_folders(scene, monkeypatch):
    """References rendered without the cache live in scratch folders that the call removes
    (the command line removes them when it ends; a script may run for hours)."""
    from raster_oracle.oracle.reference import cache

    made = []
    real = cache.scratch_dir

    def spy():
        made.append(real())
        return made[-1]

    monkeypatch.setattr(cache, "scratch_dir", spy)
    monkeypatch.setattr("raster_oracle.oracle.reference.store.scratch_dir", spy)
    ro.score_image(scene, np.ones((H, W)), spp=SPP, cache=False)
    assert len(made) == 2  # the reference and the noise-floor reference
    assert not any(folder.exists() for folder in made)


def test_export_folder_is_a_scene(tmp_path):
    """An export folder loads as the command line loads it: the exported size, named after
    its folder; a loaded scene takes no loading options."""
    summary = ro.export("plate", tmp_path / "plate-small", width=W, height=H)
    assert set(summary["shapes"]) == {"ground", "plate"}
    for scene in (tmp_path / "plate-small", tmp_path / "plate-small" / "scene.xml"):
        loaded = ro.load_scene(scene)
        assert (loaded.width, loaded.height, loaded.name) == (W, H, "plate-small")
    with pytest.raises(ro.InputError, match="load_scene"):
        ro.load_scene(loaded, light=0)
