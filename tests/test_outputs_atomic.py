"""Issue 48: a command's output folder appears whole or not at all (write aside, rename
last, the folder included), and a stop or failure leaves the previous output as it was."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.scenes.base import files

SMALL = ["--width", "16", "--height", "12", "--spp", "1", "--quiet", "--no-cache"]


class Stop(Exception):
    pass


def test_a_failure_leaves_no_output_folder_and_no_staging(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(Stop), files.staged_folder(out) as stage:
        (stage / "reference.exr").write_bytes(b"half")
        raise Stop
    assert sorted(os.listdir(tmp_path)) == []


def test_a_failure_keeps_the_previous_output_whole(tmp_path):
    out = tmp_path / "out"
    (out / "case").mkdir(parents=True)
    (out / "metrics.json").write_text("old")
    (out / "case" / "metrics.json").write_text("old case")
    with pytest.raises(Stop), files.staged_folder(out) as stage:
        (stage / "case").mkdir()
        (stage / "metrics.json").write_text("new")
        raise Stop
    assert (out / "metrics.json").read_text() == "old"
    assert (out / "case" / "metrics.json").read_text() == "old case"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_a_reused_folder_gets_whole_sub_folders_and_its_record_last(tmp_path, monkeypatch):
    out = tmp_path / "out"
    (out / "case").mkdir(parents=True)
    (out / "case" / "stale.exr").write_text("earlier run")
    (out / "keep.txt").write_text("the user's")
    moved = []
    replace, rename = os.replace, os.rename

    def spy(move):
        def run(src, dst):
            moved.append(os.path.basename(dst))
            return move(src, dst)

        return run

    monkeypatch.setattr(os, "replace", spy(replace))
    monkeypatch.setattr(os, "rename", spy(rename))
    with files.staged_folder(out, last=("metrics.json",)) as stage:
        (stage / "case").mkdir()
        (stage / "case" / "metrics.json").write_text("new case")
        for name in ("metrics.json", "report.html", "candidate.json", "candidate.exr"):
            (stage / name).write_text(name)
    assert moved[-1] == "metrics.json"
    assert moved.index("candidate.json") > moved.index("candidate.exr")
    assert sorted(os.listdir(out / "case")) == ["metrics.json"]  # no stale file kept
    assert (out / "keep.txt").read_text() == "the user's"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_staging_left_by_a_killed_run_is_swept_and_a_foreign_folder_kept(tmp_path):
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    dead = tmp_path / f".out.partial-{child.pid}-x"
    dead.mkdir()
    (dead / files.STAGING_MARK).write_bytes(b"")
    (dead / "reference.exr").write_bytes(b"half")
    foreign = tmp_path / f".out.partial-{child.pid}-y"  # no mark: not ours
    foreign.mkdir()
    with files.staged_folder(tmp_path / "out") as stage:
        (stage / "a.txt").write_text("a")
    assert sorted(os.listdir(tmp_path)) == [foreign.name, "out"]


def test_reference_stopped_while_publishing_leaves_no_output(tmp_path, monkeypatch):
    """Issue 48: SIGTERM (SystemExit) after reference.exr was written left it alone in --out."""
    from raster_oracle.oracle.reference import store

    copy = store.atomic_copy

    def copy_then_stop(src, dst):
        copy(src, dst)
        raise SystemExit(128 + signal.SIGTERM)

    monkeypatch.setattr(store, "atomic_copy", copy_then_stop)
    with pytest.raises(SystemExit):
        main(["reference", "plate", *SMALL, "--out", str(tmp_path / "o")])
    assert sorted(os.listdir(tmp_path)) == []
    monkeypatch.setattr(store, "atomic_copy", copy)
    assert main(["reference", "plate", *SMALL, "--out", str(tmp_path / "o")]) == 0
    assert sorted(os.listdir(tmp_path / "o")) == ["reference.exr", "reference.json"]


def test_an_in_process_stop_is_a_system_exit_even_with_threads_alive(tmp_path, monkeypatch):
    """``main(argv)`` called in-process (a test, a script) hands a stop back as SystemExit;
    only the command itself (``main()`` on ``sys.argv``) ends the process at once when other
    threads are alive (it ended the whole test run with exit 143)."""
    import threading

    from raster_oracle.oracle.cli import app
    from raster_oracle.oracle.reference import store

    ended = []
    monkeypatch.setattr(app, "_exit_now", ended.append)
    copy = store.atomic_copy

    def copy_then_stop(src, dst):
        copy(src, dst)
        raise SystemExit(128 + signal.SIGTERM)

    monkeypatch.setattr(store, "atomic_copy", copy_then_stop)
    alive = threading.Event()
    thread = threading.Thread(target=alive.wait, daemon=True)
    thread.start()
    try:
        with pytest.raises(SystemExit):
            main(["reference", "plate", *SMALL, "--out", str(tmp_path / "o")])
    finally:
        alive.set()
    assert ended == []
