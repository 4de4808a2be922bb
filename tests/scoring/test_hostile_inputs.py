"""Hostile manifests, camera files, baselines, verdict caches and output text (issue 39).

Each case is refused with one line (the layer's input error: exit 2 at the command line),
writes nothing outside ``--out``, loses no earlier data and ends in bounded time; the output
cases check that user text reaches Markdown, HTML, JUnit and the terminal escaped. Most
cases call the library in-process; a few run the real command line.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from _bounded import bounded
from raster_oracle.oracle.certify import verdict as V
from raster_oracle.oracle.cli.args import MAX_SPP
from raster_oracle.oracle.scoring.ci.baseline import accept_baseline, resolve_baseline
from raster_oracle.oracle.scoring.ci.checks import METRICS_SCHEMA, Check, GateError, Verdict
from raster_oracle.oracle.scoring.ci.junit import junit_xml
from raster_oracle.oracle.scoring.ci.regression import load_baseline
from raster_oracle.oracle.scoring.ci.summary import summary_markdown
from raster_oracle.oracle.scoring.folder import FolderCase, score_folder
from raster_oracle.oracle.scoring.inputs import manifest as M
from raster_oracle.oracle.scoring.inputs.out_names import case_folder
from raster_oracle.oracle.scoring.score import ScoreError
from raster_oracle.scenes import backend
from raster_oracle.scenes.base import untrusted as U
from raster_oracle.scenes.camera import Camera
from raster_oracle.scenes.formats.camera_file import CameraFileError, load_camera_file


def _one_line(exc_info) -> str:
    text = str(exc_info.value)
    assert "\n" not in text and "Traceback" not in text
    return text


# --- manifests --------------------------------------------------------------------------------


def _manifest(tmp_path, text: str, name: str = "ci.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


BAD_MANIFESTS = {
    "key-dotdot": '[scenes."../escaped"]\nscene = "plate"\n',
    "key-absolute": '[scenes."/tmp/abs"]\nscene = "plate"\n',
    "key-metrics-json": '[scenes."metrics.json"]\nscene = "plate"\n',
    "key-report-html": '[scenes."REPORT.HTML"]\nscene = "plate"\n',
    "key-dot": '[scenes."."]\nscene = "plate"\n',
    "key-newline": '[scenes."a\\nb"]\nscene = "plate"\n',
    "key-nul": '[scenes."a\\u0000b"]\nscene = "plate"\n',
    "key-escape": '[scenes."a\\u001b[31m"]\nscene = "plate"\n',
    "key-backslash": '[scenes."a\\\\..\\\\b"]\nscene = "plate"\n',
    "key-long": f'[scenes."{"k" * 200}"]\nscene = "plate"\n',
    "channel-dotdot": '[scenes.plate]\nchannels = { "../up" = {} }\n',
    "channel-metrics": '[scenes.plate]\nchannels = { "metrics.json" = {} }\n',
    "channel-slash": '[scenes.plate]\nchannels = { "a/b" = {} }\n',
    "file-absolute": '[scenes.plate]\nfile = "/etc/passwd"\n',
    "file-dotdot": '[scenes.plate]\nfile = "../outside.exr"\n',
    "file-home": '[scenes.plate]\nfile = "~/x.exr"\n',
    "file-newline": '[scenes.plate]\nfile = "a\\nb.exr"\n',
    "pattern-positional": '[scenes.plate]\nfile = "f_{0}.exr"\n',
    "pattern-unknown": '[scenes.plate]\nfile = "f_{nosuch}.exr"\n',
    "pattern-width": '[scenes.plate]\nfile = "f_{frame:>100000}.exr"\n',
    "pattern-wide-zero": '[scenes.plate]\nfile = "f_{frame:0100d}.exr"\n',
    "pattern-attr": '[scenes.plate]\nfile = "f_{frame.real}.exr"\n',
    "pattern-index": '[scenes.plate]\nfile = "f_{frame[0]}.exr"\n',
    "pattern-conversion": '[scenes.plate]\nfile = "f_{frame!r}.exr"\n',
    "pattern-nested": '[scenes.plate]\nfile = "f_{frame:{frame}}.exr"\n',
    "pattern-open-brace": '[scenes.plate]\nfile = "f_{.exr"\n',
    "spp-2^21": "[defaults]\nspp = 2097152\n[scenes.plate]\n",
    "spp-zero": "[defaults]\nspp = 0\n[scenes.plate]\n",
    "spp-float": "[defaults]\nspp = 16.0\n[scenes.plate]\n",
    "spp-string": '[defaults]\nspp = "16"\n[scenes.plate]\n',
    "spp-bool": "[defaults]\nspp = true\n[scenes.plate]\n",
    "seed-huge": "[defaults]\nseed = 99999999999999\n[scenes.plate]\n",
    "seed-negative": "[defaults]\nseed = -1\n[scenes.plate]\n",
    "frames-huge": '[scenes.plate]\nframes = 100000000\ncamera_path = "orbit"\n',
    "frames-zero": "[scenes.plate]\nframes = 0\n",
    "fail-above-nan": "[defaults]\nfail_above = { flip_mean = nan }\n[scenes.plate]\n",
    "fail-above-string": '[defaults]\nfail_above = { flip_mean = "0.1" }\n[scenes.plate]\n',
    "unknown-key": "[defaults]\nspp = 4\nbogus = 1\n[scenes.plate]\n",
    "scenes-not-table": 'scenes = "plate"\n',
    "no-scenes": "[defaults]\nspp = 4\n",
    "not-toml": "[scenes.plate\n",
    "visibility-unknown": '[scenes.plate]\nvisibility = "1-is-maybe"\n',
    "deep-array": "[defaults]\nprofiles = " + "[" * 40 + "]" * 40 + "\n[scenes.plate]\n",
    "deep-array-100k": "x = " + "[" * 100_000 + "]" * 100_000 + "\n",
    "deep-inline-tables": "x = " + "{a = " * 50 + "1" + "}" * 50 + "\n",
    "too-many-cases": "".join(f'[scenes.s{k}]\nscene = "plate"\n' for k in range(1002)),
}


@pytest.mark.parametrize("case", sorted(BAD_MANIFESTS))
def test_a_hostile_manifest_is_refused_with_one_line(tmp_path, case):
    path = _manifest(tmp_path, BAD_MANIFESTS[case])
    with pytest.raises(M.ManifestError) as info:
        bounded(M.read_manifest, path)
    _one_line(info)


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device", "binary", "huge"])
def test_a_manifest_that_is_no_regular_text_file_is_refused(tmp_path, kind):
    path = tmp_path / "ci.toml"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "zero-device":
        path.symlink_to("/dev/zero")
    elif kind == "binary":
        path.write_bytes(b"\xff\xfe\x00[scenes]")
    else:
        path.write_bytes(b"#" * (M.LIMITS["bytes"] + 1))
    with pytest.raises(M.ManifestError) as info:
        bounded(M.read_manifest, path)
    _one_line(info)


def test_manifest_spp_limit_is_the_command_lines():
    assert M.MAX_SPP == MAX_SPP


def test_good_manifest_patterns_are_kept(tmp_path):
    path = _manifest(
        tmp_path,
        '[defaults]\nspp = 1048576\n[scenes.plate]\nfile = "sub/f_{frame:03d}_{{x}}.exr"\n'
        "frames = 2\n"
        'camera_path = "orbit"\n[scenes."odd name <b>"]\nscene = "plate"\n',
    )
    m = M.read_manifest(path)
    assert m.spp == 2**20
    assert [c.scene_key for c in m.cases] == ["plate", "odd name <b>"]
    assert m.cases[0].file == "sub/f_{frame:03d}_{{x}}.exr"


@pytest.mark.parametrize(
    "name", ["../escaped", "/abs", "metrics.json", "a/b/c", ".", "a/..", "x\x00y", "report.html"]
)
def test_score_folder_refuses_a_case_folder_outside_out(tmp_path, name):
    """The library check behind every manifest and folder run: nothing is written."""
    out = tmp_path / "out"
    with pytest.raises(ScoreError) as info:
        score_folder([FolderCase(name=name, scene="plate", error="x")], out=out)
    _one_line(info)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["out"] * 0


def test_a_case_folder_is_under_out(tmp_path):
    assert case_folder(tmp_path, "plate/shadow", error=ScoreError) == tmp_path / "plate" / "shadow"


def _cli(*args, env_extra=None, timeout=180):
    env = {**os.environ, "RASTER_ORACLE_TRUST_BACKEND": "1", **(env_extra or {})}
    cmd = [sys.executable, "-m", "raster_oracle.oracle.cli", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)


@pytest.mark.parametrize("key", ["../escaped", "metrics.json"])
def test_score_folder_cli_writes_nothing_outside_out(tmp_path, key):
    root = tmp_path / "root"
    root.mkdir()
    manifest = _manifest(tmp_path, f'[scenes."{key}"]\nscene = "plate"\nfile = "p.exr"\n')
    out = tmp_path / "sub" / "out"
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    r = _cli("score-folder", root, "--manifest", manifest, "--out", out)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_a_manifest_fifo_does_not_hang_the_cli(tmp_path):
    fifo = tmp_path / "ci.toml"
    os.mkfifo(fifo)
    r = _cli("score-folder", tmp_path, "--manifest", fifo, "--out", tmp_path / "out", timeout=120)
    assert r.returncode == 2 and "FIFO" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


# --- camera files -----------------------------------------------------------------------------

BASE = Camera("perspective", np.eye(4), 64, 36, 0.1, 100.0, fov_x=60.0)
EYE = np.eye(4).tolist()


def _frame(**fields) -> dict:
    return {"frames": [{"to_world": EYE, "fov_x_deg": 60.0} | fields]}


BAD_CAMERAS = {
    "strings": _frame(to_world=[["1", "0", "0", "0"]] * 4),
    "objects": _frame(to_world=[{"a": 1}] * 4),
    "ragged": _frame(to_world=[[1, 0, 0, 0], [0, 1, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
    "flat": _frame(to_world=list(range(16))),
    "nested-deeper": _frame(to_world=[[[1]] * 4] * 4),
    "booleans": _frame(to_world=[[True, False, False, False]] * 4),
    "nulls": _frame(to_world=[[None] * 4] * 4),
    "all-zero": _frame(to_world=[[0] * 4] * 3 + [[0, 0, 0, 1]]),
    "rank-2": _frame(to_world=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]),
    "nearly-singular": _frame(to_world=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1e-9, 0], [0, 0, 0, 1]]),
    "entry-1e300": _frame(to_world=[[1e300, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
    "translation-1e300": _frame(
        to_world=[[1, 0, 0, 1e300], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    ),
    "projective-row": _frame(to_world=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 0]]),
    "view-singular": {"frames": [{"world_to_view": [[0] * 4] * 4, "fov_y_deg": 40}]},
    "fov-string": _frame(fov_x_deg="60"),
    "fov-null": _frame(fov_x_deg=None),
    "fov-list": _frame(fov_x_deg=[60]),
    "fov-bool": _frame(fov_x_deg=True),
    "fov-zero": _frame(fov_x_deg=0),
    "fov-180": _frame(fov_x_deg=180),
    "fov-huge": _frame(fov_x_deg=1e300),
    "fov-y-string": {"frames": [{"to_world": EYE, "fov_y_deg": "40"}]},
    "no-fov": {"frames": [{"to_world": EYE}]},
    "no-matrix": {"frames": [{"fov_x_deg": 60}]},
    "frame-not-object": {"frames": [7]},
    "frames-empty": {"frames": []},
    "frames-object": {"frames": {"0": {}}},
    "top-list": [1, 2],
}


@pytest.mark.parametrize("case", sorted(BAD_CAMERAS))
def test_a_hostile_camera_file_is_refused_with_one_line(tmp_path, case):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps(BAD_CAMERAS[case]))
    with pytest.raises(CameraFileError) as info:
        bounded(load_camera_file, path, BASE)
    _one_line(info)


@pytest.mark.parametrize(
    "content",
    [b'{"frames": [{"to_world": NaN}]}', b'{"frames": [1e400]}', b"[" * 100_000]
    + [b"\xff\xfe", b"", b"{"],
    ids=["nan", "1e400", "deep", "not-utf8", "empty", "truncated"],
)
def test_a_camera_file_that_is_not_strict_json_is_refused(tmp_path, content):
    path = tmp_path / "cameras.json"
    path.write_bytes(content)
    with pytest.raises(CameraFileError) as info:
        bounded(load_camera_file, path, BASE)
    _one_line(info)


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device"])
def test_a_camera_file_that_is_no_regular_file_is_refused(tmp_path, kind):
    path = tmp_path / "cameras.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    else:
        path.symlink_to("/dev/zero")
    with pytest.raises(CameraFileError) as info:
        bounded(load_camera_file, path, BASE)
    _one_line(info)


def test_a_good_camera_file_is_read(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps(_frame()))
    (cam,) = load_camera_file(path, BASE)
    assert cam.fov_x == 60.0 and np.array_equal(cam.to_world, np.eye(4))


# --- baselines --------------------------------------------------------------------------------


def _run(tmp_path, name: str, platform=None, marker: str = "") -> Path:
    run = tmp_path / name
    run.mkdir(parents=True, exist_ok=True)
    record = {"schema": METRICS_SCHEMA, "failed": [], "marker": marker or name}
    if platform is not None:
        record["platform"] = platform
    (run / "metrics.json").write_text(json.dumps(record))
    return run


def _tree(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink() and p.name != ".accept.lock"
    }


def test_accept_keeps_every_earlier_baseline(tmp_path):
    base = tmp_path / "base"
    for k in range(3):
        accept_baseline(_run(tmp_path, f"r{k}"), into=base, note=f"n{k}")
    kept = _tree(base)
    assert json.loads(kept["default/metrics.json"])["marker"] == "r2"
    assert json.loads(kept["default/previous/001/metrics.json"])["marker"] == "r0"
    assert json.loads(kept["default/previous/002/baseline.json"])["note"] == "n1"


def test_twelve_concurrent_accepts_all_leave_their_trace(tmp_path):
    base = tmp_path / "base"
    runs = [_run(tmp_path, f"r{k:02d}") for k in range(12)]
    errors = []

    def accept(run):
        try:
            accept_baseline(run, into=base, note=run.name)
        except Exception as exc:  # a lost accept is the failure this test looks for
            errors.append(exc)

    threads = [threading.Thread(target=accept, args=(r,)) for r in runs]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors
    markers = [
        json.loads(v)["marker"] for k, v in _tree(base).items() if k.endswith("metrics.json")
    ]
    assert sorted(markers) == [r.name for r in runs]
    assert not any(p.name.startswith(".incoming") for p in (base / "default").iterdir())


def _odd_previous_link_out(base, tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (base / "default" / "previous").symlink_to(outside)


def _odd_previous_link_file(base, tmp_path):
    (tmp_path / "f").write_text("x")
    (base / "default" / "previous").symlink_to(tmp_path / "f")


def _odd_previous_dangling(base, tmp_path):
    (base / "default" / "previous").symlink_to(tmp_path / "nowhere")


def _odd_previous_file(base, tmp_path):
    (base / "default" / "previous").write_text("x")


def _odd_metrics_link(base, tmp_path):
    (tmp_path / "secret.json").write_text("{}")
    (base / "default" / "metrics.json").unlink()
    (base / "default" / "metrics.json").symlink_to(tmp_path / "secret.json")


def _odd_platform_link(base, tmp_path):
    (base / "ci").symlink_to(tmp_path / "elsewhere2", target_is_directory=True)


def _odd_lock_link(base, tmp_path):
    (tmp_path / "victim").write_text("keep")
    (base / "default" / ".accept.lock").unlink(missing_ok=True)
    (base / "default" / ".accept.lock").symlink_to(tmp_path / "victim")


def _odd_lock_fifo(base, tmp_path):
    (base / "default" / ".accept.lock").unlink(missing_ok=True)
    os.mkfifo(base / "default" / ".accept.lock")


ODD_BASELINES = {
    "lock-link": _odd_lock_link,
    "lock-fifo": _odd_lock_fifo,
    "previous-link-out": _odd_previous_link_out,
    "previous-link-file": _odd_previous_link_file,
    "previous-dangling": _odd_previous_dangling,
    "previous-file": _odd_previous_file,
    "current-metrics-link": _odd_metrics_link,
}


@pytest.mark.parametrize("case", sorted(ODD_BASELINES))
def test_an_odd_baseline_folder_is_refused_and_nothing_is_lost(tmp_path, case):
    base = tmp_path / "base"
    accept_baseline(_run(tmp_path, "r0"), into=base, note="first")
    ODD_BASELINES[case](base, tmp_path)
    before = _tree(base)
    outside_before = _tree(tmp_path / "elsewhere") if (tmp_path / "elsewhere").exists() else {}
    with pytest.raises(GateError) as info:
        bounded(accept_baseline, _run(tmp_path, "r1"), into=base, note="second")
    _one_line(info)
    assert _tree(base) == before
    if outside_before or (tmp_path / "elsewhere").exists():
        assert _tree(tmp_path / "elsewhere") == outside_before


def test_previous_numbering_skips_odd_entries(tmp_path):
    """``previous/1000`` (and a file named 002) exist: the next approval takes a free number."""
    base = tmp_path / "base"
    accept_baseline(_run(tmp_path, "r0"), into=base, note="first")
    prev = base / "default" / "previous"
    prev.mkdir()
    (prev / "1000").mkdir()
    (prev / "1001").write_text("not a folder")
    accept_baseline(_run(tmp_path, "r1"), into=base, note="second")
    assert json.loads((prev / "1002" / "metrics.json").read_text())["marker"] == "r0"


@pytest.mark.parametrize("platform", [5, ["a"], {"x": 1}, True, "../up", "a/b", ".."])
def test_a_platform_of_the_wrong_type_is_refused(tmp_path, platform):
    run = _run(tmp_path, "r0", platform=platform)
    base = tmp_path / "base"
    with pytest.raises(GateError) as info:
        accept_baseline(run, into=base, note="n")
    _one_line(info)
    assert not any(p.is_file() for p in base.rglob("*")) if base.exists() else True


def test_a_platform_folder_that_is_a_file_is_refused(tmp_path):
    base = tmp_path / "base"
    base.mkdir()
    (base / "default").write_text("keep me")
    with pytest.raises(GateError) as info:
        accept_baseline(_run(tmp_path, "r0"), into=base, note="n")
    _one_line(info)
    assert (base / "default").read_text() == "keep me"


def test_a_platform_folder_that_is_a_link_is_refused(tmp_path):
    base = tmp_path / "base"
    base.mkdir()
    (tmp_path / "other").mkdir()
    (base / "default").symlink_to(tmp_path / "other")
    with pytest.raises(GateError) as info:
        accept_baseline(_run(tmp_path, "r0"), into=base, note="n")
    _one_line(info)
    assert not any((tmp_path / "other").iterdir())


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device", "not-json", "nan", "list"])
def test_a_run_record_that_is_no_json_file_is_refused(tmp_path, kind):
    run = tmp_path / "run"
    run.mkdir()
    path = run / "metrics.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "zero-device":
        path.symlink_to("/dev/zero")
    else:
        text = {"not-json": "{", "nan": '{"schema": NaN}', "list": "[]"}[kind]
        path.write_text(text)
    with pytest.raises(GateError) as info:
        bounded(accept_baseline, run, into=tmp_path / "base", note="n")
    _one_line(info)
    assert not (tmp_path / "base").exists()


@pytest.mark.parametrize("kind", ["fifo", "zero-device"])
def test_a_baseline_record_that_is_no_regular_file_is_refused(tmp_path, kind):
    path = tmp_path / "metrics.json"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    with pytest.raises(GateError) as info:
        bounded(load_baseline, path)
    _one_line(info)


def test_baseline_lookup_never_follows_a_link_out(tmp_path):
    base = tmp_path / "base"
    (base / "default").mkdir(parents=True)
    (tmp_path / "outside.json").write_text("{}")
    (base / "default" / "metrics.json").symlink_to(tmp_path / "outside.json")
    with pytest.raises(GateError) as info:
        resolve_baseline(base)
    _one_line(info)


def test_concurrent_cli_accepts_all_leave_their_trace(tmp_path):
    """The real command line, 6 processes at once into one folder (12 threads above)."""
    base = tmp_path / "base"
    runs = [_run(tmp_path, f"c{k:02d}") for k in range(6)]
    env = {**os.environ, "RASTER_ORACLE_TRUST_BACKEND": "1"}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "raster_oracle.oracle.cli", "baseline", "accept", str(r)]
            + ["--into", str(base), "--note", r.name],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for r in runs
    ]
    codes = [p.wait(timeout=300) for p in procs]
    for p in procs:
        p.stdout.close()
        p.stderr.close()
    assert codes == [0] * 6
    markers = [
        json.loads(v)["marker"] for k, v in _tree(base).items() if k.endswith("metrics.json")
    ]
    assert sorted(markers) == [r.name for r in runs]


# --- the verdict cache ------------------------------------------------------------------------

KEY = {"variant": "llvm_ad_rgb", "device": "x", "battery": 3}
GOOD = {"key": KEY, "passed": True, "failed": [], "checks": [], "checked_at": None}
CHECK_OK = {"name": "a", "passed": True}
CHECK_BAD = {"name": "b", "passed": False}

BAD_VERDICTS = {
    "passed-string-false": GOOD | {"passed": "false"},
    "passed-string-true": GOOD | {"passed": "true"},
    "passed-int": GOOD | {"passed": 1},
    "passed-null": GOOD | {"passed": None},
    "passed-missing": {k: v for k, v in GOOD.items() if k != "passed"},
    "passed-with-failures": GOOD | {"failed": ["sun-shadow"]},
    "failed-without-names": GOOD | {"passed": False, "failed": []},
    "failed-string": GOOD | {"failed": "sun-shadow"},
    "failed-numbers": GOOD | {"passed": False, "failed": [1, 2]},
    "failed-missing": {k: v for k, v in GOOD.items() if k != "failed"},
    "checks-disagree": GOOD | {"checks": [CHECK_OK, CHECK_BAD]},
    "checks-not-list": GOOD | {"checks": "all fine"},
    "checks-malformed": GOOD | {"checks": [{"name": 3, "passed": "yes"}]},
    "checked-at-number": GOOD | {"checked_at": 12},
    "other-key": GOOD | {"key": KEY | {"device": "y"}},
    "key-missing": {k: v for k, v in GOOD.items() if k != "key"},
    "not-object": [GOOD],
}


@pytest.mark.parametrize("case", sorted(BAD_VERDICTS))
def test_a_malformed_or_inconsistent_verdict_is_not_trusted(case):
    assert V.valid_verdict(GOOD, KEY)
    assert V.valid_verdict(
        GOOD | {"passed": False, "failed": ["b"], "checks": [CHECK_OK, CHECK_BAD]}, KEY
    )
    assert not V.valid_verdict(BAD_VERDICTS[case], KEY)


@pytest.fixture
def verdict_cache(tmp_path):
    """An empty cache folder, no verdict in force; the battery stood in for (fast)."""
    held = backend.self_check()
    backend.set_self_check(None)
    yield tmp_path / "cache"
    backend.set_self_check(held)


def _fake_battery(monkeypatch, calls):
    from raster_oracle.oracle.certify import battery

    class _Check:
        name, passed = "fake", True

        def to_json(self):
            return {"name": self.name, "passed": self.passed}

    def run_battery(on_check=None):
        calls.append(1)
        return [_Check()]

    monkeypatch.setattr(battery, "run_battery", run_battery)


def _plant(cache: Path, content) -> Path:
    variant = backend.active().variant
    path = V.verdict_path(V.machine_key(variant), cache)
    path.parent.mkdir(parents=True, exist_ok=True)
    if content == "fifo":
        os.mkfifo(path)
    elif content == "folder":
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        key = V.machine_key(variant)
        path.write_text(
            json.dumps({**content, "key": key} if isinstance(content, dict) else content)
        )
    return path


PLANTED = {
    "passed-string": {"passed": "false", "failed": [], "checks": []},
    "passed-with-failures": {"passed": True, "failed": ["sun-shadow"], "checks": []},
    "fields-missing": {},
    "failed-mistyped": {"passed": False, "failed": {"a": 1}},
    "not-json": b"{",
    "nan": b'{"passed": NaN}',
    "folder": "folder",
    "fifo": "fifo",
}


@pytest.mark.parametrize("case", sorted(PLANTED))
def test_a_bad_cached_verdict_is_discarded_and_the_check_run_again(
    verdict_cache, monkeypatch, case
):
    calls = []
    _fake_battery(monkeypatch, calls)
    _plant(verdict_cache, PLANTED[case])
    variant = backend.active().variant
    assert bounded(V.cached_verdict, variant, cache_dir=verdict_cache) is None
    V.certified_select(variant, cache_dir=verdict_cache, announce=False)
    assert calls == [1]  # the battery ran again
    assert backend.self_check()["status"] == "passed"


def test_a_verdict_that_cannot_be_cached_holds_for_the_run(verdict_cache, monkeypatch, capsys):
    calls = []
    _fake_battery(monkeypatch, calls)
    verdict_cache.mkdir(parents=True)
    (verdict_cache / "self-check").write_text("a file where a folder belongs")
    variant = backend.active().variant
    V.certified_select(variant, cache_dir=verdict_cache, announce=False)
    err = capsys.readouterr().err.strip().splitlines()
    assert calls == [1] and len(err) == 1 and "cannot be cached" in err[0]
    assert (verdict_cache / "self-check").read_text() == "a file where a folder belongs"


# --- output injection -------------------------------------------------------------------------

HOSTILE = [
    "<script>alert(1)</script>",
    "<img src=x onerror=alert(1)>",
    "[click](javascript:alert(1))",
    "![x](http://evil/x.png)",
    "]]><evil/>",
    "<!-- comment",
    "a\nb\r\nc",
    "nul\x00byte",
    "esc\x1b[31mred",
    "pipe | cell",
    "`code` **bold** _em_",
    "del\x7f c1\x9b",
]


def _verdict(name: str) -> Verdict:
    bad = Check(name=f"{name} flip_mean", metric="flip_mean", passed=False, line=f"FAIL {name}")
    good = Check(name=f"{name} mae", metric="mae", passed=True, line=f"PASS {name}")
    return Verdict(scene=name, checks=[bad, good]).add_error(f"{name} scored", f"missing {name}")


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_markdown_summary_escapes_user_text(text):
    md = summary_markdown([_verdict(text)], report=Path(f"out/{text}/report.html"))
    for raw in ("<script", "<img", "](javascript", "![", "<!--", "\x00", "\x1b", "\r"):
        assert raw not in md
    body = md.split("\n")
    # each table keeps its columns: no unescaped pipe came from the text
    header, rows = None, 0
    for line in body:
        if line.startswith("| scene |"):
            header = len(_cells(line))
        elif line.startswith("| ") and "flip" in line:
            assert len(_cells(line)) == header
            rows += 1
    assert rows == 2  # the first screen's row and the failed check's


def _cells(row: str) -> list[str]:
    out, cur, esc = [], "", False
    for c in row.strip()[1:-1]:
        if esc:
            cur, esc = cur + c, False
        elif c == "\\":
            cur, esc = cur + c, True
        elif c == "|":
            out, cur = [*out, cur], ""
        else:
            cur += c
    return [*out, cur]


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_junit_holds_only_xml_characters(text):
    xml = junit_xml([_verdict(text)])
    root = ET.fromstring(xml)  # parses: no NUL, no control character
    names = [c.get("classname") for c in root.iter("testcase")]
    assert names and all(n == U.xml_text(text) for n in names)


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_html_report_escapes_user_text(tmp_path, text):
    from raster_oracle.oracle.scoring.combine import combine_reports

    errors = [{"case": text, "name": f"{text} scored", "message": f"missing {text}"}]
    combine_reports([], tmp_path / "report.html", title=text, errors=errors)
    page = (tmp_path / "report.html").read_text()
    for raw in ("<script>alert", "<img src=x", "<evil/>", "\x00", "\x1b"):
        assert raw not in page


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_terminal_text_is_one_line_without_control_characters(text):
    out = U.terminal(text)
    assert not any(ord(c) < 32 and c != "\t" or 0x7F <= ord(c) <= 0x9F for c in out)


def test_escape_helpers_closed_form():
    assert U.escape_markdown("a|b") == "a\\|b"
    assert U.escape_markdown("<b>") == "&lt;b&gt;"
    assert U.escape_html('<a href="x">') == "&lt;a href=&quot;x&quot;&gt;"
    assert U.xml_text("a\x00b\x1fc\ud800d") == "a\\x00b\\x1fc\\ud800d"
    assert U.terminal("a\nb\x1b") == "a\\nb\\x1b"


# --- run folders and stores: export folders, the reference cache ------------------------------


def _odd(path: Path, kind: str) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    else:
        path.symlink_to("/dev/zero")


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device"])
def test_an_export_record_that_is_no_regular_file_is_refused(tmp_path, kind):
    from raster_oracle.scenes import SceneError
    from raster_oracle.scenes.inputs import resolve_input

    folder = tmp_path / "export"
    folder.mkdir()
    (folder / "scene.xml").write_text("<scene/>")
    (folder / "camera.json").write_text("{}")
    _odd(folder / "export.json", kind)
    with pytest.raises(SceneError) as info:
        bounded(resolve_input, str(folder))
    _one_line(info)


@pytest.mark.parametrize("odd", ["checksums.json", "reference.exr"])
@pytest.mark.parametrize("kind", ["fifo", "zero-device"])
def test_a_cache_entry_holding_a_fifo_or_device_is_corrupted_not_a_hang(tmp_path, odd, kind):
    from raster_oracle.oracle.reference.cache import FILES, ReferenceCache

    cache = ReferenceCache(tmp_path / "cache")
    key = "ab" + "0" * 62
    folder = cache.entry(key)
    folder.mkdir(parents=True)
    for name in (*FILES, "checksums.json"):
        if name != odd:
            (folder / name).write_text("{}")
    _odd(folder / odd, kind)
    assert bounded(cache.lookup, key) == (None, "corrupted")


@pytest.mark.parametrize("case", ["passed-string", "fifo"])
def test_the_cli_reruns_the_check_on_a_bad_cached_verdict(tmp_path, case):
    """``raster-oracle scenes`` with a malformed cached verdict (or a FIFO in its place):
    exit 0, the battery run again, a well-formed verdict cached; never a traceback."""
    cache = tmp_path / "cache"
    variant = backend.active().variant
    path = _plant(cache, PLANTED[case])
    env = {k: v for k, v in os.environ.items() if k != "RASTER_ORACLE_TRUST_BACKEND"}
    env |= {"RASTER_ORACLE_CACHE": str(cache), "RASTER_ORACLE_BACKEND": variant}
    cmd = [sys.executable, "-m", "raster_oracle.oracle.cli", "scenes"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr and "checking backend" in r.stderr
    cached = json.loads(path.read_text())
    assert V.valid_verdict(cached, V.machine_key(variant)) and cached["passed"] is True


# --- the pure helpers -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "value", [float("nan"), float("inf"), -float("inf"), "1", None, True, [1], 10**400, 2e9]
)
def test_check_number_refuses(value):
    with pytest.raises(U.UntrustedError) as info:
        U.check_number(value, what="field x", lo=-1e9, hi=1e9)
    assert "field x" in _one_line(info)


@pytest.mark.parametrize("value", [1.5, "3", None, True, -1, 11])
def test_check_int_refuses(value):
    with pytest.raises(U.UntrustedError):
        U.check_int(value, what="n", lo=0, hi=10)


def test_checks_keep_good_values():
    assert U.check_number(3, what="x", lo=0, hi=5) == 3.0
    assert U.check_int(7, what="n", lo=0, hi=10) == 7
    assert U.check_finite([1, 2.5], what="v") == [1.0, 2.5]
    with pytest.raises(U.UntrustedError):
        U.check_finite([1, float("nan")], what="v")


@pytest.mark.parametrize(
    "relative",
    ["../x", "a/../../x", "/etc/passwd", "~/x", "file:x", "C:x", "a\\b", "a\x00b", "", "s/.."],
)
def test_contained_refuses(tmp_path, relative):
    with pytest.raises(U.UntrustedError):
        U.contained(tmp_path, relative, what="uri")


def test_contained_follows_links_only_inside(tmp_path):
    (tmp_path / "inside").mkdir()
    (tmp_path / "inside" / "f").write_text("x")
    (tmp_path / "inside" / "ok").symlink_to(tmp_path / "inside" / "f")
    (tmp_path / "inside" / "out").symlink_to(tmp_path)
    assert U.contained(tmp_path / "inside", "ok", what="u") == tmp_path / "inside" / "f"
    (tmp_path / "secret").write_text("s")
    with pytest.raises(U.UntrustedError, match="outside"):
        U.contained(tmp_path / "inside", "out/secret", what="u")
    # a link out that comes back in stays inside
    assert U.contained(tmp_path / "inside", "out/inside/f", what="u") == tmp_path / "inside" / "f"


@pytest.mark.parametrize("text", ["", ".", "..", "a/b", "a\\b", "a\nb", "a\x00"])
def test_safe_component_refuses(text):
    with pytest.raises(U.UntrustedError):
        U.safe_component(text, what="name")


def test_safe_component_replaces_odd_characters():
    assert U.safe_component("a b<c>", what="name") == "a_b_c_"


def test_read_bounded_limit_and_kinds(tmp_path):
    f = tmp_path / "f"
    f.write_bytes(b"x" * 10)
    assert U.read_bounded(f, limit=10) == b"x" * 10
    with pytest.raises(U.UntrustedError, match="over the limit"):
        U.read_bounded(f, limit=9)
    os.mkfifo(tmp_path / "p")
    with pytest.raises(U.UntrustedError, match="FIFO"):
        bounded(U.read_bounded, tmp_path / "p", limit=10)
    with pytest.raises(U.UntrustedError, match="character device"):
        U.read_bounded("/dev/zero", limit=10)


def test_json_depth_is_iterative():
    deep: list = []
    node = deep
    for _ in range(200_000):
        node.append([])
        node = node[0]
    assert U.json_depth(deep, 64) == 65  # counted up to the limit + 1, no recursion


# --- sweeps: every field set to every hostile value, a refusal or a result, nothing else ------

SWEEP_VALUES = [None, -1, 0, 2**63, 1e300, "x", "", [], [1], {}, {"a": 1}, True, 0.5]


def _paths(node, prefix=()):
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        items = ()
    for k, v in items:
        out += _paths(v, (*prefix, k))
    return out


def _variants(base):
    for path in _paths(base):
        for value in SWEEP_VALUES:
            doc = json.loads(json.dumps(base))
            node = doc
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = value
            yield path, value, doc


def test_every_camera_file_field_of_every_type_is_refused_or_read(tmp_path):
    base = {"frames": [_frame()["frames"][0], {"world_to_view": EYE, "fov_y_deg": 40.0}]}
    path, escaped = tmp_path / "cameras.json", []
    for where, value, doc in _variants(base):
        path.write_text(json.dumps(doc))
        try:
            bounded(load_camera_file, path, BASE)
        except CameraFileError as exc:
            assert "\n" not in str(exc)
        except Exception as exc:  # the failure this test looks for
            escaped.append(f"{where}={value!r}: {type(exc).__name__}: {exc}")
    assert not escaped, "\n".join(escaped[:20])


def test_every_verdict_field_of_every_type_is_judged_without_an_exception():
    base = GOOD | {"passed": False, "failed": ["b"], "checks": [CHECK_OK, CHECK_BAD]}
    judged = [V.valid_verdict(doc, KEY) for _, _, doc in _variants(base)]
    assert len(judged) > 150 and not all(judged)


MANIFEST_VALUES = ["1", "-1", "1e300", "true", "[]", "{}", '"../x"', "nan", "inf", '"{0}"']
MANIFEST_VALUES += ['"x"', '["a"]', "{ a = 1 }", '"metrics.json"', "2097152", '"a\\u0000b"']
MANIFEST_KEYS = {
    "defaults": ["spp", "seed", "flip_mode", "profiles", "visibility", "camera_path", "exports"],
    "scenes.plate": ["scene", "file", "frames", "camera_path", "visibility", "channels"],
    "scenes.plate.channels.shadow": ["kind", "visibility", "fail_above", "fail_below"],
}


def test_every_manifest_field_of_every_type_is_refused_or_read(tmp_path):
    path, escaped = tmp_path / "ci.toml", []
    for table, keys in MANIFEST_KEYS.items():
        for key in keys:
            for value in MANIFEST_VALUES:
                other = "" if table == "scenes.plate" else "[scenes.plate]\n"
                path.write_text(f"{other}[{table}]\n{key} = {value}\n")
                try:
                    bounded(M.read_manifest, path)
                except M.ManifestError as exc:
                    assert "\n" not in str(exc)
                except Exception as exc:  # the failure this test looks for
                    escaped.append(f"[{table}] {key} = {value}: {type(exc).__name__}: {exc}")
    assert not escaped, "\n".join(escaped[:20])


def test_every_baseline_record_field_of_every_type_is_refused_or_compared(tmp_path):
    """A previous run's metrics.json with each field set to each hostile value: read and
    compared with this run's record, or refused (GateError); never another exception."""
    from raster_oracle.oracle.scoring.ci.regression import compare_baseline

    record = {
        "schema": METRICS_SCHEMA,
        "channel": "visibility",
        "kind": "visibility",
        "reference": {"scene": {"name": "plate", "resolution": [64, 36], "light_index": 0}},
        "frames": None,
        "noise_floor": {"mae": 0.01},
        "mae": 0.1,
        "platform": None,
    }
    path, escaped = tmp_path / "metrics.json", []
    for where, value, doc in _variants(record):
        path.write_text(json.dumps(doc))
        try:
            compare_baseline(record, bounded(load_baseline, path))
        except GateError as exc:
            assert "\n" not in str(exc)
        except Exception as exc:  # the failure this test looks for
            escaped.append(f"{where}={value!r}: {type(exc).__name__}: {exc}")
    assert not escaped, "\n".join(escaped[:20])


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_printed_verdicts_carry_no_control_characters(text, capsys):
    from raster_oracle.oracle.cli.gate_args import print_verdict

    verdict = _verdict(text).add(notes=[f"note {text}"])
    print_verdict(verdict, baseline=f"base {text}", prefix=f"{text}: ")
    out = capsys.readouterr()
    for stream in (out.out, out.err):
        lines = stream.splitlines()
        assert lines and not any(
            ord(c) < 32 and c != "\t" or 0x7F <= ord(c) <= 0x9F for line in lines for c in line
        )
