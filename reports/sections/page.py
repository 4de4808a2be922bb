"""Pages made of section records: a study's own page (``claims.html``, ``extremes.html``,
``converge.html``, ``aa_memory.html``) and the sweep report's page, rendered with the
package's jinja2 templates (autoescaped, self-contained: inline CSS, SVG and script, no network)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from .. import _env
from ._record import SECTION_SCHEMA
from .overview import overview_record
from .sweep import sweep_view

__all__ = [
    "STUDY_PAGE_SCHEMA",
    "render_section",
    "render_study_page",
    "render_sweep_page",
    "study_page",
]

#: Value of the ``"schema"`` key of a study page record.
STUDY_PAGE_SCHEMA = "raster-oracle.study-page/1"


def _check_sections(sections: Sequence[Mapping]) -> None:
    for i, section in enumerate(sections):
        if not isinstance(section, Mapping) or section.get("schema") != SECTION_SCHEMA:
            got = section.get("schema") if isinstance(section, Mapping) else section
            raise ValueError(
                f"sections[{i}] must be a section record ({SECTION_SCHEMA}), got {got!r}"
            )


def study_page(sections: Sequence[Mapping], *, title: str) -> dict:
    """The record of a page of ``sections`` (section records, e.g. from
    :func:`reports.sections.claims_section`): ``{"schema", "title", "sections"}``."""
    sections = list(sections)
    _check_sections(sections)
    return {"schema": STUDY_PAGE_SCHEMA, "title": title, "sections": sections}


def render_section(section: Mapping) -> str:
    """One section record as an HTML fragment (``<section id=...>``)."""
    _check_sections([section])
    return _env.environment().get_template("section.html").render(section=section)


def render_study_page(page: Mapping) -> str:
    """A :func:`study_page` record as one self-contained HTML page."""
    if not isinstance(page, Mapping) or page.get("schema") != STUDY_PAGE_SCHEMA:
        raise ValueError(f"page must be a record from study_page ({STUDY_PAGE_SCHEMA})")
    _check_sections(page["sections"])
    return _env.environment().get_template("study.html").render(page=page)


def render_sweep_page(record: Mapping, *, images: Mapping[str, Mapping] | None = None) -> str:
    """The sweep report's page of ``record`` (:func:`reports.sweep.sweep_record` with its
    ``"sections"``); ``images`` are thumbnails by row key (``data:`` URIs; others are
    dropped), shown for the cases on each group's headline front."""
    _check_sections(record.get("sections", []))
    record = {"sections": [], **record}
    if "overview" not in record:
        record["overview"] = overview_record(record)
    view = sweep_view(record, images=images)
    template = _env.environment().get_template("sweep.html")
    return template.render(record=record, view=view)
