"""Assemble case records into one report record; read cases back from a report's JSON."""

from __future__ import annotations

import copy
import json
import os
import posixpath
import urllib.parse
from collections.abc import Mapping, Sequence
from pathlib import Path

from . import images as _images
from ._case import CASE_SCHEMA
from ._tradeoff import tradeoff_section
from ._validate import check_case_record, check_name, to_jsonable
from .viewer import MAX_VIEWER_PAGE_BYTES, check_viewer, fit_viewers

__all__ = ["REPORT_SCHEMA", "build_report", "read_cases"]

#: Value of the ``"schema"`` key of every report record.
REPORT_SCHEMA = "raster-oracle.report/1"


def _check_case(index: int, case: object) -> dict:
    if not isinstance(case, Mapping) or case.get("schema") != CASE_SCHEMA:
        got = case.get("schema") if isinstance(case, Mapping) else type(case).__name__
        raise ValueError(
            f"cases[{index}] must be a record from make_case ({CASE_SCHEMA}), got {got!r}"
        )
    return copy.deepcopy(dict(case))


def _common(cases: Sequence[dict], field: str, names: Sequence[str]) -> dict:
    """Per metric: the one value every case that sets it agrees on, or ``"varies"``."""
    out = {}
    for name in names:
        values = [case[field][name] for case in cases if name in case[field]]
        if values:
            same = all(v == values[0] for v in values[1:])
            out[name] = values[0] if same else "varies"
    return out


def _errors(errors) -> list[dict]:
    out = []
    for i, e in enumerate(errors or []):
        if not isinstance(e, Mapping):
            raise TypeError(f"errors[{i}] must be a dict, got {type(e).__name__}")
        for key in ("case", "name", "message"):
            if not isinstance(e.get(key), str):
                raise TypeError(f"errors[{i}][{key!r}] must be a string, got {e.get(key)!r}")
        out.append({key: e[key] for key in ("case", "name", "message")})
    return out


def build_report(
    cases: Sequence[Mapping],
    *,
    title: str,
    provenance: Mapping[str, object],
    tradeoff_cost: str | None = None,
    tradeoff_metric: str | None = None,
    errors: Sequence[Mapping] | None = None,
) -> dict:
    """Combine case records from :func:`make_case` into one JSON-safe report record.

    Parameters
    ----------
    cases : sequence of dict
        Records from :func:`make_case`, possibly read back from JSON (:func:`read_cases`).
        They are copied; each gets an ``"id"`` (``"case-1"``, ...) by position. Their pixel
        viewers share one page budget (:data:`reports.viewer.MAX_VIEWER_PAGE_BYTES`): over it,
        every viewer is reduced by one further integer factor until they fit.
    title : str
        Page title.
    provenance : dict
        How the results were made: scene, light, resolution, spp, seed, filter, ppd,
        exposure, tone mapper, backend, package versions, times. Nested dicts are shown
        with dotted keys.
    tradeoff_cost : str, optional
        Cost key on the x axis of the cost-versus-error plots. Default: the first of
        ``memory_bytes``, ``texels_rendered``, ``texture_lookups_per_pixel`` that a case
        carries, else the first cost key seen.
    tradeoff_metric : str, optional
        Metric on the y axis (lower is better). Default: the first metric seen in a case
        that carries a cost.
    errors : list of dict, optional
        ``{"case", "name", "message"}`` of each case that could not be scored (a manifest's
        layer missing from its file): listed first, with the failed checks.

    Returns
    -------
    dict
        The report record; its keys are documented in the :mod:`reports` module docstring.
    """
    check_name("title", title)
    if not isinstance(provenance, Mapping):
        raise TypeError(f"provenance must be a dict, got {type(provenance).__name__}")
    if isinstance(cases, Mapping | str) or not isinstance(cases, Sequence):
        raise TypeError(f"cases must be a list of case records, got {type(cases).__name__}")
    records = [_check_case(i, case) for i, case in enumerate(cases)]
    for i, case in enumerate(records):
        case["id"] = f"case-{i + 1}"
    # the viewers' float data of all cases share one page budget
    fitted = fit_viewers([case.get("viewer") for case in records], max_bytes=MAX_VIEWER_PAGE_BYTES)
    for case, viewer in zip(records, fitted, strict=True):
        if "viewer" in case or viewer is not None:
            case["viewer"] = viewer
    metric_names = list(dict.fromkeys(k for case in records for k in case["metrics"]))
    # gated and failed metrics first: the columns a CI reader looks for never scroll off
    gated = {k for case in records for k in case["thresholds"]}
    gated |= {c["metric"] for case in records for c in case.get("checks", []) if not c["passed"]}
    metric_names = [m for m in metric_names if m in gated] + [
        m for m in metric_names if m not in gated
    ]
    cost_names = list(dict.fromkeys(k for case in records for k in (case["cost"] or {})))
    styles = sorted({m["style"] for case in records for m in case["error_maps"]})
    # a multi-frame case's frames are shown as cases of their own, but counted as its parts
    statuses = [case["status"] for case in records if case.get("frame") is None]
    return {
        "schema": REPORT_SCHEMA,
        "title": title,
        "provenance": to_jsonable(dict(provenance), "provenance"),
        "metric_names": metric_names,
        # which way each metric is better (the first case that says so; default lower)
        "directions": {
            m: next((c["directions"][m] for c in records if m in c.get("directions", {})), "lower")
            for m in metric_names
        },
        "cost_names": cost_names,
        "summary": {
            "n_cases": len(statuses),
            "n_frames": sum(case.get("frame") is not None for case in records),
            "n_pass": statuses.count("pass"),
            "n_fail": statuses.count("fail"),
            "n_unchecked": statuses.count("unchecked"),
            "thresholds": _common(records, "thresholds", metric_names),
            "noise_floor": _common(records, "noise_floor", metric_names),
            # every failed gate and regression of every case: the page's first screen
            "failed_checks": [
                {"case_id": case["id"], "case": case["name"], "scene": case["scene"], **c}
                for case in records
                for c in case.get("checks", [])
                if not c["passed"]
            ],
            # the verdict table: each failed gate, and a case's regressions as one row
            "failed_rows": _failed_rows(records),
            # the first screen's "Where" crops: failing cases, the worst tile first
            "where_cases": _where_order(records),
            "n_checks": sum(len(case.get("checks", [])) for case in records),
            "errors": _errors(errors),
            "diagnoses": [
                {"case_id": case["id"], "case": case["name"], "message": d}
                for case in records
                for d in case.get("diagnoses", [])
            ],
        },
        "tradeoff": tradeoff_section(records, cost_key=tradeoff_cost, metric=tradeoff_metric),
        "colorbars": {style: _images.colorbar_uri(style) for style in styles},
        "cases": records,
    }


