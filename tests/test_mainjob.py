"""The main job: the default sweep spec, the sweep into ``OUT/sweep.db``, the sections
(claims, extremes, anti-aliasing memory) and the one report with its JSON, at a small size."""

from __future__ import annotations

import json

import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.sweeps import mainjob
from raster_oracle.oracle.sweeps.spec import expand_spec
from raster_oracle.oracle.sweeps.store import SweepStore

from raster_oracle import raster_models

#: Small enough for the shared test machine: 64x36 at 4 spp, in this process.
SMALL = ["--spp", "4", "--width", "64", "--height", "36", "--workers", "0", "--quiet"]


def test_default_spec_is_worth_looking_at_and_covers_every_technique():
    data = mainjob.default_spec()
    assert data["defaults"]["width"] >= 640 and data["defaults"]["height"] >= 360
    exp = expand_spec(data)  # valid as written: every name and value checks out
    assert not exp.skipped
    assert {c.technique for c in exp.cases} == set(raster_models.TECHNIQUES)
    # every technique runs at more than one setting or on more than one scene
    for tech in raster_models.TECHNIQUES:
        mine = [c for c in exp.cases if c.technique == tech]
        assert len({(c.scene, json.dumps(c.params, sort_keys=True)) for c in mine}) > 1, tech


#: The cheapest claim and extremes of the real studies (their own tests run them all).
CLAIMS = ["coherent-lossless"]
EXTREMES = ["baseline"]
EXTREME_MODELS = ["shadow-map", "msaa"]


@pytest.fixture
def sections(monkeypatch):
    """The real claims and extremes studies, restricted to a claim and two models; their
    calls are recorded, and ``fail["extremes"]`` makes the extremes raise."""
    calls = []
    fail: dict = {}
    real_claims, real_extremes = mainjob.run_claims, mainjob.run_extremes
    real_soft, real_alpha = mainjob.run_soft_shadows, mainjob.run_alpha_foliage

    def claims(*, out, cache, quick, only):
        calls.append({"id": "claims", "out": out, "quick": quick, "only": only})
        return real_claims(out, cache=cache, quick=quick, only=only, size=(32, 18))

    def extremes(*, out, cache, quick, extremes):
        calls.append({"id": "extremes", "out": out, "quick": quick, "only": extremes})
        if fail.get("extremes"):
            raise RuntimeError("extremes <broke>")
        return real_extremes(
            out, cache=cache, quick=quick, extremes=extremes, techniques=EXTREME_MODELS
        )

    def soft_shadows(out, *, cache, quick):
        calls.append({"id": "soft_shadows", "out": out, "quick": quick})
        return real_soft(out, cache=cache, quick=quick, size=(32, 18))

    def alpha_foliage(out, *, quick):
        calls.append({"id": "alpha_foliage", "out": out, "quick": quick})
        return real_alpha(out, quick=quick, size=(64, 36))

    monkeypatch.setattr(mainjob, "run_alpha_foliage", alpha_foliage)
    monkeypatch.setattr(mainjob, "run_claims", claims)
    monkeypatch.setattr(mainjob, "run_extremes", extremes)
    monkeypatch.setattr(mainjob, "run_soft_shadows", soft_shadows)
    monkeypatch.setattr(mainjob, "CLAIMS", [c for c in mainjob.CLAIMS if c.id in CLAIMS])
    monkeypatch.setattr(mainjob, "EXTREMES", {k: mainjob.EXTREMES[k] for k in EXTREMES})
    return calls, fail


def test_main_job_runs_the_sweep_and_ends_with_one_report(tmp_path, capsys, sections):
    calls, _ = sections
    out = tmp_path / "main"
    assert main(["main", "--scenes", "plate,spot,decal", "--out", str(out), *SMALL]) == 0
    printed = capsys.readouterr().out
    assert str((out / "report.html").resolve()) in printed
    # its own time by phase at the end, one line per phase, before the report's path
    lines = printed.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("main job by phase: "))
    named = [line.split()[0] for line in lines[head + 1 : head + 1 + len(MAIN_PHASES)]]
    assert named == list(MAIN_PHASES)
    with SweepStore(out / "sweep.db", readonly=True) as store:
        rows = store.rows()
        assert store.integrity_ok()
    assert rows and all(r["status"] == "done" for r in rows)
    assert {r["scene"] for r in rows} == {"plate", "spot", "decal"}
    assert {r["width"] for r in rows} == {64} and {r["spp"] for r in rows} == {4}
    # spot light: shadow-map only; the AA scene: AA techniques only
    assert {r["technique"] for r in rows if r["scene"] == "spot"} == {"shadow-map"}
    assert {r["family"] for r in rows if r["scene"] == "decal"} == {"aa"}
    report = json.loads((out / "report.json").read_text())
    groups = {(g["family"], g["scene"]) for g in report["groups"]}
    assert groups == {("shadow", "plate"), ("soft", "plate"), ("shadow", "spot"), ("aa", "decal")}
    assert all(g["fronts"] for g in report["groups"])
    assert len(report["cases"]) == len(rows)
    # the studies ran in their quick form, a part each (a claim, an extreme), as side tasks
    # of the sweep; their files are written into the main folder
    assert [(c["id"], c["quick"], c["out"], c.get("only")) for c in calls] == [
        ("claims", True, None, CLAIMS),
        ("extremes", True, None, EXTREMES),
        ("soft_shadows", True, None, None),
        ("alpha_foliage", True, None, None),
    ]
    for name in ("claims", "extremes", "soft_shadows", "alpha_foliage"):
        assert (out / f"{name}.json").is_file() and (out / f"{name}.html").is_file()
    html = (out / "report.html").read_text()
    assert "Claims of the seed documents" in html and "Numerical extremes" in html
    assert "Anti-aliasing framebuffer memory" in html
    # SMAA's presets and modes ranked on the AA scene beside no AA, FXAA, MSAA and SSAA
    (ranking,) = [s for s in report["sections"] if s["kind"] == "aa_ranking"]
    (table,) = ranking["data"]["scenes"]
    labels = [r["label"] for r in table["rows"]]
    assert table["scene"] == "decal" and "smaa (preset=ultra, mode=1x)" in labels
    assert {"noaa", "fxaa", "msaa (samples=8)"} <= set(labels)
    assert [r["rank"] for r in table["rows"]] == list(range(1, len(labels) + 1))
    assert "Anti-aliasing ranking" in html
    (soft,) = [s for s in report["sections"] if s["kind"] == "soft_shadows"]
    assert soft["data"]["ranking"]["rows"] and "Light bleeding of moment shadow maps" in html
    (alpha,) = [s for s in report["sections"] if s["kind"] == "alpha_foliage"]
    assert set(alpha["data"]["kept"]) == {s["name"] for s in alpha["series"]}
    assert "coverage kept" in html and "threejs-a2c/box" in html
    assert html.index('id="fronts"') < html.index('id="claims"') < html.index('id="cases"')
    # a second run finds every case in the store
    assert main(["main", "--scenes", "plate,spot,decal", "--out", str(out), *SMALL]) == 0
    assert f"({len(rows)} already done, 0 done, 0 failed)" in capsys.readouterr().out


