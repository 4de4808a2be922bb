"""The shipped alpha-test rules as registered techniques (family ``alpha``): ``raster-oracle
model alpha-test ...`` and ``score --technique`` run the study's models
(:mod:`oracle.studies.alpha_coverage`), with their parameters."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.studies import alpha_coverage as ac
from raster_oracle.raster_models.alpha import RULES
from raster_oracle.raster_models.alpha.model import AlphaRasterParams, alpha_raster
from raster_oracle.raster_models.alpha.technique import TECHNIQUE_RULES
from raster_oracle.scenes.catalogue import alpha_foliage as af

from raster_oracle import raster_models as rm
from raster_oracle import scenes

#: The study's presets as registered techniques and parameter values.
AS_TECHNIQUE = {
    "test/box": ("alpha-test", {"mips": "box"}),
    "test/coverage": ("alpha-test", {"mips": "nvtt"}),
    "threejs-a2c/box": ("alpha-threejs-a2c", {}),
    "filament-a2c/box (0.4)": ("alpha-filament-a2c", {}),
    "hashed/box": ("alpha-hashed", {}),
}


def test_every_rule_is_registered_in_the_alpha_family():
    assert set(TECHNIQUE_RULES) == {t for t, f in rm.TECHNIQUES.items() if f.family == "alpha"}
    assert set(TECHNIQUE_RULES.values()) == set(RULES)
    assert rm.family("alpha-test").channels == ("coverage",)
    assert rm.family("alpha-test").coverage_channel == "coverage"
    assert rm.parse_params("alpha-hashed", ["mips=nvtt", "samples=8", "cutoff=0.3"]) == {
        "mips": "nvtt",
        "samples": 8,
        "cutoff": 0.3,
    }
    with pytest.raises(rm.ModelError, match="mips"):
        rm.parse_params("alpha-test", ["mips=trilinear"])
    with pytest.raises(rm.ModelError, match="samples"):
        rm.parse_params("alpha-test", ["samples=3"])


@pytest.fixture(scope="module")
def foliage(mi):
    return scenes.load("alpha-foliage:n=300", width=96, height=54)


def test_registered_models_are_the_studys(foliage):
    """Each registered rule gives the bytes of the study's preset of the same rule."""
    for preset, (technique, values) in AS_TECHNIQUE.items():
        res = rm.run(technique, foliage, samples=2, **values)
        study = alpha_raster(
            foliage.mi_scene,
            foliage.alpha,
            foliage.camera,
            AlphaRasterParams(samples=2, **ac.PRESETS[preset]),
        )
        np.testing.assert_array_equal(res.outputs["coverage"], study["coverage"], err_msg=preset)
        assert res.cost["samples"] == 2 and res.cost["framebuffer_bytes"] == 16
    # an explicit cutoff replaces the material's: above every alpha, nothing is kept
    empty = rm.run("alpha-test", foliage, samples=1, cutoff=1.0).outputs["coverage"]
    assert empty.max() == 0.0


@pytest.mark.slow
def test_registered_models_reproduce_the_studys_figures(foliage):
    """The study's figures at 96 x 54 (tests/test_alpha_study.py), from the techniques: box
    mips lose the near band's foliage, NVTT's keep it, hashed alpha is unbiased."""
    view = ac.FoliageView(foliage.mi_scene, foliage.alpha, foliage.camera)
    truth, depth = ac.truth_and_depth(view, 3)
    band = np.searchsorted(af.band_edges(), depth, side="right") - 1
    near = (band == 0) & (depth > 0)

    def kept(technique, **values):
        cov = rm.run(technique, foliage, **values).outputs["coverage"]
        return cov[near].mean() / truth[near].mean()

    assert kept("alpha-test", mips="box") < 0.05
    assert kept("alpha-test", mips="nvtt") > 0.9
    assert abs(kept("alpha-hashed") - 1.0) < 0.1


