"""Approved baselines: ``raster-oracle baseline accept RUN_DIR --into BASELINE_DIR``.

A baseline folder holds one approved run per platform (``--platform NAME`` of the run;
``default`` without one): ``BASELINE_DIR/<platform>/metrics.json`` (the run's record, a
``score`` or a ``score-folder`` one) and ``baseline.json`` (who approved what: the note, the
time, the run folder, the run's failed checks). Accepting a new run moves the platform's
current files to ``previous/NNN/`` first (numbered from 001), so every approval and its note
is kept: the human step every golden-image tool has.

``--baseline BASELINE_DIR`` (with the run's ``--platform``) finds the platform's
``metrics.json`` (:func:`resolve_baseline`).
"""

from __future__ import annotations

import json
import shutil
from datetime import UTC, datetime
from pathlib import Path

from ...scenes.base.files import atomic_copy, atomic_write_json
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


def _run_record(run_dir: Path) -> dict:
    path = run_dir / "metrics.json"
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise GateError(f"baseline accept: cannot read {path} ({type(exc).__name__})") from None
    if not isinstance(record, dict) or record.get("schema") not in (METRICS_SCHEMA, FOLDER_SCHEMA):
        raise GateError(
            f"baseline accept: {path} is not the metrics.json of a score or score-folder run"
        )
    return record


def _next_previous(folder: Path) -> Path:
    previous = folder / "previous"
    taken = [int(p.name) for p in previous.glob("[0-9][0-9][0-9]") if p.is_dir()]
    return previous / f"{max(taken, default=0) + 1:03d}"


def accept_baseline(run_dir, *, into, note: str, now: datetime | None = None) -> Path:
    """Approve the run in ``run_dir`` (a ``score`` or ``score-folder`` output folder) as the
    baseline of its platform in ``into``; returns the platform folder written.

    The platform's current baseline (if any) is moved to ``previous/NNN/`` with its note
    first; then the run's ``metrics.json`` is copied and ``baseline.json`` written
    (``{"schema", "note", "accepted_at", "run", "platform", "failed", "previous"}``).
    :class:`GateError` for an empty note, a folder that is no run, or ``into`` inside it.
    """
    run_dir, into = Path(run_dir), Path(into)
    if not isinstance(note, str) or not note.strip():
        raise GateError("baseline accept: --note must say why this run is approved")
    record = _run_record(run_dir)
    if into.resolve() == run_dir.resolve() or run_dir.resolve() in into.resolve().parents:
        raise GateError(f"baseline accept: --into {into} is inside the run folder {run_dir}")
    if into.exists() and not into.is_dir():
        raise GateError(f"baseline accept: --into {into} exists and is not a folder")
    platform = record.get("platform") or DEFAULT_PLATFORM
    folder = into / check_platform(platform)
    folder.mkdir(parents=True, exist_ok=True)
    previous = None
    if (folder / "metrics.json").is_file():
        target = _next_previous(folder)
        target.mkdir(parents=True)
        for name in _FILES:
            if (folder / name).is_file():
                shutil.move(folder / name, target / name)
        previous = target.relative_to(folder).as_posix()
    atomic_copy(run_dir / "metrics.json", folder / "metrics.json")
    failed = record.get("failed")
    stamp = (now or datetime.now(UTC)).isoformat(timespec="seconds")
    atomic_write_json(
        folder / "baseline.json",
        {
            "schema": BASELINE_SCHEMA,
            "note": note.strip(),
            "accepted_at": stamp,
            "run": str(run_dir.resolve()),
            "platform": platform,
            "failed": failed,
            "previous": previous,
        },
    )
    return folder
