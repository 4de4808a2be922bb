"""HTML of the sweep report: one self-contained page (inline CSS and SVG, no script, no
network). Every piece of data text is escaped here; ``extra_sections`` are HTML fragments
that escaped their own text (the claims and extremes sections)."""

from __future__ import annotations

import importlib.resources
import math
import re
from collections.abc import Mapping, Sequence

from markupsafe import Markup, escape

from .._format import fmt_cost, fmt_number, fmt_value
from .._svg import _axis, scatter_svg

__all__ = ["front_svg", "render_sweep_html", "sensitivity_svg", "technique_colours"]

_FONT = 'font-family="system-ui, sans-serif" font-size="11"'
#: Smallest max/min ratio of a positive numeric parameter drawn on a log axis.
LOG_SPAN = 4.0
#: Most parameter settings that get a tick each (more: round ticks).
MAX_LEVEL_TICKS = 8
_EXTRA_CSS = """
.front-grid { display: grid; gap: 14px;
  grid-template-columns: repeat(auto-fill, minmax(440px, 1fr)); }
.front-grid figure { margin: 0; }
.front-grid figcaption { font-size: 12.5px; color: #475569; }
table.sweep td, table.sweep th { padding: 3px 8px; border-bottom: 1px solid #e2e8f0;
  text-align: left; vertical-align: top; }
table.sweep td.num, table.sweep th.num { text-align: right; }
table.sweep tr.failed td { background: #fee2e2; }
.nowrap { white-space: nowrap; }
.thumbs { display: flex; flex-wrap: wrap; gap: 10px; }
.thumb { margin: 0; width: 240px; }
.thumb img { display: block; width: 100%; image-rendering: pixelated; margin-bottom: 2px; }
.thumb figcaption { font-size: 12px; color: #475569; }
.legend { display: flex; flex-wrap: wrap; gap: 2px 12px; font-size: 12px; color: #334155; }
.legend .swatch { display: inline-block; width: 10px; height: 10px; border-radius: 50%;
  margin-right: 4px; vertical-align: -1px; }
"""


