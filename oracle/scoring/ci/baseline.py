"""Approved baselines: ``raster-oracle baseline accept RUN_DIR --into BASELINE_DIR``.

A baseline folder holds one approved run per platform (``--platform NAME`` of the run;
``default`` without one): ``BASELINE_DIR/<platform>/metrics.json`` (the run's record, a
``score`` or a ``score-folder`` one) and ``baseline.json`` (who approved what: the note, the
time, the run folder, the run's failed checks). Accepting a new run moves the platform's
current files to ``previous/NNN/`` first (numbered from 001), so every approval and its note
is kept: the human step every golden-image tool has.

``--baseline BASELINE_DIR`` (with the run's ``--platform``) finds the platform's
``metrics.json`` (:func:`resolve_baseline`).

Nothing is lost and no link is followed out (:mod:`.baseline_files`): concurrent accepts
take turns, the new files are written aside and renamed last.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

from ....scenes.base.records import jsonable
from .baseline_files import install, platform_folder, read_run_record
from .checks import FOLDER_SCHEMA, METRICS_SCHEMA, GateError

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
    path = run_dir / "metrics.json"
    record, data = read_run_record(path)
    if not isinstance(record, dict) or record.get("schema") not in (METRICS_SCHEMA, FOLDER_SCHEMA):
        raise GateError(
            f"baseline accept: {path} is not the metrics.json of a score or score-folder run"
        )
    return record, data


def accept_baseline(run_dir, *, into, note: str, now: datetime | None = None) -> Path:
    """Approve the run in ``run_dir`` (a ``score`` or ``score-folder`` output folder) as the
    baseline of its platform in ``into``; returns the platform folder written.

    The platform's current baseline (if any) is moved to ``previous/NNN/`` with its note
    first; then the run's ``metrics.json`` is copied and ``baseline.json`` written
    (``{"schema", "note", "accepted_at", "run", "platform", "failed", "previous"}``), both
    written aside and renamed into place last (:func:`.baseline_files.install`).
    :class:`GateError` for an empty note, a folder that is no run, ``into`` inside it, or
    an odd baseline folder (a link, a file where a folder belongs).
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
    folder = platform_folder(into, check_platform(platform))
    failed = record.get("failed")
    stamp = (now or datetime.now(UTC)).isoformat(timespec="seconds")

    def files(previous: str | None) -> dict:
        note_record = {
            "schema": BASELINE_SCHEMA,
            "note": note.strip(),
            "accepted_at": stamp,
            "run": str(run_dir.resolve()),
            "platform": platform,
            "failed": failed,
            "previous": previous,
        }
        text = json.dumps(jsonable(note_record), indent=2, allow_nan=False)
        return {"metrics.json": data, "baseline.json": text.encode()}

    install(folder, _FILES, files)
    return folder
