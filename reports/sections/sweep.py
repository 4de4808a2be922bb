"""The sweep report's page view: its plots (Pareto fronts, parameter sensitivity) as inline
SVG, and what ``templates/sweep.html`` shows besides the record of
:func:`reports.sweep.sweep_record` (one colour per technique, the best-at-equal-cost tables,
the gallery of front cases with their thumbnails). Every piece of data text in an SVG is
escaped here; the template escapes the rest."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

from markupsafe import Markup, escape

from ..formatting import fmt_cost, fmt_number, fmt_value
from ..svg import axis, scatter_svg

__all__ = [
    "PALETTE",
    "fmt_cost_level",
    "fmt_params",
    "front_svg",
    "sensitivity_svg",
    "sweep_view",
    "technique_colours",
]

_FONT = 'font-family="system-ui, sans-serif" font-size="11"'
#: Smallest max/min ratio of a positive numeric parameter drawn on a log axis.
LOG_SPAN = 4.0
#: Most parameter settings that get a tick each (more: round ticks).
MAX_LEVEL_TICKS = 8


def sensitivity_svg(item: Mapping) -> Markup:
    """Metric against one parameter: every case (hollow) and the mean per value (line).

    Numeric parameters use a value axis (base-2 logarithmic when positive and spanning at
    least :data:`LOG_SPAN` times, as resolutions and sample counts do); other parameters are
    evenly spaced categories.
    """
    width, height = 460.0, 260.0
    left, right, top, bottom = 74.0, 16.0, 14.0, 42.0
    plot_w, plot_h = width - left - right, height - top - bottom
    levels = item["levels"]
    numeric = item["numeric"]
    ys = [p["y"] for p in item["points"]]
    y_lo, y_hi, y_ticks = axis(ys, log_base=None)
    if numeric:
        xs = [float(level["x"]) for level in levels]
        log_x = min(xs) > 0 and max(xs) / min(xs) >= LOG_SPAN
        x_lo, x_hi, x_ticks = axis(xs, log_base=2.0 if log_x else None)

        def sx(v) -> float:
            v = float(v)
            if log_x:
                t = (math.log(v) - math.log(x_lo)) / (math.log(x_hi) - math.log(x_lo))
            else:
                t = (v - x_lo) / (x_hi - x_lo)
            return left + plot_w * t

        if len(xs) <= MAX_LEVEL_TICKS:  # a few settings: tick at each one
            x_ticks = xs
        tick_labels = [(sx(t), fmt_number(t)) for t in x_ticks]
    else:
        names = [fmt_value(level["x"]) for level in levels]
        index = {n: i for i, n in enumerate(names)}

        def sx(v) -> float:
            return left + plot_w * (index[fmt_value(v)] + 0.5) / len(names)

        tick_labels = [(sx(level["x"]), n) for level, n in zip(levels, names, strict=True)]

    def sy(v: float) -> float:
        return top + plot_h * (1.0 - (v - y_lo) / (y_hi - y_lo))

    title = f"{item['metric']} vs {item['param']} ({item['technique']} on {item['scene']})"
    parts = [
        f'<svg class="scatter" viewBox="0 0 {width:g} {height:g}" role="img" '
        f'aria-label="{escape(title)}" xmlns="http://www.w3.org/2000/svg">',
        f'<rect x="{left:g}" y="{top:g}" width="{plot_w:g}" height="{plot_h:g}" '
        'fill="#f8fafc" stroke="#cbd5e1"/>',
    ]
    for x, text in tick_labels:
        parts.append(
            f'<line x1="{x:.2f}" x2="{x:.2f}" y1="{top:g}" y2="{top + plot_h:g}" '
            f'stroke="#e2e8f0"/><text x="{x:.2f}" y="{top + plot_h + 14:g}" '
            f'text-anchor="middle" fill="#475569" {_FONT}>{escape(text)}</text>'
        )
    for t in y_ticks:
        y = sy(t)
        parts.append(
            f'<line x1="{left:g}" x2="{left + plot_w:g}" y1="{y:.2f}" y2="{y:.2f}" '
            f'stroke="#e2e8f0"/><text x="{left - 6:g}" y="{y + 3:.2f}" text-anchor="end" '
            f'fill="#475569" {_FONT}>{escape(fmt_number(t))}</text>'
        )
    parts.append(
        f'<text x="{left + plot_w / 2:g}" y="{height - 8:g}" text-anchor="middle" '
        f'fill="#0f172a" {_FONT}>{escape(item["param"])}</text>'
        f'<text transform="translate(12 {top + plot_h / 2:g}) rotate(-90)" '
        f'text-anchor="middle" fill="#0f172a" {_FONT}>{escape(item["metric"])}</text>'
    )
    line = " ".join(
        f"{'M' if i == 0 else 'L'}{sx(level['x']):.2f},{sy(level['mean']):.2f}"
        for i, level in enumerate(levels)
    )
    parts.append(f'<path d="{line}" fill="none" stroke="#2563eb" stroke-width="1.6"/>')
    for p in item["points"]:
        parts.append(
            f'<circle cx="{sx(p["x"]):.2f}" cy="{sy(p["y"]):.2f}" r="3.5" fill="#ffffff" '
            f'stroke="#94a3b8" stroke-width="1.2"><title>{escape(item["param"])} = '
            f"{escape(fmt_value(p['x']))}: {escape(fmt_number(p['y']))}</title></circle>"
        )
    for level in levels:
        parts.append(
            f'<circle cx="{sx(level["x"]):.2f}" cy="{sy(level["mean"]):.2f}" r="4" '
            f'fill="#2563eb"><title>mean of {level["n"]}: {escape(fmt_number(level["mean"]))}'
            "</title></circle>"
        )
    parts.append("</svg>")
    return Markup("".join(parts))


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
    """Cost against error of one family and scene: the front as a staircase (as
    :func:`reports.svg.scatter_svg` draws it), each technique in its colour (``colour``,
    default: by order of appearance) with a legend; points on the front are filled,
    dominated ones hollow."""
    base = str(scatter_svg(front, cost_key=front["cost_key"], metric=front["metric"]))
    techs = list(dict.fromkeys(p["technique"] for p in front["points"]))
    colour = dict(colour or technique_colours(techs))
    # recolour each point: scatter_svg draws them in order, one <circle class="point..."> each
    parts = base.split('<circle class="point')
    out = [parts[0]]
    for p, rest in zip(front["points"], parts[1:], strict=True):
        c = colour[p["technique"]]
        fill = c if p["on_front"] else "#ffffff"
        rest = rest.replace('fill="#2563eb"', f'fill="{fill}"', 1)
        rest = rest.replace('fill="#ffffff"', f'fill="{fill}"', 1)
        rest = rest.replace('stroke="#1e3a8a"', f'stroke="{c}"', 1)
        rest = rest.replace('stroke="#94a3b8"', f'stroke="{c}"', 1)
        out.append(rest)
    svg = '<circle class="point'.join(out)
    legend = "".join(
        f'<span class="legend-item"><span class="swatch" style="background:{colour[t]}">'
        f"</span>{escape(t)}</span>"
        for t in techs
    )
    return Markup(f'{svg}<div class="legend">{legend}</div>')


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


def sweep_view(record: Mapping, *, images: Mapping[str, Mapping] | None = None) -> dict:
    """What the page shows besides ``record``: ``colours`` (technique -> colour), ``best``
    (the best-at-equal-cost tables) and ``gallery`` (thumbnails by row key from ``images``:
    ``{"reference", "candidate", "error"}`` data URIs; anything else is dropped)."""
    best = [
        _best_table(f"{g['family']} on {g['scene']}: {f['metric']} by {f['cost_key']}", f)
        for g in record["groups"]
        for f in g["fronts"]
    ]
    return {
        "colours": _colours(record["cases"]),
        "best": best,
        "gallery": _gallery(record["groups"], images or {}),
    }
