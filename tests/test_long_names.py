"""Issue 48: names over 255 bytes (a component) or 4095 (a path), scene names of 5,000
characters and names that are not UTF-8 are handled: one line and exit 2 for what cannot
name a file, and a valid EXR read and written whatever bytes its name holds."""

from __future__ import annotations

import os

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.scenes.base import untrusted

SMALL = ["--width", "16", "--height", "12", "--spp", "1", "--quiet", "--no-cache"]
LONG = "a" * 300


@pytest.mark.parametrize(
    "argv",
    [
        ["reference", "plate", "--out", f"o/{LONG}"],
        ["reference", "plate", "--camera-file", f"{LONG}.json", "--out", "o"],
        ["reference", LONG, "--out", "o"],
        ["reference", f"{LONG}.xml", "--out", "o"],
        ["reference", "meadow:n=" + "9" * 5000, "--out", "o"],
        ["reference", "plate", "--out", "o/" + "b/" * 2100],
    ],
)
def test_names_that_cannot_name_a_file_are_one_line(argv, tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, *SMALL]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and len(err[0]) < 600 and "Traceback" not in err[0], err
    assert os.listdir(tmp_path) == []


def test_path_problem_measures_bytes():
    assert untrusted.path_problem("x/" + "é" * 127) is None  # 254 bytes
    assert "256 bytes" in untrusted.path_problem("x/" + "é" * 128)
    assert "NUL" in untrusted.path_problem("a\0b")
    assert untrusted.path_problem(os.fsdecode(b"ok\xff")) is None


def test_an_exr_whose_name_is_not_utf8_is_read_and_scored(tmp_path):
    name = os.fsdecode(os.path.join(os.fsencode(tmp_path), b"cand\xff.exr"))
    write_exr(name, {"visibility": np.ones((12, 16), np.float32)})
    assert read_exr(name)["visibility"].shape == (12, 16)
    out = os.fsdecode(os.path.join(os.fsencode(tmp_path), b"out\xfe"))
    rc = main(["score", "plate", "--candidate", name, *SMALL, "--out", out])
    assert rc in (0, 1) and os.path.isfile(os.path.join(out, "metrics.json"))
