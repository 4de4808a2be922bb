"""The main job: the default sweep spec, the sweep into ``OUT/sweep.db``, the optional
sections (claims, extremes) and the one report, at a small size."""

from __future__ import annotations

import json

import pytest

import raster_models
from oracle.cli.app import main
from oracle.sweeps import mainjob
from oracle.sweeps.spec import expand_spec
from oracle.sweeps.store import SweepStore

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


@pytest.fixture
def sections(monkeypatch):
    """Record the calls of the claims and extremes sections (their own tests run them)."""
    calls = []

    def fake(entry):
        sid = entry[0]

        def run(out, *, cache, quiet, echo, quick):
            calls.append({"id": sid, "out": out, "quick": quick, "cache": cache})
            if sid == "extremes" and fail.get("extremes"):
                raise RuntimeError("extremes broke")
            data = {"section": sid, "cells": 3}
            (out / f"{sid}.json").write_text(json.dumps(data))
            return data

        def render(data):
            return f'<p class="{data["section"]}-fragment">{data["cells"]} cells</p>'

        return run, render

    fail: dict = {}
    monkeypatch.setattr(mainjob, "_load_section", fake)
    return calls, fail


def test_main_job_runs_the_sweep_and_ends_with_one_report(tmp_path, capsys, sections):
    calls, _ = sections
    out = tmp_path / "main"
    assert main(["main", "--scenes", "plate,spot,decal", "--out", str(out), *SMALL]) == 0
    printed = capsys.readouterr().out
    assert str((out / "report.html").resolve()) in printed
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
    assert groups == {("shadow", "plate"), ("shadow", "spot"), ("aa", "decal")}
    assert all(g["fronts"] for g in report["groups"])
    assert len(report["cases"]) == len(rows)
    # the claims and extremes ran in their quick form into the main folder
    assert [(c["id"], c["quick"], c["out"]) for c in calls] == [
        ("claims", True, out),
        ("extremes", True, out),
    ]
    html = (out / "report.html").read_text()
    assert '<p class="claims-fragment">3 cells</p>' in html
    assert '<p class="extremes-fragment">3 cells</p>' in html
    assert html.index('id="fronts"') < html.index('id="claims"') < html.index('id="cases"')
    # a second run finds every case in the store
    assert main(["main", "--scenes", "plate,spot,decal", "--out", str(out), *SMALL]) == 0
    assert f"({len(rows)} already done, 0 done, 0 failed)" in capsys.readouterr().out


def test_a_failing_section_is_in_the_report_and_the_exit_code(tmp_path, capsys, sections):
    _, fail = sections
    fail["extremes"] = True
    out = tmp_path / "main"
    assert main(["main", "--scenes", "spot", "--out", str(out), *SMALL]) == 1
    captured = capsys.readouterr()
    assert "failed: extremes" in captured.err
    html = (out / "report.html").read_text()
    assert "This section failed" in html and "extremes broke" in html


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
