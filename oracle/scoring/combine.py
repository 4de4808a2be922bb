"""Combine the cases of several score folders into one report (``raster-oracle report DIR...``)."""

from __future__ import annotations

import json
from pathlib import Path

from ... import reports
from .result import ScoreError

__all__ = ["combine_reports"]

#: Provenance entries shown once for the combined report ("varies" when folders differ).
SHARED_PROVENANCE = (
    "backend",
    "reference spp",
    "seed",
    "filter",
    "ppd",
    "tone mapper",
    "versions",
)


def combine_reports(folders: list[Path], out: Path, *, title: str, errors=None) -> int:
    """Combine the cases of several score folders into the report ``out`` (HTML, with its
    JSON beside it); returns the case count. ``errors``: ``[{"case", "name", "message"}]``
    of cases that could not be scored (listed first on the page).

    Raises
    ------
    ScoreError
        ``out`` is a folder, a folder is not a score folder or its ``report.json`` is not JSON.
    """
    from ...scenes.base.untrusted import read_json

    out = Path(out)
    if out.exists() and out.is_dir():
        raise ScoreError(f"--out {out} is a folder; give the report file to write")
    cases, scenes, provs = [], [], []
    for folder in folders:
        js = Path(folder) / "report.json"
        if not js.is_file():
            raise ScoreError(f"{folder} is not a score folder (no report.json)")
        data = read_json(js, what="score folder report", error=ScoreError)
        cases.extend(reports.read_cases(js, relative_to=out.parent.resolve()))
        provs.append(data.get("provenance", {}))
        scenes.append(str(data.get("provenance", {}).get("scene", "?")))
    provenance = {"folders": [str(f) for f in folders], "scenes": sorted(set(scenes))}
    for key in SHARED_PROVENANCE:
        values = {json.dumps(p.get(key), sort_keys=True) for p in provs}
        provenance[key] = provs[0].get(key) if len(values) == 1 else "varies"
    report = reports.build_report(cases, title=title, provenance=provenance, errors=errors)
    out.parent.mkdir(parents=True, exist_ok=True)
    reports.write_report(report, out)
    return len(cases)
