"""Score an engine's own output end to end, as an engine team's CI would (issue 17).

A built-in scene is exported (``export``), rendered by an independent engine of our own
(``tests/engine_raster.py``: a NumPy z-buffer rasterizer with a shadow map and 4 samples a
pixel, none of the oracle's code), written as engine-style layered EXRs (``shadow.Y``,
``msaa.R/G/B``, ``msaa.coverage``) and a grey PNG shadow mask, scored with the command line
and the Python API, and gated with ``--fail-above``, ``--fail-below``, ``--baseline`` and
``--junit``. Exit codes: 0 pass, 1 a gate or baseline failed, 2 bad input.
"""

from __future__ import annotations

import json
import re
import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from engine_raster import render, write_engine_exr, write_grey_png
from raster_oracle.oracle.cli import main

import raster_oracle as ro

SPP = ["--spp", "16"]


@pytest.fixture(scope="module")
def engine(tmp_path_factory):
    """The export of ``plate`` at 96x54, the engine's good frame and a broken one (its
    shadow pass lost: every receiver lit), as files an engine writes."""
    root = tmp_path_factory.mktemp("engine")
    export = root / "export"
    assert main(["export", "plate", "--width", "96", "--height", "54", "--out", str(export)]) == 0
    good = render(export)
    broken = dict(good, shadow=np.ones_like(good["shadow"]))
    write_engine_exr(root / "good.exr", good)
    write_engine_exr(root / "broken.exr", broken)
    write_grey_png(root / "shadow.png", good["shadow"])
    write_grey_png(root / "broken.png", broken["shadow"])
    return {"root": root, "export": export, "scene": str(export / "scene.xml"), "good": good}


def _said(capsys) -> str:
    """What the command printed, stdout and stderr (gate lines go to stdout, the summary of
    failures to stderr)."""
    said = capsys.readouterr()
    return said.out + said.err


def _score(engine, candidate, *extra, out="score"):
    folder = engine["root"] / out
    argv = ["score", engine["scene"], "--candidate", str(engine["root"] / candidate)]
    code = main([*argv, *SPP, "--out", str(folder), *extra])
    record = None
    if (folder / "metrics.json").is_file():
        record = json.loads((folder / "metrics.json").read_text())
    return code, record


def test_engine_agrees_with_the_reference(engine):
    """The independent engine is a faithful renderer: its shadow mask, colour and coverage
    are close to the oracle's reference (a wrong engine would make the gates meaningless)."""
    ref = ro.reference(engine["export"], spp=16, channels=["visibility", "coverage", "color"])
    good = engine["good"]
    assert good["shadow"].shape == ref.visibility.shape == (54, 96)
    assert 0.02 < 1.0 - ref.visibility.mean() < 0.2  # the plate's shadow is in view
    assert np.abs(good["shadow"] - ref.visibility).mean() < 0.01
    assert np.abs(good["coverage"] - ref.coverage).mean() < 0.01
    assert np.abs(good["color"] - ref.color).mean() < 0.01 * ref.color.mean() + 0.005


def test_layered_shadow_passes_its_gates(engine, capsys):
    code, rec = _score(
        engine,
        "good.exr",
        "--channel",
        "shadow",
        "--fail-above",
        "misclassified_fraction=0.01",
        "--fail-above",
        "visibility_mae=0.02",
        out="shadow",
    )
    assert code == 0, capsys.readouterr().err
    assert rec["channel"] == "visibility"
    assert rec["visibility_mae"] < 0.01 and rec["misclassified_fraction"] < 0.01


def test_grey_png_is_scored_as_visibility_without_channel(engine, capsys):
    """The silent failure of the issue: a grey mask without ``--channel`` was scored as
    colour (exit 0, every shadow metric null)."""
    code, rec = _score(engine, "shadow.png", "--fail-above", "misclassified_fraction=0.01")
    assert code == 0, capsys.readouterr().err
    assert rec["channel"] == "visibility"
    assert rec["misclassified_fraction"] is not None and rec["misclassified_fraction"] < 0.01


