"""The sweep store: one SQLite file (WAL mode) with a row per case.

Only the sweep's client process writes, one transaction per finished case, so a ``kill -9``
at any moment loses at most the cases in flight: SQLite's write-ahead log makes every
committed row durable and an interrupted transaction invisible, and the next run finds every
committed row and skips it. Optuna studies of ``raster-oracle tune`` live in the same file
(their own tables).

Table ``sweep_cases``: ``key`` (primary key, :func:`case_key`), ``sweep`` (spec name),
``scene``, ``technique``, ``family``, ``params`` (JSON, every parameter with its value),
``frame``, ``path`` (camera or light path, or NULL), ``width``, ``height``, ``spp``, ``seed``,
``metrics`` (JSON: every metric key, the noise floor under ``noise_floor``), ``cost`` (JSON),
``wall_seconds`` (the case's own time on its worker), ``status`` (``done`` or ``failed``),
``error`` (one line, or NULL), ``finished`` (Unix time the row was written) and ``run_id``
(the run that wrote it). Table ``sweep_images``: ``key`` and ``images`` (JSON: thumbnails of
the reference, the candidate and its primary error map as ``data:`` URIs). Table
``sweep_viewers``: ``key`` and ``viewer`` (JSON: the pixel viewer's record of the case,
:func:`reports.viewer.viewer_record`, at the thumbnails' resolution; about 0.1 to 1 MB a case).
A store written before viewers were kept lacks that table: opened for writing it gains it
(``CREATE TABLE IF NOT EXISTS``, its old rows keep no viewer); read only, it has no viewers.
"""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3
import time
from pathlib import Path

from ...reports.viewer import check_viewer
from ...scenes.records import jsonable
from ..errors import InputError

__all__ = [
    "SCHEMA_VERSION",
    "SweepStore",
    "StoreError",
    "case_key",
]

#: Version of the table layout and of the key's meaning; part of every key.
SCHEMA_VERSION = 1
#: How long a connection waits for a lock held by another process (an Optuna study, a
#: reader) before failing, in seconds.
BUSY_TIMEOUT_S = 30.0

_COLUMNS = (
    "key",
    "sweep",
    "scene",
    "technique",
    "family",
    "params",
    "frame",
    "path",
    "width",
    "height",
    "spp",
    "seed",
    "metrics",
    "cost",
    "wall_seconds",
    "status",
    "error",
    "finished",
    "run_id",
)

_CREATE = """
CREATE TABLE IF NOT EXISTS sweep_meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS sweep_cases (
    key TEXT PRIMARY KEY,
    sweep TEXT NOT NULL,
    scene TEXT NOT NULL,
    technique TEXT NOT NULL,
    family TEXT NOT NULL,
    params TEXT NOT NULL,
    frame INTEGER NOT NULL,
    path TEXT,
    width INTEGER NOT NULL,
    height INTEGER NOT NULL,
    spp INTEGER NOT NULL,
    seed INTEGER NOT NULL,
    metrics TEXT,
    cost TEXT,
    wall_seconds REAL,
    status TEXT NOT NULL CHECK (status IN ('done', 'failed')),
    error TEXT,
    finished REAL NOT NULL,
    run_id TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS sweep_cases_by_sweep ON sweep_cases (sweep);
CREATE TABLE IF NOT EXISTS sweep_images (key TEXT PRIMARY KEY, images TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS sweep_viewers (key TEXT PRIMARY KEY, viewer TEXT NOT NULL);
"""


class StoreError(InputError):
    """The store file cannot be used (not SQLite, another schema, not writable)."""


def dumps(value) -> str:
    """Canonical JSON (sorted keys, no NaN literals)."""
    return json.dumps(jsonable(value), sort_keys=True, allow_nan=False)


def case_key(record: dict) -> str:
    """SHA-256 of a case's identity: scene content, technique, every parameter, frame, spp,
    seed, backend variant and versions (``record`` is built by the sweep)."""
    return hashlib.sha256(dumps({"schema": SCHEMA_VERSION, **record}).encode()).hexdigest()


