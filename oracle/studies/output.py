"""A study's files: its JSON record and its HTML page, side by side, written atomically."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from ...reports.sections import render_study_page, study_page
from ...scenes.base.files import atomic_write_bytes

__all__ = ["write_study"]


def write_study(
    out: str | os.PathLike, *, name: str, data: Mapping, section: Mapping, title: str
) -> tuple[Path, Path]:
    """Write ``out/NAME.json`` (``data``, the study's record) and ``out/NAME.html`` (the page
    of ``section``, the section record built from ``data``).

    The page is rendered before anything is written; each file goes through a temporary
    file and an atomic rename, so a reader never sees half a file. ``out`` is created if
    missing.

    Parameters
    ----------
    out : path-like
        Output folder.
    name : str
        File stem: ``claims``, ``extremes``, ``converge``, ``aa_memory``.
    data : dict
        The study's JSON record (no NaN or infinity: the JSON stays standard).
    section : dict
        Its section record (:mod:`reports.sections`), shown on the page.
    title : str
        The page title.

    Returns
    -------
    (Path, Path)
        The JSON and the HTML file.
    """
    html = render_study_page(study_page([section], title=title))
    text = json.dumps(data, indent=2, allow_nan=False)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    json_path, html_path = out / f"{name}.json", out / f"{name}.html"
    atomic_write_bytes(json_path, text.encode("utf-8"))
    atomic_write_bytes(html_path, html.encode("utf-8"))
    return json_path, html_path
