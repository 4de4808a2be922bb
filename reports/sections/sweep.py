"""The sweep report's page view: its plots (Pareto fronts, parameter sensitivity) as inline
SVG, and what ``templates/sweep.html`` shows besides the record of
:func:`reports.sweep.sweep_record` (one colour per technique, the best-at-equal-cost tables,
the gallery of front cases with their thumbnails). Every piece of data text in an SVG is
escaped here; the template escapes the rest."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

from markupsafe import Markup

from .. import plots
from ..formatting import fmt_cost, fmt_value
from .overview import group_anchor

__all__ = [
    "PALETTE",
    "fmt_cost_level",
    "fmt_params",
    "front_svg",
    "sensitivity_svg",
    "sweep_view",
    "technique_colours",
]


def sensitivity_svg(item: Mapping) -> Markup:
    """Metric against one parameter (:func:`reports.plots.sensitivity_plot`)."""
    salt = f"sens-{item['technique']}-{item['scene']}-{item['param']}-{item['metric']}"
    return plots.sensitivity_plot(item, salt=salt)


#: Colours of the techniques of one plot, in order of appearance (Tableau 10).
PALETTE = (
    "#4e79a7",
    "#f28e2b",
    "#e15759",
    "#76b7b2",
    "#59a14f",
    "#edc948",
    "#b07aa1",
    "#ff9da7",
    "#9c755f",
    "#bab0ac",
)


def technique_colours(techniques: Sequence[str]) -> dict[str, str]:
    """One colour per technique (the page's order), the same in every plot."""
    return {t: PALETTE[i % len(PALETTE)] for i, t in enumerate(techniques)}


def front_svg(front: Mapping, colour: Mapping[str, str] | None = None) -> Markup:
    """Cost against error of one family and scene (:func:`reports.plots.front_plot`), each
    technique in its colour (``colour``, default: by order of appearance)."""
    techs = list(dict.fromkeys(p["technique"] for p in front["points"]))
    colour = dict(colour or technique_colours(techs))
    salt = f"front-{front['family']}-{front['cost_key']}-{front['metric']}"
    return plots.front_plot(front, colours=colour, salt=salt)


def fmt_params(params: Mapping) -> str:
    """``key=value, ...`` of a case's varying parameters."""
    return ", ".join(f"{k}={fmt_value(v)}" for k, v in params.items())


def fmt_cost_level(row: Mapping, key: str) -> str:
    """The cost of a best-at-equal-cost row: one value, or a ``[lo, hi)`` bin."""
    if row["cost_lo"] == row["cost_hi"]:
        return fmt_cost(row["cost_lo"], key)
    return f"[{fmt_cost(row['cost_lo'], key)}, {fmt_cost(row['cost_hi'], key)})"


def _colours(cases: Sequence[Mapping]) -> dict[str, str]:
    """One colour per technique, the same in every plot; techniques of a family differ."""
    by_family: dict[str, list[str]] = {}
    for c in cases:
        techs = by_family.setdefault(c.get("family") or "", [])
        if c["technique"] not in techs:
            techs.append(c["technique"])
    colours: dict[str, str] = {}
    for techs in by_family.values():
        colours.update(technique_colours(sorted(techs)))
    return colours


def _best_table(heading: str, front: Mapping) -> dict:
    """A best-at-equal-cost table: per cost level, each technique's best point and whether
    it is the best of the row (when more than one technique is in it)."""
    rows = front["best_at_equal_cost"]
    techs = list(dict.fromkeys(t for r in rows for t in r["best"]))
    out = []
    for r in rows:
        winner = min(r["best"].values(), key=lambda p: p["error"])
        cells = [
            {"point": r["best"].get(t), "winner": r["best"].get(t) is winner and len(r["best"]) > 1}
            for t in techs
        ]
        out.append({"level": r, "cells": cells})
    return {"heading": heading, "cost_key": front["cost_key"], "techniques": techs, "rows": out}


_DATA_URI = re.compile(r"^data:image/(png|webp|jpeg);base64,[A-Za-z0-9+/=]+$")


def _image(uri: object, alt: str) -> dict | None:
    """An image of the page: ``data:`` image URIs only (a link or a script is dropped)."""
    if not isinstance(uri, str) or not _DATA_URI.match(uri):
        return None
    return {"uri": uri, "alt": alt}


def _gallery(groups: Sequence[Mapping], images: Mapping[str, Mapping]) -> list[dict]:
    """Per group, the thumbnails of the cases on its headline front: the reference, then
    each case's own reference (another frame), image and error map."""
    out = []
    for g in groups:
        cards = [c for c in g.get("gallery", []) if c["key"] in images]
        if not cards:
            continue
        first = images[cards[0]["key"]]
        figures = [{"images": [_image(first.get("reference"), "reference")], "card": None}]
        for c in cards:
            im = images[c["key"]]
            # a case of another frame (camera or light path) has a reference of its own
            own = im.get("reference") if im.get("reference") != first.get("reference") else None
            shown = [
                _image(own, "reference of " + c["name"]),
                _image(im.get("candidate"), c["name"]),
                _image(im.get("error"), "error map of " + c["name"]),
            ]
            figures.append({"images": shown, "card": c})
        for fig in figures:
            fig["images"] = [im for im in fig["images"] if im is not None]
        out.append({"heading": f"{g['family']} on {g['scene']}", "figures": figures})
    return out


def _cases_filters(cases: Sequence[Mapping]) -> dict:
    """The choices of the cases table's filters: scenes, techniques, parameter names."""
    return {
        "scenes": sorted({c["scene"] for c in cases}),
        "techniques": sorted({c["technique"] for c in cases}),
        "params": sorted({k for c in cases for k in c.get("params") or {}}),
    }


def sweep_view(record: Mapping, *, images: Mapping[str, Mapping] | None = None) -> dict:
    """What the page shows besides ``record``: ``colours`` (technique -> colour), ``groups``
    (per family and scene: its anchor and its best-at-equal-cost tables), ``best`` (all
    those tables), ``filters`` (the cases table's choices) and ``gallery`` (thumbnails by
    row key from ``images``: ``{"reference", "candidate", "error"}`` data URIs; anything else
    is dropped)."""
    groups = []
    for g in record["groups"]:
        tables = [
            _best_table(f"{g['family']} on {g['scene']}: {f['metric']} by {f['cost_key']}", f)
            for f in g["fronts"]
        ]
        groups.append(
            {
                "anchor": group_anchor(g["family"], g["scene"]),
                "heading": f"{g['family']} on {g['scene']}",
                "best": tables,
            }
        )
    return {
        "colours": _colours(record["cases"]),
        "groups": groups,
        "best": [t for g in groups for t in g["best"]],
        "filters": _cases_filters(record["cases"]),
        "gallery": _gallery(record["groups"], images or {}),
    }