def _where_order(records) -> list[int]:
    """Indices of the failing cases with worst tiles, most severe first: by the mean |error|
    of each case's worst tile, descending (ties keep the cases' order)."""
    idx = [
        i
        for i, case in enumerate(records)
        if case.get("status") == "fail" and case.get("worst_tiles", {}).get("tiles")
    ]

    def severity(i: int) -> float:
        value = records[i]["worst_tiles"]["tiles"][0].get("mean_abs_error")
        return float(value) if isinstance(value, int | float) else 0.0

    return sorted(idx, key=lambda i: -severity(i))


def _failed_rows(records) -> list[dict]:
    """The verdict table's rows: every failed gate, then per case its regressions grouped in
    one row (their count and metrics; a single one as it is), so one intended change is one
    row, not one a metric."""
    rows = []
    for case in records:
        failed = [c for c in case.get("checks", []) if not c["passed"]]
        where = {"case_id": case["id"], "case": case["name"], "scene": case["scene"]}
        regressions = [c for c in failed if c["kind"] == "baseline"]
        alone = len(regressions) < 2  # one regression keeps its own row (values, floors)
        rows += [{**where, **c} for c in failed if c["kind"] != "baseline" or alone]
        if not alone:
            names = ", ".join(c["metric"] for c in regressions[:6])
            more = f" and {len(regressions) - 6} more" if len(regressions) > 6 else ""
            rows.append(
                {
                    **where,
                    "name": f"{len(regressions)} regression(s): {names}{more}",
                    "summary": f"{len(regressions)} metrics past their baselines' noise "
                    "floors (each listed in the case)",
                    "kind": "baseline",
                    "metric": None,
                    "count": len(regressions),
                    "value": None,
                    "limit": None,
                    "previous": None,
                    "noise_floor": None,
                    "previous_noise_floor": None,
                }
            )
    return rows


def read_cases(path: str | os.PathLike, *, relative_to: str | os.PathLike) -> list[dict]:
    """Read the case records of a report JSON written by :func:`write_report`.

    Relative EXR links are rewritten so they stay valid from the folder ``relative_to``
    (where the combined report will be written).

    Parameters
    ----------
    path : path-like
        A ``report.json`` written by :func:`write_report`.
    relative_to : path-like
        Folder of the report the cases will be shown in.
    """
    path = Path(path)
    report = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(report, dict) or report.get("schema") != REPORT_SCHEMA:
        raise ValueError(f"{path} is not a report JSON ({REPORT_SCHEMA})")
    if not isinstance(report.get("cases"), list):
        raise ValueError(f"{path}: 'cases' must be a list of case records")
    source = path.parent.resolve()
    target = Path(relative_to).resolve()
    cases = []
    for i, case in enumerate(report["cases"]):
        # Untrusted data: every key, every image URI and link (inside the folder) is checked.
        case = check_case_record(f"{path} cases[{i}]", case, schema=CASE_SCHEMA)
        case.pop("id", None)
        case["viewer"] = check_viewer(f"{path} cases[{i}]['viewer']", case.get("viewer"))
        links = []
        for link in case["exr_links"]:
            link = dict(link)
            if not posixpath.isabs(link["path"]):
                moved = Path(os.path.relpath(source / link["path"], target)).as_posix()
                link["path"] = moved
                link["href"] = urllib.parse.quote(moved, safe="/")
            links.append(link)
        case["exr_links"] = links
        cases.append(case)
    return cases
