"""Probe of bad command-line input: every item gives one stderr line, exit 2, nothing written.

Each case runs the real CLI entry point in-process (``main(argv)``) with the working folder
set to a fresh temporary folder, and captures file descriptors 1 and 2 (``capfd``), so text
that C libraries print bypassing Python (OpenEXR on truncated files) is seen too. "Nothing
written" means: the folder holds exactly the fixtures it held before, and no
``raster-oracle-ref-*`` scratch folder is left in the temporary folder.
"""

from __future__ import annotations

import json
import tempfile

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.cli.args import MAX_SPP, CliError
from raster_oracle.oracle.reference.exr import write_exr

SMALL = ["--width", "16", "--height", "12", "--quiet", "--no-cache"]

#: A directional light with direction 0,0,0 (its to_world is NaN): must be refused at load.
ZERO_DIRECTION_XML = """<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/>
    </film>
  </sensor>
  <emitter type="directional"><vector name="direction" value="0,0,0"/></emitter>
  <shape type="sphere"/>
</scene>
"""

#: A report case record missing keys, in an otherwise valid report JSON.
MISSING_KEYS_REPORT = {"schema": "raster-oracle.report/1", "cases": [{"schema": "x"}]}


def _fixtures(folder):
    """Files every case may use: a file where a folder is expected, scenes, bad reports."""
    (folder / "afile").write_text("not a folder")
    (folder / "zero.xml").write_text(ZERO_DIRECTION_XML)
    rng = np.random.default_rng(0)
    good = folder / "cand.exr"
    write_exr(good, {c: rng.random((12, 16)).astype(np.float32) for c in "RGB"})
    data = good.read_bytes()
    # Cut inside the pixel data: OpenEXR prints its own messages (stdout and stderr).
    (folder / "trunc.exr").write_bytes(data[: len(data) * 2 // 3])
    good.unlink()
    for name, content in {
        "listreport": [1, 2],
        "schemareport": {"schema": "something/else", "cases": []},
        "missingkeys": MISSING_KEYS_REPORT,
        "nocases": {"schema": "raster-oracle.report/1"},
    }.items():
        (folder / name).mkdir()
        (folder / name / "report.json").write_text(json.dumps(content))


def _listing(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


BAD = {
    "directional light direction 0,0,0": (["reference", "zero.xml", *SMALL], "no direction"),
    "--spp 2^32": (["reference", "plate", "--spp", str(2**32), *SMALL], r"--spp: must be <="),
    "--seed 2^32 (would wrap onto seed 0)": (
        ["reference", "plate", "--seed", str(2**32), *SMALL],
        r"seed must be in \[0, 4294967295\]",
    ),
    "--spp above the maximum": (
        ["reference", "plate", "--spp", str(MAX_SPP + 1), *SMALL],
        r"--spp: must be <= 1048576",
    ),
    "--spp 1e12": (["reference", "plate", "--spp", "1e12", *SMALL], "expected an integer"),
    "--spp 1e9": (["reference", "plate", "--spp", "1e9", *SMALL], "expected an integer"),
    "--max-spp 2^32": (
        ["reference", "plate", "--adaptive", "--max-spp", str(2**32), *SMALL],
        "--max-spp: must be <=",
    ),
    "score --spp 2^32": (
        ["score", "plate", "--technique", "shadow-map", "--spp", str(2**32), *SMALL],
        "--spp: must be <=",
    ),
    "--frame without a camera path": (
        ["reference", "plate", "--frame", "3", *SMALL],
        "--frame 3 needs --camera-path",
    ),
    "model --frame without a camera path": (
        ["model", "shadow-map", "plate", "--frame", "2", "--width", "16", "--height", "12"],
        "--frame 2 needs --camera-path",
    ),
    "--out under a file": (["reference", "plate", "--out", "afile/x", *SMALL], "not a folder"),
    "--out is a file": (["reference", "plate", "--out", "afile", *SMALL], "not a folder"),
    "--out /dev/null/x": (
        ["reference", "plate", "--out", "/dev/null/x", *SMALL],
        "/dev/null is not a folder",
    ),
    "--out ''": (["reference", "plate", "--out", "", *SMALL], "expected a path"),
    "model --out under a file": (
        ["model", "shadow-map", "plate", "--out", "afile/m", "--width", "16", "--height", "12"],
        "not a folder",
    ),
    "score --out under a file": (
        ["score", "plate", "--technique", "shadow-map", "--out", "afile/s", *SMALL],
        "not a folder",
    ),
    "export --out ''": (["export", "plate", "--out", ""], "expected a path"),
    "main --out under a file": (["main", "--out", "afile/m", "--quiet"], "not a folder"),
    "--cache-dir is a file": (
        ["reference", "plate", "--cache-dir", "afile", "--width", "16", "--height", "12"],
        "--cache-dir afile exists and is not a folder",
    ),
    "--cache-dir under a file": (
        ["reference", "plate", "--cache-dir", "afile/c", "--width", "16", "--height", "12"],
        "not a folder",
    ),
    "--fail-above flip_mean=nan": (
        ["score", "plate", "--technique", "shadow-map", "--fail-above", "flip_mean=nan", *SMALL],
        "expected a finite number, got 'nan'",
    ),
    "--fail-above flip_mean=inf": (
        ["score", "plate", "--technique", "shadow-map", "--fail-above", "flip_mean=inf", *SMALL],
        "expected a finite number",
    ),
    "frame pattern {frame:zz}": (
        ["score", "plate", "--candidate", "f{frame:zz}.exr", "--frames", "2", *SMALL],
        r"pattern 'f\{frame:zz\}.exr' is not valid",
    ),
    "frame pattern {frame}_{eye}": (
        ["score", "plate", "--candidate", "f{frame}_{eye}.exr", "--frames", "2", *SMALL],
        r"pattern 'f\{frame\}_\{eye\}.exr' is not valid",
    ),
    "truncated EXR candidate": (
        ["score", "plate", "--candidate", "trunc.exr", *SMALL],
        "truncated or not a readable EXR",
    ),
    "candidate name with a newline": (
        ["score", "plate", "--candidate", "a\nb.exr", *SMALL],
        r"a\\nb.exr",
    ),
    "report: list report.json": (
        ["report", "listreport", "--out", "r.html"],
        "is not a report JSON",
    ),
    "report: wrong schema": (["report", "schemareport", "--out", "r.html"], "not a report JSON"),
    "report: missing keys": (["report", "missingkeys", "--out", "r.html"], "case record"),
    "report: no cases": (["report", "nocases", "--out", "r.html"], "'cases' must be a list"),
    "report: --out under a file": (
        ["report", "listreport", "--out", "afile/r.html"],
        "not a folder",
    ),
    "report: --out x.json": (["report", "listreport", "--out", "x.json"], "must name the HTML"),
    "report: --title ''": (
        ["report", "listreport", "--out", "r.html", "--title", ""],
        "--title must not be empty",
    ),
    "report: not a score folder": (["report", "afile", "--out", "r.html"], "not a score folder"),
    "bench models --only unknown": (
        ["bench", "models", "--only", "msaa,nope"],
        r"unknown technique\(s\) nope",
    ),
    "bench oracle --only": (["bench", "oracle", "--only", "msaa"], "'bench models' only"),
}


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_input_one_line_exit_2_nothing_written(case, tmp_path, monkeypatch, capfd):
    import re

    args, message = BAD[case]
    work = tmp_path / "work"
    work.mkdir()
    _fixtures(work)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.setenv("RASTER_ORACLE_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(work)
    before = _listing(work)
    capfd.readouterr()
    rc = main(args)
    out, err = capfd.readouterr()
    assert rc == 2, (out, err)
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("raster-oracle: error: "), err
    assert re.search(message, lines[0]), lines[0]
    assert "Traceback" not in err and "Warning" not in out + err
    assert _listing(work) == before
    assert not (tmp_path / "cache").exists()
    assert list(scratch.iterdir()) == []


def test_runtime_warnings_do_not_add_stderr_lines(monkeypatch, capfd):
    """NumPy RuntimeWarnings raised on the way to an error are not printed."""
    import warnings

    from raster_oracle.oracle.cli import app

    def noisy(args):
        np.log(np.zeros(1))  # a genuine NumPy "divide by zero" RuntimeWarning
        warnings.warn("mean of empty slice", RuntimeWarning, stacklevel=1)
        raise CliError("the one line")

    monkeypatch.setitem(app.COMMANDS, "scenes", noisy)
    capfd.readouterr()
    assert main(["scenes"]) == 2
    out, err = capfd.readouterr()
    assert err == "raster-oracle: error: the one line\n" and out == ""


def _store(path):
    from raster_oracle.oracle.sweeps.store import SweepStore

    SweepStore(path).close()
    return path


def _digests(folder):
    import hashlib

    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


#: An output path that is, or whose JSON twin is, an input: refused before anything is written.
OVERWRITES = {
    "report --sweep S.db --out S.db": (lambda w: ["report", "--sweep", "S.db", "--out", "S.db"]),
    "report --sweep S.json --out S.html (the JSON twin)": (
        lambda w: ["report", "--sweep", "S.json", "--out", "S.html"]
    ),
    "report --sweep through a link to the store": (
        lambda w: ["report", "--sweep", "S.db", "--out", "link.html"]
    ),
    "report DIR --out DIR/report.html (its record)": (
        lambda w: ["report", "scored", "--out", "scored/report.html"]
    ),
    "sweep --out D --db D/report.json": (
        lambda w: ["sweep", "spec.toml", "--out", "D", "--db", "D/report.json", "--workers", "0"]
    ),
    "sweep --out E --db E/report.json (neither exists yet)": (
        lambda w: ["sweep", "spec.toml", "--out", "E", "--db", "E/report.json", "--workers", "0"]
    ),
    "sweep F/report.html --out F (the spec is the report)": (
        lambda w: ["sweep", "F/report.html", "--out", "F", "--workers", "0"]
    ),
    "sweep F/report.json --out F (the spec is the JSON twin)": (
        lambda w: ["sweep", "F/report.json", "--out", "F", "--db", "S.db", "--workers", "0"]
    ),
    "sweep spec.toml --db spec.toml": (
        lambda w: ["sweep", "spec.toml", "--out", "D", "--db", "spec.toml", "--workers", "0"]
    ),
    "sweep --out D --db D/report.html": (
        lambda w: ["sweep", "spec.toml", "--out", "D", "--db", "D/report.html", "--workers", "0"]
    ),
}


@pytest.mark.parametrize("case", list(OVERWRITES), ids=list(OVERWRITES))
def test_output_paths_never_overwrite_inputs(case, tmp_path, monkeypatch, capfd):
    """Issue 20's data loss: a report written over its own sweep store (or over the JSON twin
    that is the store) is exit 2 with every input byte for byte as it was."""
    work = tmp_path / "work"
    work.mkdir()
    _store(work / "S.db")
    _store(work / "S.json")
    (work / "link.json").symlink_to(work / "S.db")
    (work / "scored").mkdir()
    (work / "scored" / "report.json").write_text(json.dumps({"schema": "raster-oracle.report/1"}))
    (work / "spec.toml").write_text(
        'name = "t"\n[defaults]\nwidth = 8\nheight = 6\nspp = 1\n'
        '[[case]]\nscenes = ["plate"]\ntechnique = "shadow-map"\n'
    )
    (work / "F").mkdir()
    for name in ("report.html", "report.json"):
        (work / "F" / name).write_text((work / "spec.toml").read_text())
    (work / "D").mkdir()
    _store(work / "D" / "report.json")
    _store(work / "D" / "report.html")
    monkeypatch.setenv("RASTER_ORACLE_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(work)
    before = _digests(work)
    capfd.readouterr()
    rc = main(OVERWRITES[case](work))
    out, err = capfd.readouterr()
    assert rc == 2, (out, err)
    assert len(err.splitlines()) == 1 and "would destroy it" in err, err
    assert _digests(work) == before
    assert not (tmp_path / "cache").exists()
