"""Pages made of section records: a study's own page (``claims.html``, ``extremes.html``,
``converge.html``, ``aa_memory.html``) and the sweep report's page, rendered with the
package's jinja2 templates (autoescaped, self-contained: inline CSS, SVG and script, no network)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence

from .. import _env
from ..viewer import MAX_VIEWER_PAGE_BYTES
from ..viewer import viewer_cases as fit_viewer_cases
from . import aa_memory, aa_ranking, claims, converge, extremes, sweep
from ._record import SECTION_SCHEMA
from .overview import overview_record
from .sweep import sweep_view

__all__ = [
    "STUDY_PAGE_SCHEMA",
    "render_section",
    "render_study_page",
    "render_sweep_page",
    "study_page",
    "summary_viewer_cases",
]

#: Value of the ``"schema"`` key of a study page record.
STUDY_PAGE_SCHEMA = "raster-oracle.study-page/1"


@functools.cache
def _environment():
    """The shared filters plus each section's own (built once per process)."""
    return _env.build_environment(
        {
            "front_svg": sweep.front_svg,
            "sensitivity_svg": sweep.sensitivity_svg,
            "params_text": sweep.fmt_params,
            "cost_level": sweep.fmt_cost_level,
            "verdict_class": claims.verdict_class,
            "extra_value": claims.fmt_extra,
            "cell_class": extremes.cell_class,
            "cell_text": extremes.fmt_cell,
            "cell_tip": extremes.fmt_cell_tip,
            "cell_style": extremes.cell_style,
            "cell_mark": extremes.cell_mark,
            "slope": converge.fmt_slope,
            "quoted_value": aa_memory.fmt_quoted,
            "computed_text": aa_memory.fmt_computed,
            "quote_note": aa_memory.fmt_note,
            "with_floor": aa_ranking.fmt_with_floor,
        }
    )


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
    return _environment().get_template("section.html").render(section=section)


def render_study_page(page: Mapping) -> str:
    """A :func:`study_page` record as one self-contained HTML page."""
    if not isinstance(page, Mapping) or page.get("schema") != STUDY_PAGE_SCHEMA:
        raise ValueError(f"page must be a record from study_page ({STUDY_PAGE_SCHEMA})")
    _check_sections(page["sections"])
    return _environment().get_template("study.html").render(page=page)


def summary_viewer_cases(
    record: Mapping,
    viewers: Mapping[str, Mapping] | Callable[[list[str]], Mapping[str, Mapping]],
    *,
    max_bytes: int = MAX_VIEWER_PAGE_BYTES,
) -> list[dict]:
    """The sweep page's pixel viewers: one per case the summary names (per family and scene,
    the best technique at each cost level it lists), in the summary's order, all reduced by
    one further factor until together they hold at most ``max_bytes`` packed characters
    (:func:`reports.viewer.viewer_cases`).

    ``viewers`` maps row keys to pixel viewer records, or is a function of a list of keys
    returning that mapping for those that have one (e.g.
    :meth:`oracle.sweeps.store.SweepStore.viewers`: only the named cases are read). Each
    result is ``{"id", "name", "viewer", "level"}``: ``id`` is the case's row id (the
    viewer's element is ``id + "-inspect"``), ``level`` the summary row (``family``,
    ``scene``, ``metric``, ``cost_key`` and the level's ``cost``, ``error``, ``floor``)."""
    overview = record.get("overview") or overview_record(record)
    cases = {c["id"]: c for c in record["cases"]}
    named: dict[str, tuple] = {}
    for g in overview["groups"]:
        for level in g["levels"]:
            case = cases.get(level["case_id"])
            if case is not None and case["id"] not in named:
                named[case["id"]] = (case, g, level)
    keys = [case["key"] for case, _, _ in named.values()]
    found = viewers(keys) if callable(viewers) else {k: viewers[k] for k in keys if k in viewers}
    picks, levels = [], {}
    for case, g, level in named.values():
        if case["key"] not in found:
            continue
        name = f"{g['family']} on {g['scene']}: {case['name']}"
        picks.append((case["id"], name, found[case["key"]]))
        levels[case["id"]] = {
            "family": g["family"],
            "scene": g["scene"],
            "metric": g["metric"],
            "cost_key": g["cost_key"],
            "cost": level["cost"],
            "error": level["error"],
            "floor": level["floor"],
        }
    out = fit_viewer_cases(picks, max_bytes=max_bytes)
    return [{**case, "level": levels[case["id"]]} for case in out]


def render_sweep_page(
    record: Mapping,
    *,
    images: Mapping[str, Mapping] | None = None,
    viewer_cases: Sequence[Mapping] | None = None,
) -> str:
    """The sweep report's page of ``record`` (:func:`reports.sweep.sweep_record` with its
    ``"sections"``); ``images`` are thumbnails by row key (``data:`` URIs; others are
    dropped), shown for the cases on each group's headline front; ``viewer_cases`` are the
    pixel viewers (:func:`summary_viewer_cases`), linked from the summary's rows."""
    _check_sections(record.get("sections", []))
    record = {"sections": [], **record}
    if "overview" not in record:
        record["overview"] = overview_record(record)
    view = sweep_view(record, images=images)
    template = _environment().get_template("sweep.html")
    cases = list(viewer_cases or [])
    return template.render(
        record=record,
        view=view,
        viewer_cases=cases,
        inspect_ids={c["id"] for c in cases},
        viewer_budget=MAX_VIEWER_PAGE_BYTES,
    )