def test_broken_shadow_fails_with_numbers(engine, capsys):
    capsys.readouterr()
    code, rec = _score(
        engine, "broken.png", "--fail-above", "misclassified_fraction=0.01", out="broken"
    )
    err = _said(capsys)
    assert code == 1
    assert rec["misclassified_fraction"] > 0.02
    assert re.search(rf"misclassified_fraction {rec['misclassified_fraction']:.4g} > 0.01", err)


def test_msaa_colour_and_coverage_layers(engine, capsys):
    code, rec = _score(
        engine,
        "good.exr",
        "--channel",
        "msaa",
        "--fail-above",
        "flip_mean=0.02",
        "--fail-below",
        "ssim=0.95",
        out="msaa",
    )
    assert code == 0, capsys.readouterr().err
    assert rec["channel"] == "color" and rec["flip_mean"] < 0.02 and rec["ssim"] > 0.95
    code, rec = _score(
        engine,
        "good.exr",
        "--channel",
        "msaa.coverage",
        "--fail-above",
        "coverage_mae=0.01",
        out="coverage",
    )
    assert code == 0, capsys.readouterr().err
    assert rec["channel"] == "coverage" and rec["coverage_mae"] < 0.01
    # a higher-is-better metric above its bar fails, with the numbers
    capsys.readouterr()
    code, _ = _score(engine, "good.exr", "--channel", "msaa", "--fail-below", "ssim=0.9999")
    assert code == 1 and "ssim" in _said(capsys)


@pytest.mark.parametrize(
    "gate",
    [
        ["--fail-above", "ssim=0.9"],  # ssim is higher-is-better
        ["--fail-above", "delta_e2000_mean=1"],  # a colour metric on a shadow mask
        ["--fail-above", "flicker=0.1"],  # needs two frames or more
    ],
)
def test_gates_that_cannot_apply_are_bad_input(engine, gate, capsys):
    code, _ = _score(engine, "good.exr", "--channel", "shadow", *gate, out="bad-gate")
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and gate[1].split("=")[0] in err[0]


def test_baseline_flags_a_regression(engine, capsys):
    _, base = _score(engine, "good.exr", "--channel", "shadow", out="base")
    baseline = str(engine["root"] / "base" / "metrics.json")
    capsys.readouterr()
    code, _ = _score(engine, "good.exr", "--channel", "shadow", "--baseline", baseline, out="same")
    assert code == 0, capsys.readouterr().err
    capsys.readouterr()
    code, rec = _score(
        engine, "broken.exr", "--channel", "shadow", "--baseline", baseline, out="worse"
    )
    err = _said(capsys)
    assert code == 1
    # one line with both values (4 significant digits)
    line = next(t for t in err.splitlines() if "visibility_mae" in t and "REGRESSION" in t)
    assert f"{rec['visibility_mae']:.4g}" in line and f"{base['visibility_mae']:.4g}" in line
    assert rec["visibility_mae"] > base["visibility_mae"]
    # a baseline of another channel is no comparison: bad input
    _, _ = _score(engine, "good.exr", "--channel", "msaa", out="colour-base")
    other = str(engine["root"] / "colour-base" / "metrics.json")
    code, _ = _score(engine, "good.exr", "--channel", "shadow", "--baseline", other)
    assert code == 2


def test_junit_file(engine, capsys):
    junit = engine["root"] / "junit.xml"
    code, rec = _score(
        engine,
        "broken.exr",
        "--channel",
        "shadow",
        "--fail-above",
        "misclassified_fraction=0.01",
        "--fail-above",
        "visibility_mae=0.5",
        "--fail-below",
        "ssim=0.1",
        "--junit",
        str(junit),
        out="junit",
    )
    assert code == 1
    root = ET.parse(junit).getroot()
    suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
    cases = [c for s in suites for c in s.iter("testcase")]
    assert len(cases) == 3
    assert sum(int(s.get("tests")) for s in suites) == 3
    assert sum(int(s.get("failures")) for s in suites) == 1
    failed = [c for c in cases if c.find("failure") is not None]
    assert len(failed) == 1 and "misclassified_fraction" in failed[0].get("name")
    message = failed[0].find("failure").get("message")
    assert f"{rec['misclassified_fraction']:.4g} > 0.01" in message
    assert len({c.get("classname") for c in cases}) == 1 and cases[0].get("classname")


