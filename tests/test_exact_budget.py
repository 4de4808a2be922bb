"""The exact-coverage budget (issue 35): a deterministic cost estimate before the work;
over budget the group is skipped for that view with one line, recorded, and coverage is
scored against the Monte Carlo truth."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr
from raster_oracle.oracle.reference.render import EXACT_BUDGET_S, ReferenceSettings
from raster_oracle.scenes.geometry.exact_coverage import (
    OverBudget,
    estimate_cost,
    exact_coverage_of,
    scene_triangle_set,
)

from raster_oracle import scenes

SMALL = ["--width", "48", "--height", "27", "--quiet", "--no-cache", "--spp", "4"]


def test_estimate_is_deterministic_and_grows_with_overlap():
    """Same scene, same estimate; five times the blades on the same ground gives more than
    five times the overlapping pairs (density squared), and the estimate does not depend
    on the film's resolution."""
    small = scenes.load("meadow:n=2000", width=64, height=36)
    e1 = estimate_cost(small.camera, scene_triangle_set(small))
    assert e1 == estimate_cost(small.camera, scene_triangle_set(small))
    big = scenes.load("meadow:n=10000", width=64, height=36)
    e5 = estimate_cost(big.camera, scene_triangle_set(big))
    assert e5["pairs"] > 10 * e1["pairs"] and e5["seconds"] > 5 * e1["seconds"]
    hi = scenes.load("meadow:n=2000", width=256, height=144)
    e_hi = estimate_cost(hi.camera, scene_triangle_set(hi))
    assert abs(e_hi["triangles"] - e1["triangles"]) < 0.05 * e1["triangles"]
    assert 0.5 < e_hi["pairs"] / e1["pairs"] < 2.0


def test_over_budget_raises_before_the_work():
    loaded = scenes.load("meadow:n=500", width=32, height=18)
    centre = np.zeros(32 * 18, np.int64)
    with pytest.raises(OverBudget, match=r"estimated .* > budget 0 s"):
        exact_coverage_of(loaded.camera, scene_triangle_set(loaded), centre, budget=0.0)


def test_reference_skips_exact_coverage_over_budget_with_one_line(tmp_path, capsys):
    out = tmp_path / "ref"
    rc = main(["reference", "meadow:n=300", "--out", str(out), "--exact-budget", "0", *SMALL])
    assert rc == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "coverage_exact" in line]
    assert len(err) == 1 and "skipped" in err[0] and "--exact-budget" in err[0]
    record = json.loads((out / "reference.json").read_text())["coverage_exact"]
    assert record["decision"] == "skipped: over budget" and record["budget_seconds"] == 0.0
    assert record["estimate"]["seconds"] > 0 and record["estimate"]["triangles"] > 0
    ch = read_exr(out / "reference.exr")
    assert not ch["coverage_exact_valid"].any()
    # the default budget computes it, and says so
    out2 = tmp_path / "ref2"
    assert main(["reference", "meadow:n=300", "--out", str(out2), *SMALL]) == 0
    record = json.loads((out2 / "reference.json").read_text())["coverage_exact"]
    assert record["decision"] == "computed" and record["budget_seconds"] == EXACT_BUDGET_S
    assert record["method"] == "polygons" and record["valid_fraction"] == 1.0  # small: as before


def test_score_over_budget_uses_the_monte_carlo_truth(tmp_path):
    out = tmp_path / "s"
    args = ["score", "meadow:n=300", "--technique", "msaa"]
    rc = main([*args, "--exact-budget", "0", "--out", str(out), *SMALL])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["coverage_reference"]["coverage_truth"]["truth"] == "monte carlo"
    assert m["noise_floor"]["coverage_mae"] > 0.0  # the Monte Carlo truth's noise floor
    out2 = tmp_path / "s2"
    assert main([*args, "--out", str(out2), *SMALL]) == 0
    m2 = json.loads((out2 / "metrics.json").read_text())
    assert m2["coverage_reference"]["coverage_truth"] == {"truth": "exact", "exact_fraction": 1.0}


def test_default_budget_leaves_cache_keys_as_they_were():
    """The default budget is not in the key (every cached reference stays valid); another
    budget is, when the exact group is asked for."""
    base = ReferenceSettings(spp=4).validate()
    assert "exact_budget" not in base.key_record()
    other = ReferenceSettings(spp=4, exact_budget=5.0).validate()
    assert other.key_record()["exact_budget"] == 5.0
    no_exact = ReferenceSettings(spp=4, channels=("color",), exact_budget=5.0).validate()
    assert "exact_budget" not in no_exact.key_record()


def test_bad_budget_is_one_line_and_exit_2(tmp_path, capsys):
    rc = main(["reference", "plate", "--exact-budget", "-1", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--exact-budget" in err[0]
    assert "coverage_exact, color" in main_help()


def main_help() -> str:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["reference", "--help"])
    return " ".join(buf.getvalue().split())


def test_bench_scale_prints_every_phase(capsys):
    """``bench scale`` (tiny): per size, every phase with seconds, peak memory and its ratio to
    the tracing (1 for the tracing itself), and the exact coverage's decision."""
    argv = ["bench", "scale", "--sizes", "300", "--width", "48", "--height", "27"]
    assert main([*argv, "--spp", "2", "--only", "fxaa", "--quiet"]) == 0
    figures = json.loads(capsys.readouterr().out)
    rec = figures["sizes"]["300"]
    assert rec["scene"] == "meadow:n=300" and figures["resolution"] == [48, 27]
    phases = rec["phases"]
    assert list(phases) == [
        "loading",
        "tracing",
        "coverage_mc",
        "coverage_exact",
        "fxaa",
        "metrics",
    ]
    assert phases["tracing"]["ratio_to_tracing"] == 1.0
    assert all(p["seconds"] > 0 and p["peak_gb"] > 0.01 for p in phases.values())
    assert rec["coverage_exact"]["decision"] == "computed"
    assert main(["bench", "scale", "--sizes", "x"]) == 2


def test_the_noise_floor_reference_of_a_skipped_view_says_nothing_new(tmp_path, capsys):
    """``score`` renders the view twice (the reference and its noise floor): one line."""
    out = tmp_path / "s"
    argv = ["score", "meadow:n=300", "--technique", "fxaa", "--exact-budget", "0"]
    assert main([*argv, "--out", str(out), *SMALL]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "coverage_exact" in line]
    assert len(err) == 1, err
