"""Approved baselines: ``raster-oracle baseline accept RUN_DIR --into BASELINE_DIR``.

A baseline folder holds one approved run per platform (``--platform NAME`` of the run;
``default`` without one): ``BASELINE_DIR/<platform>/metrics.json`` (the run's record, a
``score`` or a ``score-folder`` one) and ``baseline.json`` (who approved what: the note, the
time, the run folder, the run's failed checks). Accepting a new run moves the platform's
current files to ``previous/NNN/`` first (numbered from 001), so every approval and its note
is kept: the human step every golden-image tool has.

``--baseline BASELINE_DIR`` (with the run's ``--platform``) finds the platform's
``metrics.json`` (:func:`resolve_baseline`).

Nothing is lost: an accept holds the platform folder's lock (``.accept.lock``; concurrent
accepts into one folder take turns, each leaving its trace), claims ``previous/NNN`` with an
atomic ``mkdir``, writes the new files aside (``.incoming-*``), then renames the current files
into ``previous/NNN`` and the new ones into place. Links inside the baseline folder (the
platform folder, ``previous``, the current files) are never followed: refused with one line,
as are a platform folder that is a file, a ``previous`` that is no folder, a run's
``metrics.json`` that is no regular file, and a platform that is not a name.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from ...scenes.base.files import atomic_write_bytes, atomic_write_json
from ...scenes.base.untrusted import LIMITS, loads_json, read_bounded
from .gates import FOLDER_SCHEMA, METRICS_SCHEMA, GateError

__all__ = [
    "BASELINE_SCHEMA",
    "DEFAULT_PLATFORM",
    "accept_baseline",
    "check_platform",
    "resolve_baseline",
]

#: ``schema`` of ``baseline.json``.
BASELINE_SCHEMA = "raster-oracle/baseline/1"
#: The platform folder of a run made without ``--platform``.
DEFAULT_PLATFORM = "default"
_FILES = ("metrics.json", "baseline.json")


def check_platform(name: str | None) -> str | None:
    """A ``--platform`` name is a plain folder name (letters, digits, ``.``, ``_``, ``-``)."""
    if name is None:
        return None
    if not isinstance(name, str):
        raise GateError(f"platform {name!r}: a platform is a name, not a {type(name).__name__}")
    ok = name and name not in (".", "..") and all(c.isalnum() or c in "._-" for c in name)
    if not ok:
        raise GateError(
            f"--platform {name!r}: use letters, digits, '.', '_' and '-' (a folder name)"
        )
    return name


def resolve_baseline(path, *, platform: str | None = None) -> Path:
    """The ``metrics.json`` a ``--baseline`` path stands for: the file itself, a run's folder
    (its ``metrics.json``), or a baseline folder (its ``<platform>/metrics.json``; ``default``
    without ``platform``). A baseline folder without that platform is a :class:`GateError`
    naming the platforms it has."""
    path = Path(path)
    if not path.is_dir():
        return path
    found = _find_baseline(path, platform)
    root = path.resolve()
    if root not in found.resolve().parents:
        raise GateError(f"--baseline {found} leads outside {path} (a link out is not followed)")
    return found


def _find_baseline(path: Path, platform: str | None) -> Path:
    if (path / "metrics.json").is_file() and platform is None:
        return path / "metrics.json"
    folder = path / (platform or DEFAULT_PLATFORM)
    if (folder / "metrics.json").is_file():
        return folder / "metrics.json"
    if (path / "metrics.json").is_file():
        return path / "metrics.json"
    have = sorted(p.name for p in path.iterdir() if (p / "metrics.json").is_file())
    raise GateError(
        f"--baseline {path} has no baseline for platform {platform or DEFAULT_PLATFORM!r}"
        + (f" (it has {', '.join(have)})" if have else "")
        + "; approve one with `raster-oracle baseline accept RUN_DIR --into "
        f"{path}`"
    )


def _run_record(run_dir: Path) -> tuple[dict, bytes]:
    """The run's ``metrics.json`` (a bounded regular file of strict JSON) and its bytes."""
    path = run_dir / "metrics.json"
    what = "baseline accept: run record"
    data = read_bounded(path, limit=LIMITS["json_bytes"], what=what, error=GateError)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise GateError(f"{what} {path} is not UTF-8 text") from None
    record = loads_json(text, what=f"{what} {path}", error=GateError)
    if not isinstance(record, dict) or record.get("schema") not in (METRICS_SCHEMA, FOLDER_SCHEMA):
        raise GateError(
            f"baseline accept: {path} is not the metrics.json of a score or score-folder run"
        )
    return record, data


