"""Render a report record to one self-contained HTML file plus its JSON twin."""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Mapping
from pathlib import Path

from ._build import REPORT_SCHEMA
from ._env import environment
from ._validate import check_report_urls

__all__ = ["atomic_write_text", "render_html", "write_report"]


def _page_data(report: Mapping) -> dict:
    """The small record the page's script reads: geometry and worst tiles of each case."""
    return {
        "cases": [
            {
                "id": case["id"],
                "name": case["name"],
                "width": case["width"],
                "height": case["height"],
                "tiles": [
                    {k: tile[k] for k in ("rank", "x", "y", "w", "h", "mean_abs_error")}
                    for tile in case["worst_tiles"]["tiles"]
                ],
            }
            for case in report["cases"]
        ]
    }


def render_html(report: Mapping) -> str:
    """Render ``report`` (from :func:`build_report`) with ``templates/report.html``."""
    if not isinstance(report, Mapping) or report.get("schema") != REPORT_SCHEMA:
        got = report.get("schema") if isinstance(report, Mapping) else type(report).__name__
        raise ValueError(
            f"report must be a record from build_report ({REPORT_SCHEMA}), got {got!r}"
        )
    check_report_urls(report)  # only data: images and relative links reach the page
    template = environment().get_template("report.html")
    return template.render(report=report, page_data=_page_data(report))


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8, LF) to ``path`` through a temporary file and ``os.replace``."""
    # open(..., "x") on a random name rather than tempfile.mkstemp: mkstemp creates the file
    # with mode 0600, and the page should get the usual umask-derived permissions.
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(8)}.tmp")
    try:
        with open(tmp, "x", encoding="utf-8", newline="\n") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_report(report: Mapping, path: str | os.PathLike) -> None:
    """Write ``report`` as self-contained HTML at ``path`` and as JSON beside it.

    Both files are written atomically (temporary file in the same folder, then
    ``os.replace``). The JSON file is ``path.with_suffix(".json")`` and holds exactly
    ``report``; the HTML embeds every image, style and script, so it works from ``file://``
    with no network.

    Parameters
    ----------
    report : dict
        A record from :func:`build_report`.
    path : path-like
        The HTML file to write (``report.html``); its folder is created if missing.
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        raise ValueError(f"path must name the HTML file (its JSON goes beside it), got {path}")
    html = render_html(report)
    text = json.dumps(report, ensure_ascii=False, allow_nan=False, indent=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path.with_suffix(".json"), text + "\n")
    atomic_write_text(path, html)
