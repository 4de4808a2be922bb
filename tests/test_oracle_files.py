"""The shared rules of the oracle: JSON-ready records, atomic files, one-line errors."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from raster_oracle.oracle.errors import InputError, one_line
from raster_oracle.scenes.base.files import (
    atomic_copy,
    atomic_write,
    atomic_write_bytes,
    atomic_write_json,
)
from raster_oracle.scenes.base.records import jsonable, package_versions


def test_jsonable_converts_numpy_tuples_paths_and_non_finite_floats():
    record = {
        1: (np.int64(3), np.float32(0.5), np.bool_(True)),
        "a": np.arange(3, dtype=np.uint8),
        "f": [math.nan, math.inf, -math.inf, np.float64(-np.inf)],
        "p": Path("x") / "y",
        "s": {"b", "a"},
        "n": None,
    }
    out = jsonable(record)
    assert out == {
        "1": [3, 0.5, True],
        "a": [0, 1, 2],
        "f": ["nan", "inf", "-inf", "-inf"],
        "p": os.path.join("x", "y"),
        "s": ["a", "b"],
        "n": None,
    }
    assert type(out["1"][0]) is int and type(out["1"][2]) is bool
    json.dumps(out, allow_nan=False)  # plain JSON: no NaN literal needed


def test_jsonable_refuses_objects_json_cannot_hold():
    with pytest.raises(TypeError, match="not JSON-serialisable: object"):
        jsonable({"x": object()})


def test_package_versions_name_python_and_the_packages():
    versions = package_versions()
    assert versions["python"].count(".") == 2
    assert versions["numpy"] == np.__version__


def test_atomic_writes_replace_the_file_and_leave_no_temporary(tmp_path):
    target = tmp_path / "data.json"
    target.write_text("old")
    atomic_write_json(target, {"v": np.float32(1.5), "bad": math.nan})
    assert json.loads(target.read_text()) == {"v": 1.5, "bad": "nan"}
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    atomic_copy(tmp_path / "b.bin", tmp_path / "c.bin")
    assert (tmp_path / "c.bin").read_bytes() == b"\x00\x01"
    mask = os.umask(0)
    os.umask(mask)
    assert (tmp_path / "c.bin").stat().st_mode & 0o777 == 0o666 & ~mask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin", "c.bin", "data.json"]


def test_a_failed_atomic_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "keep.txt"
    target.write_text("old")

    def fail(tmp):
        Path(tmp).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, fail)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_one_line_escapes_control_characters():
    exc = InputError("bad file a\nb\r\x1b.exr\tx")
    assert one_line(exc) == "bad file a\\nb\\r\\x1b.exr\tx"
    assert one_line(KeyError("k"), with_type=True) == "KeyError: 'k'"
    assert isinstance(exc, ValueError)