def _thumbnails(text) -> dict | None:
    """A row's thumbnails (a JSON object: name -> data URI), or None when the stored value is
    not a JSON object (a hand-edited store: raw bytes, a list): thumbnails are decoration, so
    a bad one is left out, never fatal. The report keeps only ``data:`` image URIs of it."""
    try:
        value = json.loads(text)
    except (TypeError, ValueError):
        return None
    return value if isinstance(value, dict) and value else None


class SweepStore:
    """The SQLite file of a sweep (created when missing).

    Parameters
    ----------
    path : the database file.
    readonly : open an existing file for reading only (reports).
    """

    def __init__(self, path: str | os.PathLike, *, readonly: bool = False):
        self.path = Path(path)
        self.readonly = readonly
        if readonly and not self.path.is_file():
            raise StoreError(f"sweep database {self.path}: no such file")
        if self.path.exists() and not self.path.is_file():
            raise StoreError(f"sweep database {self.path} exists and is not a file")
        if not readonly and self.path.is_file() and self.path.stat().st_size > 0:
            # An existing file is checked read-only first: a foreign database or another
            # schema version is refused without a byte of it changed.
            SweepStore(self.path, readonly=True).conn.close()
        try:
            if readonly:
                uri = f"file:{self.path.resolve()}?mode=ro"
                self.conn = sqlite3.connect(uri, uri=True, timeout=BUSY_TIMEOUT_S)
            else:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self.conn = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S)
                self.conn.execute("PRAGMA journal_mode=WAL")
                # WAL + NORMAL: a committed row survives a killed process (only an OS crash
                # may lose the last transactions); the file never corrupts.
                self.conn.execute("PRAGMA synchronous=NORMAL")
                self.conn.executescript(_CREATE)
                self.conn.execute(
                    "INSERT OR IGNORE INTO sweep_meta VALUES ('schema', ?)", (str(SCHEMA_VERSION),)
                )
                self.conn.commit()
            row = self.conn.execute("SELECT value FROM sweep_meta WHERE name = 'schema'").fetchone()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"sweep database {self.path}: {exc}") from None
        if row is None or row[0] != str(SCHEMA_VERSION):
            found = row[0] if row else "none"
            raise StoreError(
                f"sweep database {self.path}: schema {found}, expected {SCHEMA_VERSION}"
            )

    def close(self) -> None:
        if not self.readonly:
            # Leave a single file behind: back to rollback journalling when this is the last
            # connection (readers opened later with mode=ro then create no -wal/-shm files that
            # they could not remove). Another open connection keeps WAL: locked, ignored.
            try:
                self.conn.execute("PRAGMA journal_mode=DELETE")
            except sqlite3.OperationalError:
                pass
        self.conn.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def url(self) -> str:
        """SQLAlchemy URL of the file (Optuna's storage)."""
        return f"sqlite:///{self.path.resolve()}"

    def finished_keys(self, *, include_failed: bool = True) -> set[str]:
        """Keys of the rows already written (failed ones too unless ``include_failed=False``)."""
        sql = "SELECT key FROM sweep_cases"
        if not include_failed:
            sql += " WHERE status = 'done'"
        return {r[0] for r in self.conn.execute(sql)}

    def put(self, row: dict, *, images: dict | None = None) -> None:
        """Write (or replace) one case row, and its thumbnails when given, and commit.
        ``images["viewer"]`` (a pixel viewer record, :func:`oracle.sweeps.thumbnails.case_images`)
        goes to the ``sweep_viewers`` table, the rest to ``sweep_images``."""
        images = dict(images or {})
        viewer = images.pop("viewer", None)
        values = dict(row)
        for name in ("params", "metrics", "cost"):
            if values.get(name) is not None:
                values[name] = dumps(values[name])
        values.setdefault("finished", time.time())
        missing = [c for c in _COLUMNS if c not in values and c not in ("error", "path")]
        if missing:
            raise StoreError(f"sweep row lacks {', '.join(missing)}")
        cols = ", ".join(_COLUMNS)
        marks = ", ".join("?" for _ in _COLUMNS)
        with self.conn:  # one transaction per case
            self.conn.execute(
                f"INSERT OR REPLACE INTO sweep_cases ({cols}) VALUES ({marks})",
                [values.get(c) for c in _COLUMNS],
            )
            if images:
                self.conn.execute(
                    "INSERT OR REPLACE INTO sweep_images VALUES (?, ?)",
                    (values["key"], dumps(images)),
                )
            if viewer is not None:
                self.conn.execute(
                    "INSERT OR REPLACE INTO sweep_viewers VALUES (?, ?)",
                    (values["key"], dumps(viewer)),
                )

    def get(self, key: str) -> dict | None:
        rows = self.rows(where="key = ?", args=(key,))
        return rows[0] if rows else None

    def rows(self, *, sweep: str | None = None, where: str = "", args=()) -> list[dict]:
        """Every row (of ``sweep``), JSON columns decoded, in the order they were written."""
        clauses, params = [], list(args)
        if where:
            clauses.append(where)
        if sweep is not None:
            clauses.append("sweep = ?")
            params.append(sweep)
        sql = f"SELECT {', '.join(_COLUMNS)} FROM sweep_cases"
        if clauses:
            sql += " WHERE " + " AND ".join(clauses)
        sql += " ORDER BY finished, key"
        try:
            return [self._row(r) for r in self.conn.execute(sql, params).fetchall()]
        except sqlite3.DatabaseError as exc:  # missing table, wrong shape, damaged pages
            raise StoreError(f"sweep database {self.path}: {exc}") from None

    def _row(self, values) -> dict:
        """One row as a record; rows are untrusted (a store can be edited by hand): a JSON
        column that is not a JSON object (or null) is a StoreError naming the row."""
        row = dict(zip(_COLUMNS, values, strict=True))
        for name in ("params", "metrics", "cost"):
            text = row[name]
            if text is None:
                continue
            try:
                value = json.loads(text)
            except (TypeError, ValueError):
                value = None
            if not isinstance(value, dict):
                raise StoreError(
                    f"sweep database {self.path}: row {str(row['key'])[:16]!r}: {name} is not "
                    "a JSON object"
                )
            row[name] = value
        return row

    def images(self, keys) -> dict[str, dict]:
        """Thumbnails (``reference``, ``candidate``, ``error`` data URIs) of ``keys``."""
        out = {}
        try:
            for key in keys:
                r = self.conn.execute("SELECT images FROM sweep_images WHERE key = ?", (key,))
                hit = r.fetchone()
                if hit is not None and (images := _thumbnails(hit[0])):
                    out[key] = images
        except sqlite3.OperationalError:  # a store written before thumbnails were kept
            return {}
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"sweep database {self.path}: {exc}") from None
        return out

    def viewers(self, keys) -> dict[str, dict]:
        """Pixel viewer records of ``keys`` (those that have one). Each is checked
        (:func:`reports.viewer.check_viewer`): a damaged or hand-edited one is left out, as a
        bad thumbnail is, since the viewer is an aid to the report, never its content."""
        out = {}
        try:
            for key in keys:
                hit = self.conn.execute(
                    "SELECT viewer FROM sweep_viewers WHERE key = ?", (key,)
                ).fetchone()
                if hit is None:
                    continue
                try:
                    viewer = check_viewer("viewer", json.loads(hit[0]))
                except (TypeError, ValueError):
                    continue
                if viewer is not None:
                    out[key] = viewer
        except sqlite3.OperationalError:  # a store written before viewers were kept
            return {}
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"sweep database {self.path}: {exc}") from None
        return out

    def check_integrity(self) -> None:
        """Raise :class:`StoreError` when SQLite's ``integrity_check`` finds damage."""
        try:
            ok = self.integrity_ok()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"sweep database {self.path}: {exc}") from None
        if not ok:
            raise StoreError(f"sweep database {self.path}: fails SQLite's integrity check")

    def integrity_ok(self) -> bool:
        return self.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
