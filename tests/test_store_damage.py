"""Sweep stores that are damaged, hand-edited or in the way of an output (issue 31).

A damaged store (truncated, a byte flipped inside a page) is refused by ``report --sweep``
with exit 2 and one line naming the damage; so is a row whose metric values are not
numbers. A ``sweep`` that refuses an output path holding a store leaves its bytes as they were.
"""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3
import subprocess
import sys

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.sweeps.store import SweepStore
from test_sweep_report import _real_store, _report, _sql

#: SQLite's default page size, the stores' (the tests read it from the header too).
PAGE = 4096


def _one_line_refusal(tmp_path, db, capsys, *words):
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert db.name in err and all(w in err for w in words), err
    assert not out.exists() and not out.with_suffix(".json").exists()
    return err


#: Where a store is cut: a fraction of its bytes, or bytes off its end. Cuts inside the last
#: page (its 4 rows leave most of it empty) pass SQLite's own integrity check, which reads
#: the missing bytes as zeros (measured with SQLite 3.40 before the size check was added).
CUTS = {"25%": 0.25, "50%": 0.50, "95%": 0.95, "last byte": 1, "half the last page": PAGE // 2}


@pytest.mark.parametrize("cut", list(CUTS))
def test_truncated_store_is_refused(tmp_path, capsys, cut):
    db = _real_store(tmp_path / "s.db", n=4)
    data = db.read_bytes()
    amount = CUTS[cut]
    keep = int(len(data) * amount) if isinstance(amount, float) else len(data) - amount
    db.write_bytes(data[:keep])
    _one_line_refusal(tmp_path, db, capsys, "truncated")


def test_store_short_of_whole_pages_is_refused(tmp_path, capsys):
    """Cut at a page boundary: a whole number of pages, fewer than the header counts."""
    db = _real_store(tmp_path / "s.db")
    data = db.read_bytes()
    assert int.from_bytes(data[16:18], "big") == PAGE
    db.write_bytes(data[: len(data) - PAGE])
    _one_line_refusal(tmp_path, db, capsys, "truncated", "pages")


def _root_page(db, table):
    conn = sqlite3.connect(db)
    (root,) = conn.execute("SELECT rootpage FROM sqlite_master WHERE name = ?", (table,)).fetchone()
    conn.close()
    return root


def _flip(db, offset, mask=0xFF):
    data = bytearray(db.read_bytes())
    data[offset] ^= mask
    db.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "where",
    ["page type of sweep_cases' root", "cell count of sweep_cases' root", "a key's text"],
)
def test_flipped_byte_inside_a_page_is_refused(tmp_path, capsys, where):
    """A byte of the b-tree page header of the cases' table (its page type, its cell count),
    or of a row's text (no longer UTF-8)."""
    db = _real_store(tmp_path / "s.db")
    start = (_root_page(db, "sweep_cases") - 1) * PAGE
    if where == "page type of sweep_cases' root":
        _flip(db, start)
    elif where == "cell count of sweep_cases' root":
        _flip(db, start + 3, 0x40)
    else:
        with SweepStore(db, readonly=True) as store:
            key = store.rows()[5]["key"]
        data = db.read_bytes()
        assert data.count(key.encode()) >= 1
        _flip(db, data.index(key.encode()) + 20, 0x80)  # '0' -> 0xB0: not UTF-8
    _one_line_refusal(tmp_path, db, capsys)


METRICS = {
    "a string": {"misclassified_fraction": "0.3", "noise_floor": {}},
    "a list": {"misclassified_fraction": [0.3, 0.2], "noise_floor": {}},
    "an object": {"misclassified_fraction": {"v": 0.3}, "noise_floor": {}},
    "a boolean": {"misclassified_fraction": True, "noise_floor": {}},
    "noise_floor a string": {"misclassified_fraction": 0.3, "noise_floor": "small"},
    "noise_floor a list": {"misclassified_fraction": 0.3, "noise_floor": [0.01]},
    "a noise floor a string": {
        "misclassified_fraction": 0.3,
        "noise_floor": {"misclassified_fraction": "0.01"},
    },
}


@pytest.mark.parametrize("kind", list(METRICS))
def test_metric_values_that_are_not_numbers_are_refused(tmp_path, capsys, kind):
    """A hand-edited or foreign row: one line naming the row and the metric (was, for the
    noise floor, an AttributeError traceback)."""
    db = _real_store(tmp_path / "s.db")
    _sql(db, f"UPDATE sweep_cases SET metrics = '{json.dumps(METRICS[kind])}' WHERE rowid = 3")
    err = _one_line_refusal(tmp_path, db, capsys, "metrics[")
    assert "not a number" in err or "not an object" in err


def test_null_metrics_and_floors_are_read(tmp_path, capsys):
    """Null is a metric undefined on the case (the scorer writes it): not damage."""
    db = _real_store(tmp_path / "s.db", n=4)
    edited = {"misclassified_fraction": 0.3, "visibility_mae": None, "noise_floor": None}
    _sql(db, f"UPDATE sweep_cases SET metrics = '{json.dumps(edited)}' WHERE rowid = 3")
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    assert out.is_file()


#: A writer killed after committing: its rows are in the write-ahead log beside the store.
_KILLED_WRITER = """
import os, sqlite3, sys
conn = sqlite3.connect(sys.argv[1])
conn.execute("PRAGMA journal_mode=WAL")
conn.execute("UPDATE sweep_cases SET wall_seconds = 7.0")
conn.commit()
os._exit(0)
"""


def _hot_wal(db):
    subprocess.run([sys.executable, "-c", _KILLED_WRITER, str(db)], check=True)
    assert os.path.getsize(f"{db}-wal") > 0


def test_store_with_a_killed_writers_log_is_read_whole(tmp_path, capsys):
    """The size check stands aside while a write-ahead log holds committed rows."""
    db = _real_store(tmp_path / "s.db", n=4)
    _hot_wal(db)
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    with SweepStore(db, readonly=True) as store:
        assert {r["wall_seconds"] for r in store.rows()} == {7.0}


def _digests(folder):
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


@pytest.mark.parametrize("name", ["report.json", "report.html"])
@pytest.mark.parametrize("wal", [False, True], ids=["closed", "hot-wal"])
def test_sweep_refusing_a_store_as_output_leaves_it_byte_for_byte(
    tmp_path, capsys, monkeypatch, name, wal
):
    """``sweep SPEC --out D --db D/report.json`` (or ``.html``) with a store of 40 rows
    there (its log too, when a killed writer left one): exit 2, one line, every byte kept,
    every row readable."""
    out = tmp_path / "D"
    out.mkdir()
    db = _real_store(out / name)
    if wal:
        _hot_wal(db)
    spec = tmp_path / "spec.toml"
    spec.write_text(
        'name = "t"\n[defaults]\nwidth = 8\nheight = 6\nspp = 1\n'
        '[[case]]\nscenes = ["plate"]\ntechnique = "shadow-map"\n'
    )
    monkeypatch.setenv("RASTER_ORACLE_CACHE", str(tmp_path / "cache"))
    before = _digests(out)
    capsys.readouterr()
    rc = main(["sweep", str(spec), "--out", str(out), "--db", str(db), "--workers", "0"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "would destroy it" in err, err
    assert _digests(out) == before
    with SweepStore(db, readonly=True) as store:
        assert len(store.rows()) == 40
    assert not (tmp_path / "cache").exists()
