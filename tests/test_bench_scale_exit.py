"""Issue 48: ``bench scale`` refuses bad sizes before any child runs, exits non-zero when a
size fails, and its per-size child dies with it (even when it is killed outright)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import psutil
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.studies import bench_scale


@pytest.mark.parametrize("sizes", ["100000001", "1_0", "10,1__0", "9" * 5000])
def test_bad_sizes_exit_2_with_one_line(sizes, capfd, monkeypatch):
    monkeypatch.setattr(bench_scale, "_run_child", lambda argv: pytest.fail("a child ran"))
    assert main(["bench", "scale", "--sizes", sizes, "--quiet"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("raster-oracle: error: scene 'meadow:n="), err


def test_a_failed_size_exits_1_with_its_error_in_the_figures(capfd, monkeypatch):
    monkeypatch.setattr(bench_scale, "_run_child", lambda argv: (1, "", "MemoryError: boom"))
    assert main(["bench", "scale", "--sizes", "10", "--quiet"]) == 1
    out, err = capfd.readouterr()
    assert '"error": "exit 1: MemoryError: boom"' in out
    assert err.strip() == "raster-oracle: bench scale: size(s) 10 failed"


def test_the_child_dies_when_the_parent_is_killed(tmp_path):
    argv = [sys.executable, "-m", "raster_oracle.oracle.cli", "bench", "scale"]
    argv += ["--sizes", "300000", "--only", "fxaa", "--quiet"]
    parent = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        children = []
        while not children and time.monotonic() < deadline and parent.poll() is None:
            children = psutil.Process(parent.pid).children()
            time.sleep(0.05)
        assert children, "no child started"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(children, timeout=5)
        assert not alive, alive
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