def test_opaque_scene_is_its_first_hits(mi):
    """Without alpha-tested shapes every rule keeps every covered sample: MSAA's coverage."""
    plate = scenes.load("plate", width=32, height=18)
    a = rm.run("alpha-threejs-a2c", plate, samples=4).outputs["coverage"]
    b = rm.run("alpha-test", plate, samples=4).outputs["coverage"]
    np.testing.assert_array_equal(a, b)
    assert 0.0 < a.mean() <= 1.0 and set(np.unique(a * 4)) <= {0.0, 1.0, 2.0, 3.0, 4.0}


@pytest.mark.slow
def test_the_two_alpha_claims_reproduce_the_studys_figures(mi):
    """The claims of issue 44 with the registered rules: box mips keep 0.054 of the foliage at
    5-12.6 m and NVTT's 0.99 (docs/research.md, 320 x 180); three.js A2C shrinks by 0.60 px."""
    from raster_oracle.oracle.studies.claims import run as C

    only = ["alpha-box-mips-lose-foliage", "alpha-threejs-a2c-shrinks"]
    rows = {r["id"]: r for r in C.run_claims(None, quick=True, only=only)["claims"]}
    mips = rows["alpha-box-mips-lose-foliage"]
    assert mips["verdict"] == C.REPRODUCED, mips
    band = mips["cases"][1]
    assert band["band_m"][0] == pytest.approx(5.02, abs=0.01)
    assert band["kept_box"] < 0.1 and band["kept_nvtt"] > 0.95
    a2c = rows["alpha-threejs-a2c-shrinks"]
    assert a2c["verdict"] == C.REPRODUCED and -0.7 < a2c["value"]["mean"] < -0.5
    assert abs(a2c["cases"][1]["shift_px"]) < 0.1  # the plain test: no shift


def test_alpha_foliage_section_plots_coverage_kept_per_rule():
    """The section's lines: one a rule, x at each band's geometric mid distance, bands
    without pixels left out; zeros (foliage lost) are drawn on the linear y axis."""
    from raster_oracle.reports.sections import alpha_foliage_section, render_section

    data = {
        "schema": "raster-oracle.studies.alpha-foliage/1",
        "quick": True,
        "resolution": [320, 180],
        "cards": 1000,
        "samples": 4,
        "truth_rays_per_pixel": 16,
        "bands": [[2.0, 8.0], [8.0, 32.0]],
        "pixels": [10, 0],
        "truth": [0.5, None],
        "kept": {"test/box": [0.0, None], "hashed/box": [1.0, None]},
        "closeup_px": 96,
        "silhouette_shift_px": {"test/box": 0.02, "hashed/box": -0.05},
        "wall_seconds": 1.0,
    }
    section = alpha_foliage_section(data)
    assert section["series"] == [
        {"name": "test/box", "x": [4.0], "y": [0.0]},
        {"name": "hashed/box", "x": [4.0], "y": [1.0]},
    ]
    html = render_section(section)
    assert "<svg" in html and "coverage kept" in html and "test/box" in html


def test_model_and_score_commands_run_a_rule(tmp_path, capsys):
    """``raster-oracle model`` and ``score --technique`` take the rules and their parameters;
    the score is on coverage (three.js A2C at 64 x 36 loses most of the foliage: biased low)."""
    import json

    from raster_oracle.oracle.cli.app import main

    small = ["--width", "64", "--height", "36"]
    out = tmp_path / "m"
    scene = "alpha-foliage:n=200"
    args = ["model", "alpha-test", scene, *small, "--set", "mips=nvtt", "--out", str(out)]
    assert main(args) == 0
    record = json.loads((out / "model.json").read_text())
    assert record["params"] == {"samples": 4, "mips": "nvtt", "cutoff": -1.0}
    s = tmp_path / "s"
    args = ["score", "--technique", "alpha-threejs-a2c", scene, *small, "--spp", "4"]
    assert main([*args, "--no-cache", "--quiet", "--out", str(s)]) == 0
    metrics = json.loads((s / "metrics.json").read_text())
    assert metrics["channel"] == "coverage" and metrics["coverage_bias"] < -0.2
    bad = ["model", "alpha-test", scene, *small, "--set", "mips=trilinear", "--out", str(out)]
    assert main(bad) == 2
    assert "mips" in capsys.readouterr().err
