"""Issue 48: ``baseline accept`` killed outright (``kill -9``) left an empty
``previous/NNN`` and an ``.incoming-*`` folder; the next accept removes both (under the
lock, links never followed) and numbers its ``previous`` after what is really kept."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

from raster_oracle.oracle.scoring.ci.baseline import accept_baseline
from raster_oracle.oracle.scoring.ci.checks import METRICS_SCHEMA


def _run(folder, value):
    folder.mkdir(parents=True)
    (folder / "metrics.json").write_text(json.dumps({"schema": METRICS_SCHEMA, "v": value}))
    return folder


#: An accept that stops for good once it has claimed previous/NNN and written its files aside.
_KILLED = """
import os, sys, time
from raster_oracle.oracle.scoring.ci import baseline_files
from raster_oracle.oracle.scoring.ci.baseline import accept_baseline
replace = os.replace
def stall(src, dst):
    print("stalled", flush=True)
    time.sleep(600)
baseline_files.os.replace = stall
accept_baseline(sys.argv[1], into=sys.argv[2], note="killed")
"""


def test_the_next_accept_removes_what_a_killed_one_left(tmp_path):
    into = tmp_path / "base"
    accept_baseline(_run(tmp_path / "r1", 1), into=into, note="first")
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("keep")
    child = subprocess.Popen(
        [sys.executable, "-c", _KILLED, str(_run(tmp_path / "r2", 2)), str(into)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline().strip() == "stalled"
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
        child.stdout.close()
    platform = into / "default"
    assert [p.name for p in (platform / "previous").iterdir()] == ["001"]
    assert list((platform / "previous" / "001").iterdir()) == []
    assert any(p.name.startswith(".incoming-") for p in platform.iterdir())
    (platform / ".incoming-link").symlink_to(outside, target_is_directory=True)
    accept_baseline(_run(tmp_path / "r3", 3), into=into, note="third")
    names = sorted(p.name for p in platform.iterdir())
    assert names == [".accept.lock", ".incoming-link", "baseline.json", "metrics.json", "previous"]
    assert (outside / "keep.txt").read_text() == "keep"
    assert [p.name for p in (platform / "previous").iterdir()] == ["001"]
    kept = json.loads((platform / "previous" / "001" / "metrics.json").read_text())
    assert kept["v"] == 1
    assert json.loads((platform / "metrics.json").read_text())["v"] == 3
    note = json.loads((platform / "baseline.json").read_text())
    assert note["previous"] == "previous/001"
    assert os.path.islink(platform / ".incoming-link")
