"""Render a report record to one self-contained HTML file plus its JSON twin."""

from __future__ import annotations

import functools
import json
import os
import secrets
from collections.abc import Mapping
from pathlib import Path

import jinja2
from markupsafe import Markup

from . import _format, _svg
from ._build import REPORT_SCHEMA
from ._validate import check_report_urls

__all__ = ["json_script", "render_html", "write_report"]

# JSON inside <script type="application/json">: "</script>", "<!--" and HTML entities must
# not appear literally, and U+2028/U+2029 break older JS parsers.
_JSON_SCRIPT_ESCAPES = {
    ord("<"): "\\u003c",
    ord(">"): "\\u003e",
    ord("&"): "\\u0026",
    ord("'"): "\\u0027",
    0x2028: "\\u2028",
    0x2029: "\\u2029",
}


def json_script(value: object) -> Markup:
    """Serialise ``value`` as JSON safe to place verbatim inside a ``<script>`` element."""
    text = json.dumps(value, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    return Markup(text.translate(_JSON_SCRIPT_ESCAPES))


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


@functools.cache
def _environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("reports"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(
        num=_format.fmt_number,
        cost=_format.fmt_cost,
        threshold=_format.fmt_threshold,
        value=_format.fmt_value,
        sortkey=_format.sort_key,
        flatten=_format.flatten,
        json_script=json_script,
        histogram_svg=lambda hist, style, name: _svg.histogram_svg(hist, style=style, name=name),
        scatter_svg=lambda fam, cost_key, metric: _svg.scatter_svg(
            fam, cost_key=cost_key, metric=metric
        ),
    )
    return env


def render_html(report: Mapping) -> str:
    """Render ``report`` (from :func:`build_report`) with ``templates/report.html``."""
    if not isinstance(report, Mapping) or report.get("schema") != REPORT_SCHEMA:
        got = report.get("schema") if isinstance(report, Mapping) else type(report).__name__
        raise ValueError(
            f"report must be a record from build_report ({REPORT_SCHEMA}), got {got!r}"
        )
    check_report_urls(report)  # only data: images and relative links reach the page
    template = _environment().get_template("report.html")
    return template.render(report=report, page_data=_page_data(report))


def _atomic_write_text(path: Path, text: str) -> None:
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
    _atomic_write_text(path.with_suffix(".json"), text + "\n")
    _atomic_write_text(path, html)