def test_python_api_gives_the_cli_record(engine, capsys):
    """The Python API scores the same files to the same numbers as the command line, and
    its gate check fails the broken frame."""
    _, cli = _score(engine, "good.exr", "--channel", "shadow", out="api-cli")
    rec = ro.score_image(engine["export"], engine["root"] / "good.exr", channel="shadow", spp=16)
    for key in ("visibility_mae", "misclassified_fraction", "ssim", "flip_mean"):
        assert rec[key] == pytest.approx(cli[key], rel=1e-9, abs=1e-12)
    # an in-memory array scores the same as the grey PNG's 8-bit values
    grey = np.round(engine["good"]["shadow"] * 255) / 255
    arr = ro.score_image(engine["export"], grey, spp=16)
    _, png = _score(engine, "shadow.png", out="api-png")
    assert arr["misclassified_fraction"] == pytest.approx(png["misclassified_fraction"])
    assert ro.check(rec, fail_above={"misclassified_fraction": 0.01}) == []
    broken = ro.score_image(engine["export"], engine["root"] / "broken.png", spp=16)
    assert ro.check(broken, fail_above={"misclassified_fraction": 0.01})
    with pytest.raises(ro.InputError):
        ro.check(rec, fail_above={"delta_e2000_mean": 1.0})


def test_baseline_of_an_export_scored_after_a_copy(engine, tmp_path, capsys):
    """CI exports into its own folder; the shared reference cache already holds the same
    scene rendered from another folder (``export``). Scoring the copy twice, the second run
    against the first as its baseline, must pass."""
    copy = tmp_path / "ci-plate"
    shutil.copytree(engine["export"], copy)
    candidate = str(engine["root"] / "good.exr")
    argv = ["score", str(copy), "--candidate", candidate, "--channel", "shadow", *SPP]
    assert main([*argv, "--out", str(tmp_path / "first")]) == 0
    first = json.loads((tmp_path / "first" / "metrics.json").read_text())
    baseline = str(tmp_path / "first" / "metrics.json")
    code = main([*argv, "--baseline", baseline, "--out", str(tmp_path / "second")])
    assert first["reference"]["scene"]["name"] == "ci-plate"
    assert code == 0, _said(capsys)


# --------------------------------------------------------------------------- issue 25: CI


def _manifest(path, exports: dict) -> None:
    """Two scenes, two layers each (the engine's shadow mask and its MSAA colour), with the
    gates an engine team would set."""
    text = "[defaults]\nspp = 16\n"
    for name, folder in exports.items():
        text += f"""
[scenes.{name}]
scene = "{folder}"
file = "{name}.exr"
[scenes.{name}.channels.shadow]
fail_above = {{ misclassified_fraction = 0.01, edge_band_misclassified_fraction = 0.2 }}
[scenes.{name}.channels.msaa]
fail_above = {{ flip_mean = 0.2 }}
"""
    path.write_text(text)


def _failed_junit(path) -> list[tuple[str, str]]:
    cases = ET.parse(path).getroot().iter("testcase")
    return [(c.get("classname"), c.get("name")) for c in cases if c.find("failure") is not None]


def _summary_rows(path, table: str = "| scene | check |") -> list[tuple[str, str]]:
    """(first, second cell) of the rows of the Markdown summary's table whose header starts
    with ``table`` (default: the failed-check table)."""
    rows, inside = [], False
    for line in path.read_text().splitlines():
        if line.startswith("| scene |"):
            inside = line.startswith(table)
            continue
        m = re.match(r"^\| ((?:\\.|[^\\|])+?) \| ((?:\\.|[^\\|])+?) \|", line)
        if inside and m and m.group(1) != "---":
            rows.append((_unescape(m.group(1)), _unescape(m.group(2))))
    return rows


def _unescape(text: str) -> str:
    """Markdown-escaped user text back (backslash escapes, ``&lt; &gt; &amp;``)."""
    text = re.sub(r"\\(.)", r"\1", text)
    return text.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&")


