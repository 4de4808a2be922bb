"""The sweep report: Pareto fronts, parameter sensitivity and best-at-equal-cost tables of the
rows of a sweep store.

Data in, file out: the rows are plain records (``oracle.sweeps.store.SweepStore.rows``:
``key``, ``scene``, ``technique``, ``family``, ``params``, ``frame``, ``path``, ``metrics``,
``cost``, ``status``, ``error``, ``wall_seconds``, ...); :func:`sweep_record` reduces them to
one JSON-serialisable record and :func:`write_sweep_report` writes it, with the section
records of the studies (:mod:`reports.sections`), as one self-contained HTML file
(``templates/sweep.html``) and its JSON twin (``report.json`` beside ``report.html``).

Cases are grouped by technique family and scene: techniques of one family answer the same
question (a shadow test, an anti-aliased image), so their fronts are comparable, while error
levels of different scenes are not.

References
----------
Deb, K. (2001). *Multi-Objective Optimization Using Evolutionary Algorithms*, Wiley, ch. 2
(dominance and the non-dominated set). ISBN 978-0-471-87339-6.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from ..scenes.base.files import atomic_write_bytes
from ._tradeoff import pareto_front
from .sections.overview import overview_record
from .sections.page import render_sweep_page, summary_viewer_cases

__all__ = [
    "MEMORY_ALIASES",
    "SWEEP_REPORT_SCHEMA",
    "best_at_equal_cost",
    "sweep_record",
    "undefined_metrics",
    "with_memory",
    "write_sweep_report",
]

SWEEP_REPORT_SCHEMA = "raster-oracle.sweeps.run-report/1"
# Metrics and cost keys plotted per family when none is requested come from the caller's
# ``families`` (``{family: {"metrics": [...], "costs": [...]}}``: the technique registry's
# family records, which the oracle passes); reports never import the models.
#: Cost keys that stand for ``memory_bytes`` where a technique does not report it: shadow
#: maps report their maps' bytes, IZB its lists' ``memory_bytes``, so that every shadow
#: technique lands on one memory axis.
MEMORY_ALIASES = ("shadow_map_bytes",)
#: Fallback metrics for a family without defaults (first present wins).
FALLBACK_METRICS = ("misclassified_fraction", "flip_mean", "visibility_mae")
#: Most distinct cost values listed one per row in a best-at-equal-cost table; above it the
#: costs are binned by powers of two.
MAX_COST_ROWS = 12


def _number(v) -> float | None:
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _varying(rows: Sequence[Mapping]) -> list[str]:
    """Parameter names whose value differs between ``rows``."""
    names: dict[str, set] = {}
    for r in rows:
        for k, v in (r.get("params") or {}).items():
            names.setdefault(k, set()).add(json.dumps(v, sort_keys=True))
    return [k for k, vals in names.items() if len(vals) > 1]


def _label(row: Mapping, varying: Sequence[str]) -> str:
    params = row.get("params") or {}
    bits = [f"{k}={_short(params[k])}" for k in varying if k in params]
    where = f" {row['path']}#{row['frame']}" if row.get("path") else ""
    return " ".join([row["technique"], *bits]) + where


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list):
        return ",".join(_short(x) for x in v)
    return str(v)


def _case_id(row: Mapping) -> str:
    """The HTML id of a row of the cases table (plots and tables link to it)."""
    return f"case-{row['key'][:12]}"


def _pick(requested: Sequence[str] | None, defaults: Sequence[str], present: Sequence[str]):
    if requested:
        return [k for k in requested if k in present]
    chosen = [k for k in defaults if k in present]
    return chosen or list(present[:1])


def best_at_equal_cost(points: Sequence[Mapping]) -> list[dict]:
    """Best (lowest-error) case of each technique at each cost level.

    Parameters
    ----------
    points : ``{"cost", "error", "technique", "case_id", "name"}`` records.

    Returns
    -------
    list of dict
        ``{"cost_lo", "cost_hi", "best": {technique: point}}`` by increasing cost: one row
        per distinct cost when there are at most :data:`MAX_COST_ROWS`, else power-of-two
        bins ``[2^k, 2^(k+1))``.
    """
    costs = sorted({float(p["cost"]) for p in points})
    if len(costs) <= MAX_COST_ROWS:
        edges = [(c, c) for c in costs]
    else:
        lo = math.floor(math.log2(max(costs[0], 1e-300)))
        hi = math.floor(math.log2(max(costs[-1], 1e-300)))
        edges = [(2.0**k, 2.0 ** (k + 1)) for k in range(lo, hi + 1)]
    out = []
    for a, b in edges:
        inside = [
            p for p in points if (float(p["cost"]) == a if a == b else a <= float(p["cost"]) < b)
        ]
        if not inside:
            continue
        best: dict[str, dict] = {}
        for p in sorted(inside, key=lambda p: (p.get("rank", p["error"]), p["cost"], p["case_id"])):
            best.setdefault(p["technique"], p)
        out.append({"cost_lo": a, "cost_hi": b, "best": best})
    return out


def with_memory(cost: Mapping | None) -> dict:
    """``cost`` with ``memory_bytes`` filled in from :data:`MEMORY_ALIASES` when absent."""
    out = dict(cost or {})
    if "memory_bytes" not in out:
        for key in MEMORY_ALIASES:
            if _number(out.get(key)) is not None:
                out["memory_bytes"] = out[key]
                break
    return out


def _done_rows(rows: Sequence[Mapping]) -> list[dict]:
    """The finished rows with metrics, their cost with ``memory_bytes`` filled in."""
    return [
        {**r, "cost": with_memory(r.get("cost"))}
        for r in rows
        if r["status"] == "done" and r.get("metrics")
    ]


def _numeric_keys(records: Sequence[Mapping | None]) -> list[str]:
    """Keys with a finite number in some record, first seen first."""
    keys = (k for rec in records for k, v in (rec or {}).items() if _number(v) is not None)
    return list(dict.fromkeys(keys))


def _front(
    label: str, done: Sequence[Mapping], varying: Mapping, cost_key: str, metric: str, rank=None
) -> dict | None:
    """The Pareto front of ``metric`` against ``cost_key`` over ``done`` (None: no point).

    ``rank(metric, value)``: the value as an error, 0 best (``metrics.catalog.error_of``: ``1 -
    ssim``, a PSNR's MSE); points are compared on it (``"rank"``, the floor's ``"floor_rank"``)
    and shown with their own values. None: lower values are better."""
    points = []
    for r in done:
        c = _number((r.get("cost") or {}).get(cost_key))
        e = _number(r["metrics"].get(metric))
        if c is None or e is None:
            continue
        vary = varying[r["technique"]]
        points.append(
            {
                "case_id": _case_id(r),
                "key": r["key"],
                "name": _label(r, vary),
                "technique": r["technique"],
                "params": {k: r["params"][k] for k in vary if k in r["params"]},
                "cost": c,
                "error": e,
                "floor": _number((r["metrics"].get("noise_floor") or {}).get(metric)),
            }
        )
    for p in points:
        p["rank"] = rank(metric, p["error"]) if rank else p["error"]
        floor = p["floor"]
        p["floor_rank"] = rank(metric, floor) if rank and floor is not None else floor
    if not points:
        return None
    mask = pareto_front([p["cost"] for p in points], [p["rank"] for p in points])
    for p, on in zip(points, mask, strict=True):
        p["on_front"] = bool(on)
    front = sorted(np.flatnonzero(mask).tolist(), key=lambda i: (points[i]["cost"], i))
    return {
        "family": label,
        "cost_key": cost_key,
        "metric": metric,
        "points": points,
        "front": front,
        "best_at_equal_cost": best_at_equal_cost(points),
    }


def _levels(xs: list, ys: list[float], *, numeric: bool) -> list[dict]:
    """Mean, min, max and count of ``ys`` at each distinct value of ``xs``."""
    keys = [x if numeric else json.dumps(x) for x in xs]
    levels = sorted(set(keys)) if numeric else list(dict.fromkeys(keys))
    out = []
    for level in levels:
        sel = [y for k, y in zip(keys, ys, strict=True) if k == level]
        out.append(
            {
                "x": level if numeric else json.loads(level),
                "mean": float(np.mean(sel)),
                "min": float(np.min(sel)),
                "max": float(np.max(sel)),
                "n": len(sel),
            }
        )
    return out


def _sensitivity(
    scene: str, by_tech: Mapping[str, list], varying: Mapping, headline: str | None
) -> list[dict]:
    """The headline metric against each parameter a technique varies."""
    items = []
    for tech, rs in by_tech.items():
        for name in varying[tech]:
            xs, ys, ids = [], [], []
            for r in rs:
                e = _number(r["metrics"].get(headline)) if headline else None
                if e is None or name not in r["params"]:
                    continue
                xs.append(r["params"][name])
                ys.append(e)
                ids.append(_case_id(r))
            if len(set(json.dumps(x) for x in xs)) < 2:
                continue
            numeric = all(_number(x) is not None for x in xs)
            items.append(
                {
                    "technique": tech,
                    "scene": scene,
                    "param": name,
                    "metric": headline,
                    "numeric": numeric,
                    "points": [
                        {"x": x, "y": y, "case_id": i} for x, y, i in zip(xs, ys, ids, strict=True)
                    ],
                    "levels": _levels(xs, ys, numeric=numeric),
                }
            )
    return items


def _gallery(fronts: Sequence[Mapping]) -> list[dict]:
    """The cases on the headline front (the first), by increasing cost."""
    if not fronts:
        return []
    head = fronts[0]
    return [
        {
            "case_id": p["case_id"],
            "key": p["key"],
            "name": p["name"],
            "cost_key": head["cost_key"],
            "cost": p["cost"],
            "metric": head["metric"],
            "error": p["error"],
        }
        for p in (head["points"][i] for i in head["front"])
    ]


def undefined_metrics(done: Sequence[Mapping], names: Sequence[str]) -> list[dict]:
    """Metrics of ``names`` that say nothing on these cases, with why: no finite value, or 0
    for every case (a coverage metric on a scene covered everywhere, a shadow metric on a
    scene without a shadow). Plotting them would draw an empty plot."""
    out = []
    for name in names:
        values = [_number((r.get("metrics") or {}).get(name)) for r in done]
        values = [v for v in values if v is not None]
        if not values:
            out.append({"metric": name, "why": "no case of this scene measures it"})
        elif all(v == 0.0 for v in values):
            out.append(
                {
                    "metric": name,
                    "why": f"0 for all {len(values)} cases: undefined on this scene "
                    "(nothing of what it measures is in the image)",
                }
            )
    return out


def _group_of(families: Mapping | None, family: str) -> str:
    """The report group of a family's rows: its record's ``group`` (TAA joins the
    anti-aliasing techniques' fronts), else the family itself."""
    return ((families or {}).get(family) or {}).get("group") or family


def _defaults(families: Mapping | None, family: str, what: str) -> tuple:
    """The default ``metrics`` or ``costs`` of a report group (``families``): its own
    family's first, then those of the families that join it, each key once."""
    fams = families or {}
    members = [family] + [f for f in fams if f != family and _group_of(fams, f) == family]
    out: list = []
    for f in members:
        out += [k for k in ((fams.get(f) or {}).get(what) or ()) if k not in out]
    return tuple(out)


def _group_record(
    family: str, scene: str, rows: list[dict], costs, metrics, rank=None, families=None
) -> dict:
    """Fronts, sensitivity and gallery of the rows of one family on one scene; metrics that
    are undefined on the scene (:func:`undefined_metrics`) are left out and listed."""
    done = _done_rows(rows)
    metric_names = _numeric_keys([r["metrics"] for r in done])
    cost_names = _numeric_keys([r.get("cost") for r in done])
    default_metrics = _defaults(families, family, "metrics") or FALLBACK_METRICS
    wanted = list(metrics) or list(default_metrics)
    undefined = undefined_metrics(done, metric_names)
    gone = {o["metric"] for o in undefined}
    omitted = [o for o in undefined if o["metric"] in wanted]
    metric_names = [m for m in metric_names if m not in gone]
    metric_list = _pick(metrics, default_metrics, metric_names)
    cost_list = _pick(costs, _defaults(families, family, "costs"), cost_names)
    by_tech: dict[str, list[dict]] = {}
    for r in done:
        by_tech.setdefault(r["technique"], []).append(r)
    varying = {t: _varying(rs) for t, rs in by_tech.items()}
    label = f"{family} on {scene}"
    fronts = [
        front
        for cost_key in cost_list
        for metric in metric_list
        if (front := _front(label, done, varying, cost_key, metric, rank)) is not None
    ]
    headline = metric_list[0] if metric_list else None
    return {
        "family": family,
        "scene": scene,
        "gallery": _gallery(fronts),
        "n_cases": len(rows),
        "n_done": len(done),
        "metrics": metric_list,
        "omitted": omitted,
        "costs": cost_list,
        "fronts": fronts,
        "sensitivity": _sensitivity(scene, by_tech, varying, headline),
    }


def sweep_record(
    rows: Sequence[Mapping],
    *,
    title: str,
    provenance: Mapping | None = None,
    costs: Sequence[str] | None = None,
    metrics: Sequence[str] | None = None,
    rank=None,
    families: Mapping[str, Mapping] | None = None,
) -> dict:
    """The report record of sweep ``rows`` (see the module docstring).

    Parameters
    ----------
    costs, metrics : cost keys and metrics of the fronts (default: per family, from
        ``families``); a requested key that a group does not have is left out of that group.
    families : ``{family: {"metrics": [...], "costs": [...]}}``, the defaults per family
        (headline first; the oracle passes the registry's family records).
    rank : ``rank(metric, value)``, the value as an error (0 best) that fronts compare
        (``metrics.catalog.error_of``); None: lower values are better.
    """
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        fam = _group_of(families, r.get("family") or "shadow")
        groups.setdefault((fam, r["scene"]), []).append(dict(r))
    group_records = [
        _group_record(fam, scene, rs, list(costs or []), list(metrics or []), rank, families)
        for (fam, scene), rs in sorted(groups.items())
    ]
    all_varying = {}
    for r in rows:
        all_varying.setdefault((r["technique"], r["scene"]), []).append(r)
    vary = {k: _varying(v) for k, v in all_varying.items()}
    # each case shows its group's headline metric and cost (a metric undefined on the scene
    # is not the headline there), else the family's default
    heads = {(g["family"], g["scene"]): g for g in group_records}
    cases = []
    for r in rows:
        family = _group_of(families, r.get("family") or "shadow")
        g = heads.get((family, r["scene"])) or {}
        headline = ((g.get("metrics") or []) + [None])[0] or (
            _defaults(families, family, "metrics") or FALLBACK_METRICS
        )[0]
        cost_key = ((g.get("costs") or []) + [None])[0] or (
            _defaults(families, family, "costs") or ("",)
        )[0]
        cost = with_memory(r.get("cost"))
        cases.append(
            {
                "id": _case_id(r),
                "key": r["key"],
                "name": _label(r, vary[(r["technique"], r["scene"])]),
                "scene": r["scene"],
                "technique": r["technique"],
                "family": r.get("family"),
                "params": r.get("params") or {},
                "varied": {
                    k: v
                    for k, v in (r.get("params") or {}).items()
                    if k in vary[(r["technique"], r["scene"])]
                },
                "frame": r.get("frame"),
                "path": r.get("path"),
                "resolution": f"{r.get('width')}x{r.get('height')}",
                "spp": r.get("spp"),
                "status": r["status"],
                "error": r.get("error"),
                "metric": headline,
                "value": _number((r.get("metrics") or {}).get(headline)),
                "floor": _number(((r.get("metrics") or {}).get("noise_floor") or {}).get(headline)),
                "cost_key": cost_key,
                "cost": _number(cost.get(cost_key)),
                "wall_seconds": r.get("wall_seconds"),
            }
        )
    return {
        "schema": SWEEP_REPORT_SCHEMA,
        "title": title,
        "provenance": dict(provenance or {}),
        "summary": {
            "n_cases": len(rows),
            "n_done": sum(r["status"] == "done" for r in rows),
            "n_failed": sum(r["status"] == "failed" for r in rows),
            "scenes": sorted({r["scene"] for r in rows}),
            "techniques": sorted({r["technique"] for r in rows}),
        },
        "groups": group_records,
        "cases": cases,
    }


def write_sweep_report(
    rows: Sequence[Mapping],
    path: str | os.PathLike,
    *,
    title: str,
    provenance: Mapping | None = None,
    costs: Sequence[str] | None = None,
    metrics: Sequence[str] | None = None,
    extra_sections: Sequence[Mapping] | None = None,
    images: Mapping[str, Mapping] | None = None,
    viewers: Mapping[str, Mapping] | Callable[[list[str]], Mapping] | None = None,
    rank=None,
    families: Mapping[str, Mapping] | None = None,
) -> dict:
    """Write the page ``path`` (HTML) and its JSON twin ``path.with_suffix('.json')``.

    Parameters
    ----------
    rows, title, provenance, costs, metrics, families
        As :func:`sweep_record`.
    extra_sections : sequence of dict, optional
        Section records (:mod:`reports.sections`: claims, extremes, anti-aliasing memory,
        or a failed one) placed after the fronts; the JSON holds them under ``"sections"``.
    images : dict, optional
        Thumbnails by row key (``reference``, ``candidate``, ``error`` data URIs), shown for
        the cases on each group's headline front. They are the page's only content that is
        not in the JSON (the store keeps them; the JSON names the cases by key).
    viewers : dict or callable, optional
        Pixel viewer records by row key (:func:`reports.viewer.viewer_record`), or a function
        of a list of keys returning them (only the named cases are read): the cases the
        summary names get a viewer, fitted to one page budget
        (:func:`reports.sections.page.summary_viewer_cases`). The JSON lists them under
        ``"inspect"`` (case id, key, reduction factor and size; the arrays stay in the page).

    Returns
    -------
    dict
        The record written as JSON: :func:`sweep_record` plus ``"sections"``.
    """
    record = sweep_record(
        rows,
        title=title,
        provenance=provenance,
        costs=costs,
        metrics=metrics,
        rank=rank,
        families=families,
    )
    record["sections"] = [dict(x) for x in extra_sections or []]
    record["overview"] = overview_record(record)
    inspect = summary_viewer_cases(record, viewers or {})
    record["inspect"] = [
        {
            "id": c["id"],
            "key": key_of[c["id"]],
            "factor": c["viewer"]["factor"],
            "width": c["viewer"]["width"],
            "height": c["viewer"]["height"],
        }
        for key_of in [{c["id"]: c["key"] for c in record["cases"]}]
        for c in inspect
    ]
    html = render_sweep_page(record, images=images, viewer_cases=inspect)
    text = json.dumps(record, indent=1, allow_nan=False, default=str)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path.with_suffix(".json"), text.encode("utf-8", "backslashreplace"))
    atomic_write_bytes(path, html.encode("utf-8", "backslashreplace"))
    return record