#: The main job's phases, in the order it prints them (mainjob.timing_record).
MAIN_PHASES = (
    "references",
    "models",
    "metrics",
    "images",
    "sweep",
    "claims",
    "extremes",
    "aa_memory",
    "aa_ranking",
    "soft_shadows",
    "alpha_foliage",
    "report",
)
#: Slack of the phases' sum against the wall time: the phases are disjoint stretches of the
#: job (inline), their sum cannot exceed the wall; the slack only covers clock rounding.
PHASE_SUM_SLACK_S = 1e-3


def test_report_json_holds_every_section_record(tmp_path, sections):
    out = tmp_path / "main"
    assert main(["main", "--scenes", "spot", "--out", str(out), *SMALL]) == 0
    report = json.loads((out / "report.json").read_text())
    # the job's time by phase: in timing.json and in report.json
    timing = report["timing"]
    assert timing == json.loads((out / "timing.json").read_text())
    assert list(timing["phases"]) == list(MAIN_PHASES)
    assert all(v >= 0 for v in timing["phases"].values())
    assert timing["phases"]["references"] > 0 and timing["phases"]["models"] > 0
    assert sum(timing["phases"].values()) <= timing["wall_seconds"] + PHASE_SUM_SLACK_S
    assert timing["sweep_phases"] == "wall seconds in this process"
    found = {s["kind"]: s for s in report["sections"]}
    assert [s["id"] for s in report["sections"]] == [
        "claims",
        "extremes",
        "aa-memory",
        "aa-ranking",
        "soft-shadows",
        "alpha-foliage",
    ]
    assert not any(s["failed"] for s in report["sections"])
    soft = found["soft_shadows"]["data"]
    assert soft == json.loads((out / "soft_shadows.json").read_text())
    # each holds its study's record, as the study wrote it beside the report
    claims = found["claims"]["data"]
    assert claims == json.loads((out / "claims.json").read_text())
    assert [r["id"] for r in claims["claims"]] == CLAIMS
    extremes = found["extremes"]["data"]
    assert extremes == json.loads((out / "extremes.json").read_text())
    assert {(c["extreme"], c["technique"]) for c in extremes["cells"]} == {
        (e, t) for e in EXTREMES for t in EXTREME_MODELS
    }
    # the matrix: one row per extreme, its cells (indices) in the order of the techniques
    (row,) = found["extremes"]["matrix"]
    assert row["extreme"] == "baseline"
    assert [extremes["cells"][i]["technique"] for i in row["cells"]] == extremes["techniques"]
    memory = found["aa_memory"]["data"]
    assert memory["schema"] == "raster-oracle.aa-memory/1"
    assert any(row["label"].startswith("MSAA 8x") for row in memory["rows"])


def test_a_failing_section_is_in_the_report_and_the_exit_code(tmp_path, capsys, sections):
    _, fail = sections
    fail["extremes"] = True
    out = tmp_path / "main"
    assert main(["main", "--scenes", "spot", "--out", str(out), *SMALL]) == 1
    captured = capsys.readouterr()
    assert "failed: extremes" in captured.err
    html = (out / "report.html").read_text()
    assert "This section failed" in html and "extremes &lt;broke&gt;" in html
    report = json.loads((out / "report.json").read_text())
    (failed,) = [s for s in report["sections"] if s["failed"]]
    assert failed["id"] == "extremes" and failed["error"] == "RuntimeError: extremes <broke>"
    # the other sections are still there
    assert [s["id"] for s in report["sections"]] == [
        "claims",
        "extremes",
        "aa-memory",
        "aa-ranking",
        "soft-shadows",
        "alpha-foliage",
    ]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--scenes", "plate,nowhere"], "unknown scene(s) nowhere"),
        (["--width", "64"], "give both --width and --height"),
        (["--workers", "-1"], "--workers"),
    ],
)
def test_bad_main_arguments_exit_2(tmp_path, capsys, args, message):
    out = tmp_path / "main"
    assert main(["main", "--out", str(out), "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert not out.exists()