def test_ci_manifest_run_names_one_failure_everywhere_and_accept_makes_it_pass(
    engine, tmp_path, browser
):
    """Issue 25's end-to-end run: the engine renders two exported scenes (the plate, and the
    plate from frame 3 of the dolly path), two layers each; one layer is deliberately changed
    (the second scene's colour 10 % brighter: a lighting change under review). Against the
    approved baseline the run exits 1, and the JUnit file, ``metrics.json``, the Markdown
    summary and the report's first screen (in Chromium) name the same failed checks;
    ``baseline accept`` approves the change and the next run passes."""
    exports = {"front": engine["export"], "dolly": tmp_path / "dolly-export"}
    args = ["export", "plate", "--width", "96", "--height", "54", "--camera-path", "dolly"]
    assert main([*args, "--frame", "3", "--out", str(exports["dolly"])]) == 0
    images = {name: render(folder) for name, folder in exports.items()}
    manifest = tmp_path / "ci.toml"
    _manifest(manifest, exports)
    shots, changed, base = tmp_path / "shots", tmp_path / "shots-changed", tmp_path / "baselines"
    for folder, brighter in ((shots, 1.0), (changed, 1.1)):
        folder.mkdir()
        for name, img in images.items():
            img = dict(img, color=img["color"] * (brighter if name == "dolly" else 1.0))
            write_engine_exr(folder / f"{name}.exr", img)

    def run(root, out, *extra):
        argv = ["score-folder", str(root), "--manifest", str(manifest), "--quiet"]
        files = ["--junit", str(out / "junit.xml"), "--summary-md", str(out / "summary.md")]
        return main([*argv, "--platform", "ci-linux", *files, "--out", str(out / "run"), *extra])

    # the approved state
    assert run(shots, tmp_path / "r0") == 0
    note = ["--note", "first engine build"]
    assert (
        main(["baseline", "accept", str(tmp_path / "r0" / "run"), "--into", str(base), *note]) == 0
    )
    # the changed layer against it: exit 1, one failure named the same everywhere
    out = tmp_path / "r1"
    assert run(changed, out, "--baseline", str(base)) == 1
    record = json.loads((out / "run" / "metrics.json").read_text())
    failed = [(case, name) for case, names in record["failed"].items() for name in names]
    assert failed and {case for case, _ in failed} == {"dolly/msaa"}
    assert all(name.startswith("baseline ") for _, name in failed)
    assert ("dolly/msaa", "baseline flip_mean") in failed
    assert _failed_junit(out / "junit.xml") == failed
    summary = (out / "summary.md").read_text()
    assert (
        summary.startswith("## raster-oracle: FAIL") and _summary_rows(out / "summary.md") == failed
    )
    # the first screen: one row for the one failing case, its regressions counted
    assert _summary_rows(out / "summary.md", "| scene | failed |") == [
        ("dolly/msaa", str(len(failed)))
    ]
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    try:
        page.goto((out / "run" / "report.html").resolve().as_uri())
        verdict = page.locator("#verdict")
        box = verdict.bounding_box()
        assert box is not None and box["y"] < 400  # on the first screen
        assert "FAIL" in verdict.locator("h2").inner_text()
        rows = verdict.locator("tr[data-check]")
        shown = [
            (rows.nth(i).locator("td").nth(0).inner_text(), rows.nth(i).get_attribute("data-check"))
            for i in range(rows.count())
        ]
        assert shown == failed
        first = rows.nth(0).bounding_box()
        assert first is not None and first["y"] + first["height"] <= 800
        # where: the failing case's worst tiles (reference, candidate, error) on that screen
        where = verdict.locator(".verdict-where[data-case] img.crop")
        assert where.count() >= 3
        crop = where.nth(2).bounding_box()
        assert crop is not None and crop["y"] + crop["height"] <= 800
    finally:
        page.close()
    # the change is approved: the next run against the new baseline passes
    note = ["--note", "sun 10 % brighter (art review 42)"]
    assert main(["baseline", "accept", str(out / "run"), "--into", str(base), *note]) == 0
    assert run(changed, tmp_path / "r2", "--baseline", str(base)) == 0
    kept = json.loads((base / "ci-linux" / "previous" / "001" / "baseline.json").read_text())
    assert kept["note"] == "first engine build"