def _css() -> str:
    try:
        base = importlib.resources.files("reports").joinpath("templates/report.css").read_text()
    except OSError:
        base = ""
    return base + _EXTRA_CSS


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
    y_lo, y_hi, y_ticks = _axis(ys, log_base=None)
    if numeric:
        xs = [float(level["x"]) for level in levels]
        log_x = min(xs) > 0 and max(xs) / min(xs) >= LOG_SPAN
        x_lo, x_hi, x_ticks = _axis(xs, log_base=2.0 if log_x else None)

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
    :func:`reports._svg.scatter_svg` draws it), each technique in its colour (``colour``,
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


def _params_text(params: Mapping) -> str:
    return ", ".join(f"{k}={fmt_value(v)}" for k, v in params.items())


def _best_table(front: Mapping) -> Markup:
    rows = front["best_at_equal_cost"]
    techs = list(dict.fromkeys(t for r in rows for t in r["best"]))
    key = front["cost_key"]
    head = "".join(f"<th>{escape(t)}</th>" for t in techs)
    body = []
    for r in rows:
        if r["cost_lo"] == r["cost_hi"]:
            level = fmt_cost(r["cost_lo"], key)
        else:
            level = f"[{fmt_cost(r['cost_lo'], key)}, {fmt_cost(r['cost_hi'], key)})"
        cells = []
        winner = min(r["best"].values(), key=lambda p: p["error"])
        for t in techs:
            p = r["best"].get(t)
            if p is None:
                cells.append("<td>—</td>")
                continue
            mark = " ★" if p is winner and len(r["best"]) > 1 else ""
            cells.append(
                f'<td><a href="#{escape(p["case_id"])}">{escape(fmt_number(p["error"]))}</a>'
                f'{mark}<br><span class="muted">{escape(_params_text(p["params"]))}</span></td>'
            )
        body.append(f'<tr><td class="nowrap">{escape(level)}</td>{"".join(cells)}</tr>')
    return Markup(
        f'<table class="sweep"><thead><tr><th>{escape(key)}</th>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table>"
    )


def _cases_table(cases: Sequence[Mapping]) -> Markup:
    out = [
        '<div class="table-scroll"><table class="sweep"><thead><tr><th>#</th><th>case</th>'
        '<th>scene</th><th>status</th><th>metric</th><th class="num">value</th>'
        '<th class="num">noise floor</th><th>cost</th><th class="num">value</th>'
        '<th class="num">seconds</th><th>parameters</th></tr></thead><tbody>'
    ]
    for i, c in enumerate(cases, 1):
        status = c["status"] + (f": {c['error']}" if c.get("error") else "")
        out.append(
            f'<tr id="{escape(c["id"])}" class="{escape(c["status"])}"><td>{i}</td>'
            f'<td class="nowrap">{escape(c["name"])}</td><td>{escape(c["scene"])} '
            f'<span class="muted">{escape(c["resolution"])}, {escape(str(c["spp"]))} spp'
            f"</span></td><td>{escape(status)}</td><td>{escape(c['metric'])}</td>"
            f'<td class="num">{escape(fmt_number(c["value"]))}</td>'
            f'<td class="num">{escape(fmt_number(c["floor"]))}</td>'
            f"<td>{escape(c['cost_key'])}</td>"
            f'<td class="num">{escape(fmt_cost(c["cost"], c["cost_key"]))}</td>'
            f'<td class="num">{escape(fmt_number(c["wall_seconds"]))}</td>'
            f'<td class="muted">{escape(_params_text(c["params"]))}</td></tr>'
        )
    out.append("</tbody></table></div>")
    return Markup("".join(out))


_DATA_URI = re.compile(r"^data:image/(png|webp|jpeg);base64,[A-Za-z0-9+/=]+$")


def _img(uri, alt: str) -> str:
    """An ``<img>`` of a ``data:`` image URI; anything else (a link, a script) is dropped."""
    if not isinstance(uri, str) or not _DATA_URI.match(uri):
        return ""
    return f'<img src="{uri}" alt="{escape(alt)}" loading="lazy">'


def _gallery(groups: Sequence[Mapping], images: Mapping[str, Mapping]) -> str:
    parts = []
    for g in groups:
        cards = [c for c in g.get("gallery", []) if c["key"] in images]
        if not cards:
            continue
        first = images[cards[0]["key"]]
        figs = [
            f'<figure class="thumb">{_img(first.get("reference"), "reference")}'
            "<figcaption>reference</figcaption></figure>"
        ]
        for c in cards:
            im = images[c["key"]]
            # a case of another frame (camera or light path) has a reference of its own
            own = im.get("reference") if im.get("reference") != first.get("reference") else None
            figs.append(
                f'<figure class="thumb">{_img(own, "reference of " + c["name"])}'
                f"{_img(im.get('candidate'), c['name'])}"
                f"{_img(im.get('error'), 'error map of ' + c['name'])}"
                f'<figcaption><a href="#{escape(c["case_id"])}">{escape(c["name"])}</a><br>'
                f"{escape(c['metric'])} {escape(fmt_number(c['error']))}, "
                f"{escape(fmt_cost(c['cost'], c['cost_key']))}</figcaption></figure>"
            )
        parts.append(
            f"<h3>{escape(g['family'])} on {escape(g['scene'])}</h3>"
            f'<div class="thumbs">{"".join(figs)}</div>'
        )
    return "".join(parts)


def render_sweep_html(
    record: Mapping, *, extra_sections: Sequence[Mapping] = (), images: Mapping | None = None
) -> str:
    """The page of a :func:`reports.sweep.sweep_record` record; ``images`` are thumbnails by
    row key (shown for the cases on each group's headline front)."""
    gallery = _gallery(record["groups"], images or {})
    s = record["summary"]
    toc = [
        '<a href="#fronts">Pareto fronts</a>',
        '<a href="#gallery">Front cases</a>',
        '<a href="#sensitivity">Sensitivity</a>',
        '<a href="#best">Best at equal cost</a>',
    ]
    toc += [f'<a href="#{escape(x["id"])}">{escape(x["title"])}</a>' for x in extra_sections]
    toc.append('<a href="#cases">Cases</a>')
    prov = "".join(
        f"<tr><th>{escape(k)}</th><td>{escape(fmt_value(v))}</td></tr>"
        for k, v in record["provenance"].items()
    )
    fronts, sens, best = [], [], []
    # one colour per technique, the same in every plot; techniques of a family differ
    by_family: dict[str, list[str]] = {}
    for c in record["cases"]:
        by_family.setdefault(c.get("family") or "", [])
        if c["technique"] not in by_family[c.get("family") or ""]:
            by_family[c.get("family") or ""].append(c["technique"])
    colours = {}
    for techs in by_family.values():
        colours.update(technique_colours(sorted(techs)))
    for g in record["groups"]:
        head = f"{g['family']} on {g['scene']}"
        figs = []
        for f in g["fronts"]:
            n_front = len(f["front"])
            figs.append(
                f"<figure>{front_svg(f, colours)}"
                f"<figcaption>{escape(f['metric'])} against {escape(f['cost_key'])}: "
                f"{n_front} of {len(f['points'])} cases on the front</figcaption></figure>"
            )
            best.append(
                f"<h3>{escape(head)}: {escape(f['metric'])} by {escape(f['cost_key'])}</h3>"
                f"{_best_table(f)}"
            )
        if figs:
            fronts.append(f'<h3>{escape(head)}</h3><div class="front-grid">{"".join(figs)}</div>')
        items = [
            f"<figure>{sensitivity_svg(it)}<figcaption>{escape(it['technique'])}: "
            f"{escape(it['metric'])} against {escape(it['param'])}</figcaption></figure>"
            for it in g["sensitivity"]
        ]
        if items:
            sens.append(f'<h3>{escape(head)}</h3><div class="front-grid">{"".join(items)}</div>')
    none = '<p class="note">No case varies in this respect.</p>'
    extras = "".join(
        f'<section id="{escape(x["id"])}" class="card"><h2>{escape(x["title"])}</h2>'
        f"{Markup(x['html'])}</section>"
        for x in extra_sections
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{escape(record['title'])}</title><style>{_css()}</style></head><body>"
        '<header class="page-head"><div class="wrap"><div class="brand">raster-oracle · '
        f'sweep report</div><h1>{escape(record["title"])}</h1><p class="totals">'
        f'<span class="chip">{s["n_cases"]} cases</span>'
        f'<span class="chip chip-pass">{s["n_done"]} done</span>'
        f'<span class="chip chip-fail">{s["n_failed"]} failed</span></p>'
        f'<nav class="toc">{"".join(toc)}</nav></div></header><main class="wrap">'
        f'<section class="card"><h2>Provenance</h2><table class="sweep">{prov}'
        f"<tr><th>scenes</th><td>{escape(', '.join(s['scenes']))}</td></tr>"
        f"<tr><th>techniques</th><td>{escape(', '.join(s['techniques']))}</td></tr>"
        "</table></section>"
        '<section id="fronts" class="card"><h2>Pareto fronts</h2><p class="note">Cost against '
        "error per technique family and scene; filled points are on the front (no other case "
        "is as cheap and as accurate), points link to their row in the cases table.</p>"
        f"{''.join(fronts) or none}</section>"
        '<section id="gallery" class="card"><h2>Front cases</h2><p class="note">The cases on '
        "each headline front (first plot of each group): the reference, then each case's "
        "image above its error map (signed for visibility: green = false-lit, red = "
        "false-shadowed; FLIP for colour).</p>"
        f"{gallery or none}</section>"
        '<section id="sensitivity" class="card"><h2>Parameter sensitivity</h2><p class="note">'
        "The headline metric against each parameter a technique varies: every case, and the "
        f"mean over the other parameters (line).</p>{''.join(sens) or none}</section>"
        '<section id="best" class="card"><h2>Best at equal cost</h2><p class="note">The '
        "lowest error each technique reaches at each cost (★: the best of the row).</p>"
        f"{''.join(best) or none}</section>{extras}"
        f'<section id="cases" class="card"><h2>Cases</h2>{_cases_table(record["cases"])}'
        "</section></main></body></html>\n"
    )
