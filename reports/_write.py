"""Render a report record to one self-contained HTML file plus its JSON twin."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from ..scenes.base.files import atomic_write_bytes
from ._build import REPORT_SCHEMA
from ._env import environment
from ._validate import check_report_urls

__all__ = ["render_html", "write_report"]


def _page_data(report: Mapping) -> dict:
    """The record the page's scripts read: geometry, worst tiles and viewer data of each case."""
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
                "viewer": case.get("viewer"),
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
    html = template.render(report=report, page_data=_page_data(report))
    return html.translate(_CONTROLS)  # user text's NUL, escapes, DEL, C1: never on the page


#: Control characters (but tab, newline, carriage return) -> U+FFFD: jinja2 escapes HTML's
#: specials, not these; the replacement is valid in text, attributes and embedded JSON alike.
_CONTROLS = {c: 0xFFFD for c in [*range(0x00, 0x09), 0x0B, 0x0C, *range(0x0E, 0x20)]}
_CONTROLS.update({c: 0xFFFD for c in range(0x7F, 0xA0)})


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
    atomic_write_bytes(path.with_suffix(".json"), (text + "\n").encode("utf-8", "backslashreplace"))
    atomic_write_bytes(path, html.encode("utf-8", "backslashreplace"))
