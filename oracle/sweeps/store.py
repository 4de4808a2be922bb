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

A store is untrusted when read (:meth:`SweepStore.check_integrity`, :meth:`SweepStore.rows`):
a file shorter than its header says or not a whole number of pages (SQLite reads the missing
bytes of a cut last page as zeros, and its own integrity check can pass), pages that fail
SQLite's ``integrity_check``, text that is not UTF-8 and a row whose ``params``, ``metrics``
or ``cost`` is not a JSON object, or whose metric values are not numbers (or null), are each a
:class:`StoreError` naming the damage.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sqlite3
import time
from pathlib import Path

from ...reports.viewer import check_viewer
from ...scenes.base.records import jsonable
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


#: The 16 bytes every SQLite 3 database file starts with.
SQLITE_MAGIC = b"SQLite format 3\x00"


class StoreError(InputError):
    """The store file cannot be used (not SQLite, another schema, not writable, damaged)."""


def file_damage(path: str | os.PathLike) -> str | None:
    """What is wrong with an SQLite file's size against its own header, or None.

    The header (the first 100 bytes) gives the page size and, when its "version-valid-for"
    number equals the change counter, the number of pages; a file shorter than that, or not
    a whole number of pages, lost its end. Not judged while a non-empty write-ahead log
    (``-wal``) lies beside the file: a checkpoint in progress writes the header first. A file
    that is not SQLite at all is left to SQLite's own error.
    """
    path = Path(path)
    wal = Path(f"{path}-wal")
    try:
        size = path.stat().st_size
        if wal.is_file() and wal.stat().st_size > 0:
            return None
        with open(path, "rb") as f:
            head = f.read(100)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if len(head) < 100 or not head.startswith(SQLITE_MAGIC):
        return None
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    if page < 512 or page & (page - 1):
        return f"its header names a page size of {page} bytes"
    if size % page:
        return f"truncated: {size} bytes is not a whole number of {page}-byte pages"
    pages = int.from_bytes(head[28:32], "big")
    if pages and head[24:28] == head[92:96] and size < pages * page:
        return f"truncated: {size // page} pages of the {pages} its header counts"
    return None


def _value_error(value) -> str | None:
    """Why a stored metric value is unusable (not a finite number or null), or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"a JSON {_json_kind(value)}"
    return None if math.isfinite(value) else f"{value} (not finite)"


def _json_kind(value) -> str:
    kinds = {bool: "boolean", str: "string", list: "list", dict: "object"}
    return kinds.get(type(value), type(value).__name__)


def metrics_error(metrics: dict) -> str | None:
    """Why a row's ``metrics`` object is unusable, or None: every value is a finite number or
    null, ``noise_floor`` an object of those (or null)."""
    for key, value in metrics.items():
        if key == "noise_floor" and value is not None:
            if not isinstance(value, dict):
                return f"metrics['noise_floor'] is a JSON {_json_kind(value)}, not an object"
            for name, floor in value.items():
                if (why := _value_error(floor)) is not None:
                    return f"metrics['noise_floor'][{name!r}] is {why}, not a number"
        elif key != "noise_floor" and (why := _value_error(value)) is not None:
            return f"metrics[{key!r}] is {why}, not a number"
    return None


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
        if readonly and (why := file_damage(self.path)) is not None:
            raise StoreError(f"sweep database {self.path}: {why}")
        if not readonly and self.path.is_file() and self.path.stat().st_size > 0:
            # An existing file is checked read-only first: a foreign database, another
            # schema version or a damaged file is refused without a byte of it changed.
            with SweepStore(self.path, readonly=True) as existing:
                existing.check_integrity(quick=True)
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
        except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:
            raise self._damaged(exc) from None
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
        except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:  # missing table, wrong
            raise self._damaged(exc) from None  # shape, damaged pages, text not UTF-8

    def _damaged(self, exc: Exception) -> StoreError:
        """The :class:`StoreError` of an error SQLite (or the decoding of its text) raised."""
        if isinstance(exc, UnicodeDecodeError):
            return StoreError(f"sweep database {self.path}: damaged: text that is not UTF-8")
        return StoreError(f"sweep database {self.path}: {exc}")

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
        if row["metrics"] is not None and (why := metrics_error(row["metrics"])) is not None:
            raise StoreError(f"sweep database {self.path}: row {str(row['key'])[:16]!r}: {why}")
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
        except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:
            raise self._damaged(exc) from None
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
        except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:
            raise self._damaged(exc) from None
        return out

    def check_integrity(self, *, quick: bool = False) -> None:
        """Raise :class:`StoreError` naming the damage when the file is shorter than its
        header says (:func:`file_damage`) or SQLite's ``integrity_check`` (``quick_check``
        with ``quick``: pages and records, not indexes against their tables) finds any."""
        if (why := file_damage(self.path)) is not None:
            raise StoreError(f"sweep database {self.path}: {why}")
        pragma = "quick_check" if quick else "integrity_check"
        try:
            found = self.conn.execute(f"PRAGMA {pragma}(1)").fetchone()[0]
        except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:
            raise self._damaged(exc) from None
        if found != "ok":
            raise StoreError(
                f"sweep database {self.path}: damaged: SQLite's {pragma} says {found!r}"
            )

    def integrity_ok(self) -> bool:
        try:
            self.check_integrity()
        except StoreError:
            return False
        return True
