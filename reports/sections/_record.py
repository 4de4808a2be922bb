"""The common frame of a section record: what every section (claims, extremes, converge,
anti-aliasing memory) carries besides its own view of the data."""

from __future__ import annotations

import json
from collections.abc import Mapping

__all__ = ["SECTION_KINDS", "SECTION_SCHEMA", "failed_section", "section_record"]

#: Value of the ``"schema"`` key of every section record.
SECTION_SCHEMA = "raster-oracle.report-section/1"
#: Section kinds; each has a template ``section_<kind>.html``.
SECTION_KINDS = (
    "claims",
    "extremes",
    "converge",
    "aa_memory",
    "aa_ranking",
    "soft_shadows",
    "alpha_foliage",
)


def _check_frame(kind: str, section_id: str, title: str) -> None:
    if kind not in SECTION_KINDS:
        raise ValueError(f"kind must be one of {list(SECTION_KINDS)}, got {kind!r}")
    for name, value in (("section_id", section_id), ("title", title)):
        if not isinstance(value, str) or not value:
            raise ValueError(f"{name} must be a non-empty string, got {value!r}")


def section_record(kind: str, *, section_id: str, title: str, data: Mapping, **view) -> dict:
    """A JSON-safe section record: ``{"schema", "kind", "id", "title", "failed": False,
    "error": None, "data": data, **view}``.

    ``data`` (the study's own JSON record) and ``view`` (what the section derives from it for
    its template) are copied through JSON, so the record holds plain JSON values only (no
    NaN, no NumPy scalars: a value that is not JSON raises ``TypeError``/``ValueError``).
    """
    _check_frame(kind, section_id, title)
    if not isinstance(data, Mapping):
        raise TypeError(f"data of the {kind} section must be a dict, got {type(data).__name__}")
    body = json.loads(json.dumps({"data": data, **view}, allow_nan=False))
    return {
        "schema": SECTION_SCHEMA,
        "kind": kind,
        "id": section_id,
        "title": title,
        "failed": False,
        "error": None,
        **body,
    }


def failed_section(*, kind: str, section_id: str, title: str, error: str) -> dict:
    """The record of a section whose study failed with the one-line message ``error``: the
    page says so in its place."""
    _check_frame(kind, section_id, title)
    return {
        "schema": SECTION_SCHEMA,
        "kind": kind,
        "id": section_id,
        "title": title,
        "failed": True,
        "error": " ".join(str(error).split()),
        "data": None,
    }
