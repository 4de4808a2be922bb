"""The summary at the top of the sweep and main reports: the answer first.

Per technique family and scene, the best technique at each cost level of the headline front
(the cases no cheaper case beats: cost level -> technique, parameters, its error, the noise
floor and how far the error is from the truth in noise floors), the metrics left out as
undefined on the scene, and one line per claim and for the extremes. Data in (the record of
:func:`reports.sweep.sweep_record` with its ``"sections"``), JSON-safe record out; it is
stored in ``report.json`` under ``"overview"`` and ``templates/sweep.html`` renders it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

__all__ = ["MAX_LEVELS", "group_anchor", "overview_record"]

#: Most cost levels shown per group in the summary (the cheapest, the most accurate and
#: evenly spaced ones between); the detail below has them all.
MAX_LEVELS = 5


def group_anchor(family: str, scene: str) -> str:
    """The HTML id of a group's detail (its fronts)."""
    return "group-" + re.sub(r"[^A-Za-z0-9_-]+", "-", f"{family}-{scene}").strip("-")


def _spread(items: Sequence, n: int) -> list:
    """At most ``n`` of ``items``: the first, the last and evenly spaced ones between."""
    if len(items) <= n:
        return list(items)
    picks = sorted({round(i * (len(items) - 1) / (n - 1)) for i in range(n)})
    return [items[i] for i in picks]


def _rank(point: Mapping) -> float:
    """A point's value as an error, 0 best (its ``rank``, see ``reports.sweep.sweep_record``)."""
    return point.get("rank", point["error"])


def _levels(front: Mapping) -> list[dict]:
    """The front's points by increasing cost: each the best of its cost level."""
    points: dict[float, Mapping] = {}
    for i in front["front"]:  # one per cost: ties on the front keep the first (lowest error)
        p = front["points"][i]
        if p["cost"] not in points or _rank(p) < _rank(points[p["cost"]]):
            points[p["cost"]] = p
    out = []
    for p in _spread(sorted(points.values(), key=lambda p: p["cost"]), MAX_LEVELS):
        floor, floor_rank = p.get("floor"), p.get("floor_rank", p.get("floor"))
        ratio = _rank(p) / floor_rank if floor_rank else None
        out.append(
            {
                "cost": p["cost"],
                "technique": p["technique"],
                "params": p.get("params") or {},
                "error": p["error"],
                "floor": floor,
                "floors_from_truth": ratio,
                "within_noise": bool(floor_rank is not None and _rank(p) <= floor_rank),
                "case_id": p["case_id"],
            }
        )
    return out


def _claims(sections: Sequence[Mapping]) -> list[dict]:
    out = []
    for s in sections:
        if s.get("kind") != "claims" or s.get("failed"):
            continue
        for row in (s.get("data") or {}).get("claims", []):
            out.append(
                {
                    "id": row.get("id"),
                    "verdict": row.get("verdict"),
                    "value_text": row.get("value_text") or row.get("note") or "",
                    "value": row.get("value"),
                    "anchor": s["id"],
                }
            )
    return out


def _extremes(sections: Sequence[Mapping]) -> dict | None:
    for s in sections:
        if s.get("kind") != "extremes" or s.get("failed"):
            continue
        cells = [c for c in (s.get("data") or {}).get("cells", []) if c.get("status") != "n/a"]
        met = sum(bool(c.get("outcome_met")) for c in cells)
        return {
            "anchor": s["id"],
            "cells": len(cells),
            "as_documented": met,
            "unexpected": list((s.get("data") or {}).get("unexpected") or []),
        }
    return None


def overview_record(record: Mapping) -> dict:
    """The summary of a sweep report record (see the module docstring)."""
    groups = []
    for g in record["groups"]:
        head = g["fronts"][0] if g["fronts"] else None
        groups.append(
            {
                "family": g["family"],
                "scene": g["scene"],
                "anchor": group_anchor(g["family"], g["scene"]),
                "metric": head["metric"] if head else None,
                "cost_key": head["cost_key"] if head else None,
                "levels": _levels(head) if head else [],
                "n_levels": len({head["points"][i]["cost"] for i in head["front"]}) if head else 0,
                "omitted": list(g.get("omitted") or []),
            }
        )
    sections = record.get("sections") or []
    return {
        "groups": groups,
        "claims": _claims(sections),
        "extremes": _extremes(sections),
        "failed_sections": [s["title"] for s in sections if s.get("failed")],
    }
