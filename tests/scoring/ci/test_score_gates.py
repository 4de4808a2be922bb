"""CI gates of ``score`` (issue 17): metric directions and applicability, failure lines with
numbers, the noise floor judged in each metric's direction, baselines and JUnit XML."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from raster_oracle.metrics import catalog
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.oracle.scoring.score import METRIC_KEYS
from raster_oracle.reports import make_case

import raster_oracle

SIZE = ["--width", "48", "--height", "27"]


@pytest.fixture(scope="module")
def cands(tmp_path_factory):
    """Engine-style candidates of the plate at 48x27: the scoring reference itself (16 spp,
    seed 0: exact), a 4-spp render (noisy) and a flat grey image (bad), as visibility and
    colour EXRs."""
    root = tmp_path_factory.mktemp("cands")
    for name, spp, seed in (("exact", 16, 0), ("noisy", 4, 7)):
        args = ["reference", "plate", *SIZE, "--spp", str(spp), "--seed", str(seed)]
        assert main([*args, "--out", str(root / name), "--quiet"]) == 0
    files = {}
    for name in ("exact", "noisy"):
        ref = read_exr(root / name / "reference.exr")
        files[f"{name}_vis"] = root / f"{name}_vis.exr"
        write_exr(files[f"{name}_vis"], {"visibility": ref["visibility"]})
        files[f"{name}_rgb"] = root / f"{name}_rgb.exr"
        write_exr(files[f"{name}_rgb"], {c: ref[f"color.{c}"] for c in "RGB"})
    files["bad_rgb"] = root / "bad_rgb.exr"
    write_exr(files["bad_rgb"], {c: np.full((27, 48), 0.3, np.float32) for c in "RGB"})
    return files


def _score(tmp_path, capsys, candidate, *extra, out="s"):
    """Run ``score plate --candidate``; returns (exit code, out folder, stdout, stderr)."""
    out_dir = tmp_path / out
    argv = ["score", "plate", *SIZE, "--spp", "16", "--candidate", str(candidate)]
    rc = main([*argv, "--out", str(out_dir), "--quiet", *extra])
    captured = capsys.readouterr()
    return rc, out_dir, captured.out, captured.err


def _metrics(out):
    return json.loads((out / "metrics.json").read_text())


def test_catalog_declares_every_scored_metric():
    assert tuple(k for k, m in catalog.CATALOG.items() if not m.on_request) == METRIC_KEYS
    assert all(k.startswith("conformance_") for k in set(catalog.CATALOG) - set(METRIC_KEYS))
    for m in catalog.CATALOG.values():
        assert m.direction in catalog.DIRECTIONS and m.unit
        assert m.kinds and set(m.kinds) <= set(catalog.KINDS)
    assert catalog.CATALOG["ssim"].direction == "higher"
    assert catalog.CATALOG["psnr_db"].direction == "higher"
    assert catalog.CATALOG["flicker"].min_frames == 2
    assert catalog.CATALOG["misclassified_fraction"].kinds == ("visibility",)


def test_catalog_judges_in_each_direction():
    assert not catalog.within_noise("ssim", 0.93, 0.99)
    assert catalog.within_noise("ssim", 0.995, 0.99)
    assert not catalog.within_noise("psnr_db", 14.0, 45.0)
    assert catalog.within_noise("visibility_mae", 0.001, 0.002)
    assert catalog.within_noise("coverage_bias", -0.001, 0.002)
    assert not catalog.within_noise("coverage_bias", -0.003, 0.002)
    # lower-is-better: worse by more than floor + previous floor
    assert catalog.regressed("visibility_mae", 0.05, 0.001, 0.04, 0.002)
    assert not catalog.regressed("visibility_mae", 0.0429, 0.001, 0.04, 0.002)
    assert not catalog.regressed("visibility_mae", 0.01, 0.001, 0.04, 0.002)  # better
    # SSIM: errors 1 - x; 0.90 vs 0.95 is 0.05 worse > 0.01 + 0.01
    assert catalog.regressed("ssim", 0.90, 0.99, 0.95, 0.99)
    assert not catalog.regressed("ssim", 0.95, 0.99, 0.90, 0.99)
    # PSNR: the MSE behind it, 10**(-x/10): 20 dB (0.01) vs 30 dB (0.001), floors 40 dB
    assert catalog.regressed("psnr_db", 20.0, 40.0, 30.0, 40.0)
    assert not catalog.regressed("psnr_db", 30.0, 40.0, 20.0, 40.0)
    assert catalog.error_of("psnr_db", 20.0) == pytest.approx(0.01)


def test_ssim_fail_below_passes_a_good_image_and_fails_a_bad_one(tmp_path, capsys, cands):
    rc, out, text, _ = _score(
        tmp_path, capsys, cands["exact_rgb"], "--channel", "color", "--fail-below", "ssim=0.9"
    )
    assert rc == 0
    assert re.search(r"^PASS ssim 1 >= 0\.9 \(noise floor 0\.\d+\)$", text, re.M), text
    rc, out, text, err = _score(
        tmp_path,
        capsys,
        cands["bad_rgb"],
        "--channel",
        "color",
        "--fail-below",
        "ssim=0.9",
        out="bad",
    )
    m = _metrics(out)
    assert rc == 1 and m["ssim"] < 0.9 and m["failed"] == ["ssim >= 0.9"]
    line = f"FAIL ssim {m['ssim']:.4g} < 0.9 (noise floor {m['noise_floor']['ssim']:.4g})"
    assert line in text.splitlines(), text
    assert "failed: ssim >= 0.9" in err
    assert m["fail_below"] == {"ssim": 0.9} and m["thresholds"] == {}


def test_failure_line_gives_value_threshold_and_floor(tmp_path, capsys, cands):
    rc, out, text, _ = _score(
        tmp_path,
        capsys,
        cands["noisy_vis"],
        "--channel",
        "visibility",
        "--fail-above",
        "visibility_mae=0.001",
    )
    m = _metrics(out)
    assert rc == 1 and m["failed"] == ["visibility_mae <= 0.001"]
    floor = m["noise_floor"]["visibility_mae"]
    line = f"FAIL visibility_mae {m['visibility_mae']:.4g} > 0.001 (noise floor {floor:.4g})"
    assert line in text.splitlines(), text
    assert m["gates"][0]["line"] == line and not m["gates"][0]["passed"]


@pytest.mark.parametrize(
    ("gate", "message"),
    [
        (["--fail-above", "ssim=0.9"], "ssim is higher-is-better: use --fail-below ssim=0.9"),
        (
            ["--fail-above", "psnr_db=30"],
            "psnr_db is higher-is-better: use --fail-below psnr_db=30",
        ),
        (
            ["--fail-below", "flip_mean=0.1"],
            "flip_mean is lower-is-better: use --fail-above flip_mean=0.1",
        ),
        (["--fail-above", "coverage_floor_rms=0.1"], "cannot be gated"),
        (["--fail-below", "beauty=3"], "unknown metric 'beauty'; choose from visibility_mae"),
    ],
)
def test_gate_against_the_metric_is_exit_2(tmp_path, capsys, cands, gate, message):
    rc, out, _, err = _score(tmp_path, capsys, cands["exact_rgb"], "--channel", "color", *gate)
    assert rc == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize(
    ("candidate", "channel", "gate", "message"),
    [
        (
            "exact_rgb",
            "color",
            "misclassified_fraction=0.01",
            "misclassified_fraction applies to visibility candidates; this run scores color",
        ),
        (
            "exact_vis",
            "visibility",
            "delta_e2000_mean=1",
            "delta_e2000_mean applies to color candidates; this run scores visibility",
        ),
        (
            "exact_vis",
            "visibility",
            "flicker=0.01",
            "flicker needs at least 2 frames; this run scores 1",
        ),
    ],
)
def test_gate_that_does_not_apply_is_exit_2(
    tmp_path, capsys, cands, candidate, channel, gate, message
):
    rc, out, _, err = _score(
        tmp_path, capsys, cands[candidate], "--channel", channel, "--fail-above", gate
    )
    assert rc == 2 and message in err, err
    assert not (out / "metrics.json").exists()


def test_report_judges_the_noise_floor_in_the_metric_direction(tmp_path, capsys, cands):
    img = np.zeros((8, 8), np.float32)
    case = make_case(
        name="c",
        scene="s",
        reference=img,
        candidate=img,
        kind="visibility",
        metrics={"ssim": 0.93, "psnr_db": 14.0, "flip_mean": 0.001, "coverage_bias": -0.1},
        noise_floor={"ssim": 0.99, "psnr_db": 45.0, "flip_mean": 0.002, "coverage_bias": 0.01},
        directions={"ssim": "higher", "psnr_db": "higher", "coverage_bias": "zero"},
    )
    assert case["within_noise"] == ["flip_mean"]
    assert case["directions"] == {"ssim": "higher", "psnr_db": "higher", "coverage_bias": "zero"}
    good = make_case(
        name="c",
        scene="s",
        reference=img,
        candidate=img,
        kind="visibility",
        metrics={"ssim": 0.995, "psnr_db": 50.0},
        noise_floor={"ssim": 0.99, "psnr_db": 45.0},
        directions={"ssim": "higher", "psnr_db": "higher"},
    )
    assert good["within_noise"] == ["ssim", "psnr_db"]
    # the score folder's report: a flat grey image's SSIM/PSNR are not "within noise"
    rc, out, _, _ = _score(tmp_path, capsys, cands["bad_rgb"], "--channel", "color")
    assert rc == 0
    (scored,) = json.loads((out / "report.json").read_text())["cases"]
    assert scored["metrics"]["ssim"] < scored["noise_floor"]["ssim"]
    assert not {"ssim", "psnr_db"} & set(scored["within_noise"])
    page = (out / "report.html").read_text()
    assert 'title="ssim: higher is better"' in page
    assert 'title="flip_mean: lower is better"' in page


def test_baseline_passes_an_equal_run_and_flags_a_worse_one(tmp_path, capsys, cands):
    vis = ["--channel", "visibility"]
    rc, first, _, _ = _score(tmp_path, capsys, cands["exact_vis"], *vis, out="first")
    assert rc == 0
    baseline = str(first / "metrics.json")
    rc, _, text, _ = _score(
        tmp_path, capsys, cands["exact_vis"], *vis, "--baseline", baseline, out="same"
    )
    assert rc == 0 and "REGRESSION" not in text
    assert re.search(r"metrics compared, 0 regressed", text), text
    rc, worse, text, err = _score(
        tmp_path, capsys, cands["noisy_vis"], *vis, "--baseline", baseline, out="worse"
    )
    m, b = _metrics(worse), _metrics(first)
    assert rc == 1 and "visibility_mae" in m["regressions"]
    line = (
        f"REGRESSION visibility_mae {m['visibility_mae']:.4g} (noise floor "
        f"{m['noise_floor']['visibility_mae']:.4g}) vs baseline {b['visibility_mae']:.4g} "
        f"(noise floor {b['noise_floor']['visibility_mae']:.4g})"
    )
    assert line in text.splitlines(), text
    assert "baseline visibility_mae" in err
    # one verdict (issue 25): the regressions are failed checks of metrics.json too
    assert "baseline visibility_mae" in m["failed"] and m["exit_code"] == 1


def test_baseline_of_another_run_or_file_is_exit_2(tmp_path, capsys, cands):
    vis = ["--channel", "visibility"]
    rc, first, _, _ = _score(tmp_path, capsys, cands["exact_vis"], *vis, out="first")
    record = _metrics(first)
    other_size = json.loads(json.dumps(record))
    other_size["reference"]["scene"]["resolution"] = [40, 24]
    other_kind = dict(record, channel="color")
    malformed = json.loads(json.dumps(record))
    malformed["reference"]["scene"]["resolution"] = "48x27"
    bad = {
        "size.json": (json.dumps(other_size), "resolution 40x24 vs 48x27 (baseline vs this"),
        "kind.json": (json.dumps(other_kind), "candidate kind color vs visibility"),
        "malformed.json": (json.dumps(malformed), "resolution is not [width, height]"),
        "corrupt.json": ("{not json", "is not JSON"),
        "foreign.json": (json.dumps({"schema": "junit"}), "is not a raster-oracle metrics"),
        "missing.json": (None, "cannot read it"),
    }
    for name, (text, message) in bad.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        rc, out, _, err = _score(
            tmp_path, capsys, cands["exact_vis"], *vis, "--baseline", str(tmp_path / name)
        )
        assert rc == 2 and message in err, (name, err)
        assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_junit_file_has_one_case_per_gate_with_numbers(tmp_path, capsys, cands):
    vis = ["--channel", "visibility"]
    rc, first, _, _ = _score(tmp_path, capsys, cands["exact_vis"], *vis, out="first")
    junit = tmp_path / "ci" / "gates.xml"
    junit.parent.mkdir()
    gates = ["--fail-above", "visibility_mae=0.001", "--fail-below", "ssim=0.5"]
    rc, out, text, _ = _score(
        tmp_path,
        capsys,
        cands["noisy_vis"],
        *vis,
        *gates,
        "--baseline",
        str(first),
        "--baseline-metrics",
        "all",
        "--junit",
        str(junit),
        out="noisy",
    )
    m = _metrics(out)
    assert rc == 1
    root = ET.parse(junit).getroot()
    (suite,) = root.iter("testsuite")
    cases = suite.findall("testcase")
    n_baseline = sum(g["kind"] == "baseline" for g in m["gates"])
    assert n_baseline >= 5 and len(cases) == 2 + n_baseline == int(suite.get("tests"))
    failures = [c for c in cases if c.find("failure") is not None]
    assert int(suite.get("failures")) == len(failures) == 1 + len(m["regressions"])
    assert {c.get("classname") for c in cases} == {"plate"}
    by_name = {c.get("name"): c for c in cases}
    assert by_name["ssim >= 0.5"].find("failure") is None
    message = by_name["visibility_mae <= 0.001"].find("failure").get("message")
    assert message.startswith(f"FAIL visibility_mae {m['visibility_mae']:.4g} > 0.001")
    regression = by_name["baseline visibility_mae"].find("failure").get("message")
    assert regression.startswith("REGRESSION visibility_mae") and "noise floor" in regression


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"raster-oracle {raster_oracle.__version__}"


def test_model_gates_follow_the_channels_the_model_produces(tmp_path, capsys):
    base = ["score", "plate", *SIZE, "--spp", "16", "--quiet"]
    # an anti-aliasing model is scored on colour and coverage: coverage gates apply
    gates = ["--fail-above", "coverage_bias=0.1", "--fail-below", "coverage_bias=-0.1"]
    rc = main([*base, "--technique", "msaa", "--out", str(tmp_path / "msaa"), *gates])
    text = capsys.readouterr().out
    names = [g["name"] for g in _metrics(tmp_path / "msaa")["gates"]]
    assert rc == 0 and names == ["coverage_bias <= 0.1", "coverage_bias >= -0.1"]
    assert re.search(r"^PASS coverage_bias \S+ >= -0\.1 \(noise floor", text, re.M), text
    # a shadow map produces visibility only: exit 2 before the model runs
    out = tmp_path / "sm"
    rc = main(
        [*base, "--technique", "shadow-map", "--out", str(out), "--fail-above", "coverage_mae=1"]
    )
    err = capsys.readouterr().err
    assert (
        rc == 2 and "coverage_mae applies to coverage candidates; this run scores visibility" in err
    )
    assert not out.exists()


def test_tune_target_must_be_lower_is_better():
    from raster_oracle.oracle.sweeps.tune import TuneError, parse_target

    assert parse_target("visibility_mae<=0.01") == ("visibility_mae", 0.01)
    with pytest.raises(TuneError, match="ssim is higher-is-better"):
        parse_target("ssim<=0.9")


def test_a_null_or_nan_value_cannot_be_judged():
    from raster_oracle.oracle.scoring.ci.checks import GateError
    from raster_oracle.oracle.scoring.ci.gates import evaluate_gates, parse_gates

    record = {"channel": "visibility", "visibility_mae": 0.01, "noise_floor": {}}
    (check,) = evaluate_gates(parse_gates(["visibility_mae=0.02"]), record)
    assert check.passed and check.line == "PASS visibility_mae 0.01 <= 0.02 (noise floor n/a)"
    for value, shown in ((None, "null"), (float("nan"), "nan")):
        record["visibility_mae"] = value
        with pytest.raises(GateError, match=f"visibility_mae is {shown} for this run"):
            evaluate_gates(parse_gates(["visibility_mae=0.02"]), record)


def test_judge_gates_a_record_as_the_cli_does(tmp_path, capsys, cands):
    from raster_oracle.oracle.scoring.ci.checks import GateError
    from raster_oracle.oracle.scoring.ci.gates import judge

    vis = ["--channel", "visibility"]
    _, first, _, _ = _score(tmp_path, capsys, cands["exact_vis"], *vis, out="first")
    _, noisy, _, _ = _score(tmp_path, capsys, cands["noisy_vis"], *vis, out="noisy")
    record = _metrics(noisy)
    verdict = judge(record, fail_above={"visibility_mae": 0.5}, fail_below=["ssim=0.5"])
    assert verdict.exit_code == 0 and [c.name for c in verdict.checks] == [
        "visibility_mae <= 0.5",
        "ssim >= 0.5",
    ]
    assert not verdict and json.dumps(verdict) == "[]"  # a list of the failed checks' names
    verdict = judge(record, baseline=first / "metrics.json")
    assert verdict.exit_code == 1 and "baseline visibility_mae" in verdict.failed
    assert verdict and list(verdict) == verdict.failed
    assert judge(_metrics(first), baseline=_metrics(first)).exit_code == 0
    with pytest.raises(GateError, match="higher-is-better"):
        judge(record, fail_above={"ssim": 0.9})


def test_temporal_gates_on_two_frames_and_a_baseline_of_one_frame(tmp_path, capsys, cands):
    import shutil

    for k in (0, 1):
        shutil.copy(cands["exact_vis"], tmp_path / f"f_{k}.exr")
    pattern = str(tmp_path / "f_{frame}.exr")
    vis = ["--channel", "visibility", "--frames", "2", "--camera-path", "dolly"]
    gates = ["--fail-above", "flicker=10", "--fail-above", "temporal_error=10"]
    rc, two, text, _ = _score(tmp_path, capsys, pattern, *vis, *gates, out="two")
    m = _metrics(two)
    assert rc == 0 and len(m["frames"]) == 2, text
    assert f"PASS flicker {m['flicker']:.4g} <= 10" in text
    assert f"PASS temporal_error {m['temporal_error']:.4g} <= 10" in text
    # a one-frame baseline is another run: exit 2 before rendering, naming the frame counts
    rc, one, _, _ = _score(tmp_path, capsys, cands["exact_vis"], "--channel", "visibility")
    assert rc == 0
    rc, out, _, err = _score(tmp_path, capsys, pattern, *vis, "--baseline", str(one), out="against")
    assert rc == 2 and "frames 1 vs 2" in err and not out.exists(), err


def test_score_folder_gates_baseline_and_junit_per_scene(tmp_path, capsys):
    refs = tmp_path / "refs"
    common = ["--quiet", "--channels", "visibility"]
    for name, spp, seed in (("exact", 4, 0), ("noisy", 1, 5)):
        args = ["reference", "plate", "--spp", str(spp), "--seed", str(seed), *common]
        assert main([*args, "--out", str(refs / name)]) == 0
        (tmp_path / name).mkdir()
        vis = read_exr(refs / name / "reference.exr")["visibility"]
        write_exr(tmp_path / name / "plate.exr", {"visibility": vis})
    base = ["--spp", "4", "--quiet", "--channel", "visibility"]
    first, j1 = tmp_path / "first", tmp_path / "first.xml"
    gate = ["--fail-below", "ssim=0.5", "--junit", str(j1)]
    rc = main(["score-folder", str(tmp_path / "exact"), *base, *gate, "--out", str(first)])
    text = capsys.readouterr().out
    assert rc == 0 and "plate: PASS ssim 1 >= 0.5" in text, text
    (case,) = ET.parse(j1).getroot().iter("testcase")
    assert case.get("classname") == "plate" and case.get("name") == "ssim >= 0.5"
    # a worse run against the first: a failed gate and regressions, scene by scene
    j2 = tmp_path / "worse.xml"
    gate = ["--fail-above", "visibility_mae=0", "--baseline", str(first), "--junit", str(j2)]
    gate += ["--baseline-metrics", "all"]
    out = tmp_path / "worse"
    rc = main(["score-folder", str(tmp_path / "noisy"), *base, *gate, "--out", str(out)])
    captured = capsys.readouterr()
    record = json.loads((out / "plate" / "metrics.json").read_text())
    assert rc == 1 and "visibility_mae" in record["regressions"]
    assert "plate: REGRESSION visibility_mae" in captured.out
    suite = next(ET.parse(j2).getroot().iter("testsuite"))
    n_base = sum(g["kind"] == "baseline" for g in record["gates"])
    assert int(suite.get("tests")) == 1 + n_base and n_base >= 5
    assert int(suite.get("failures")) == 1 + len(record["regressions"])
    combined = json.loads((out / "metrics.json").read_text())
    assert "visibility_mae <= 0" in combined["failed"]["plate"]
    # one scene's metrics.json is not a score-folder baseline: exit 2, nothing written
    bad = ["--baseline", str(first / "plate" / "metrics.json")]
    out = tmp_path / "bad"
    rc = main(["score-folder", str(tmp_path / "noisy"), *base, *bad, "--out", str(out)])
    assert rc == 2 and "is not a score-folder metrics.json" in capsys.readouterr().err
    assert not out.exists()


def test_inferred_kind_decides_which_gates_apply(tmp_path, capsys, cands):
    # RGB is colour: a shadow gate on it is exit 2 (was: exit 0 with every shadow metric null)
    gate = ["--fail-above", "misclassified_fraction=0.01"]
    rc, out, _, err = _score(tmp_path, capsys, cands["exact_rgb"], *gate, out="rgb")
    assert rc == 2 and "this run scores color" in err and not out.exists()
    # a single grey channel is visibility: the same gate is judged
    rc, out, text, _ = _score(tmp_path, capsys, cands["noisy_vis"], *gate, out="grey")
    m = _metrics(out)
    assert m["channel"] == "visibility" and m["misclassified_fraction"] is not None
    assert rc == (1 if m["misclassified_fraction"] > 0.01 else 0)
    assert re.search(r"^(PASS|FAIL) misclassified_fraction \S+ (<=|>) 0\.01 \(noise", text, re.M)


def test_baseline_values_that_are_not_numbers_are_left_out():
    from raster_oracle.oracle.scoring.ci.regression import compare_baseline

    scene = {"name": "plate", "resolution": [48, 27], "light_index": 0}
    mine = {
        "channel": "visibility",
        "reference": {"scene": scene},
        "visibility_mae": 0.05,
        "ssim": 0.9,
        "flip_mean": 0.1,
        "noise_floor": {"visibility_mae": 0.001, "ssim": 0.99, "flip_mean": 0.01},
    }
    old = dict(mine, visibility_mae=0.04, ssim={"bad": 1}, flip_mean="nan")
    verdict = compare_baseline(mine, old)
    assert [c.name for c in verdict.checks] == ["baseline visibility_mae", "baseline flip_mean"]
    assert verdict.failed == ["baseline visibility_mae"]  # 0.05 - 0.04 > 0.001 + 0.001
    # a metric that cannot be compared is a named check (issue 43 item 1), not a note
    (uncompared,) = [c for c in verdict.checks if not c.compared]
    assert uncompared.passed and uncompared.line.startswith("NOT COMPARED baseline flip_mean")


def test_markdown_summary_first_screen_groups_regressions_by_case():
    """An intended change that moves 20 metrics of one case is one first-screen row (its
    count and first metrics), with every check still listed in the details table."""
    from raster_oracle.oracle.scoring.ci.checks import Check, Verdict
    from raster_oracle.oracle.scoring.ci.summary import summary_markdown

    moved = [
        Check(f"baseline m{i}", f"m{i}", False, f"REGRESSION m{i}", kind="baseline")
        for i in range(20)
    ]
    gate = Check("flip_mean <= 0.03", "flip_mean", False, "FAIL flip_mean", kind="gate")
    ok = Check("ssim >= 0.9", "ssim", True, "PASS ssim")
    md = summary_markdown([Verdict("plate/msaa", [*moved, gate]), Verdict("star/msaa", [ok])])
    first = md.split("<details>")[0]
    rows = [line for line in first.splitlines() if line.startswith("| ") and "scene" not in line]
    rows = [r for r in rows if not r.startswith("|---")]
    assert len(rows) == 1
    assert (
        rows[0].startswith("| plate/msaa | 21 |")
        and "20: m0, m1, m2, m3, m4 and 15 more" in rows[0]
    )
    assert "flip\\_mean &lt;= 0\\.03" in rows[0]  # the gate by name (Markdown-escaped)
    assert md.count("| plate/msaa | baseline m") == 20
    assert md.startswith("## raster-oracle: FAIL") and "21 of 22 checks failed" in md