def _lstat(path: Path):
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None


def _no_link(path: Path, *, folder: bool) -> bool:
    """Whether ``path`` exists, as a real folder (``folder``) or regular file, never a link;
    :class:`GateError` for a link or the other kind."""
    st = _lstat(path)
    if st is None:
        return False
    if stat.S_ISLNK(st.st_mode):
        raise GateError(f"baseline accept: {path} is a link (never followed out of the folder)")
    want, kind = (stat.S_ISDIR, "a folder") if folder else (stat.S_ISREG, "a regular file")
    if not want(st.st_mode):
        raise GateError(f"baseline accept: {path} exists and is not {kind}")
    return True


@contextlib.contextmanager
def _locked(folder: Path):
    """Hold ``folder/.accept.lock`` exclusively (POSIX); a no-op where locks do not exist."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(folder / ".accept.lock", flags, 0o666)
    except OSError as exc:
        raise GateError(
            f"baseline accept: cannot take the lock {folder / '.accept.lock'} "
            f"({type(exc).__name__}; a link or an odd file there is never followed)"
        ) from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise GateError(f"baseline accept: {folder / '.accept.lock'} is not a regular file")
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _claim_previous(folder: Path) -> Path:
    """Make and return the next free ``previous/NNN`` (numbered after every numbered entry,
    claimed with an atomic ``mkdir``)."""
    previous = folder / "previous"
    if not _no_link(previous, folder=True):
        previous.mkdir()
    taken = [int(p.name) for p in previous.iterdir() if p.name.isdigit()]
    n = max(taken, default=0) + 1
    while True:
        target = previous / f"{n:03d}"
        try:
            target.mkdir()
            return target
        except FileExistsError:
            n += 1


def accept_baseline(run_dir, *, into, note: str, now: datetime | None = None) -> Path:
    """Approve the run in ``run_dir`` (a ``score`` or ``score-folder`` output folder) as the
    baseline of its platform in ``into``; returns the platform folder written.

    The platform's current baseline (if any) is moved to ``previous/NNN/`` with its note;
    the run's ``metrics.json`` is copied and ``baseline.json`` written (``{"schema", "note",
    "accepted_at", "run", "platform", "failed", "previous"}``), both written aside first and
    renamed into place last (see the module docstring). :class:`GateError` for an empty
    note, a folder that is no run, ``into`` inside it, or an odd baseline folder.
    """
    run_dir, into = Path(run_dir), Path(into)
    if not isinstance(note, str) or not note.strip():
        raise GateError("baseline accept: --note must say why this run is approved")
    record, data = _run_record(run_dir)
    if into.resolve() == run_dir.resolve() or run_dir.resolve() in into.resolve().parents:
        raise GateError(f"baseline accept: --into {into} is inside the run folder {run_dir}")
    if into.exists() and not into.is_dir():
        raise GateError(f"baseline accept: --into {into} exists and is not a folder")
    platform = record.get("platform") or DEFAULT_PLATFORM
    folder = into / check_platform(platform)
    into.mkdir(parents=True, exist_ok=True)
    if not _no_link(folder, folder=True):
        with contextlib.suppress(FileExistsError):
            folder.mkdir()
        _no_link(folder, folder=True)
    stamp = (now or datetime.now(UTC)).isoformat(timespec="seconds")
    with _locked(folder):
        return _accept_locked(folder, run_dir, record, data, note, platform, stamp)


def _accept_locked(folder, run_dir, record, data, note, platform, stamp) -> Path:
    current = [n for n in _FILES if _no_link(folder / n, folder=False)]
    target = _claim_previous(folder) if current else None
    incoming = Path(tempfile.mkdtemp(prefix=".incoming-", dir=folder))
    try:
        atomic_write_bytes(incoming / "metrics.json", data)
        atomic_write_json(
            incoming / "baseline.json",
            {
                "schema": BASELINE_SCHEMA,
                "note": note.strip(),
                "accepted_at": stamp,
                "run": str(run_dir.resolve()),
                "platform": platform,
                "failed": record.get("failed"),
                "previous": None if target is None else target.relative_to(folder).as_posix(),
            },
        )
        for name in current if target is not None else ():
            os.replace(folder / name, target / name)
        for name in _FILES:  # metrics.json first: a reader never sees a new note alone
            os.replace(incoming / name, folder / name)
    except BaseException:
        if target is not None and not any(target.iterdir()):
            target.rmdir()
        raise
    finally:
        shutil.rmtree(incoming, ignore_errors=True)
    return folder
