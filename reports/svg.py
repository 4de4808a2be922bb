"""Hand-written inline SVG plots: error histograms, cost-versus-error scatters and log-log
line plots.

Each function returns ``markupsafe.Markup``; every piece of user text it embeds (case names,
techniques, parameters) is escaped here. Coordinates are SVG user units in a ``viewBox``, so
the plots scale with the page.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from markupsafe import Markup, escape

from . import images as _images
from .formatting import fmt_cost, fmt_number, fmt_value

__all__ = ["axis", "histogram_svg", "loglog_svg", "nice_ticks", "scatter_svg"]

_FONT = 'font-family="system-ui, sans-serif" font-size="11"'
_ACCENT = "#2563eb"
_MUTED = "#94a3b8"


def nice_ticks(lo: float, hi: float, *, count: int = 5) -> list[float]:
    """Round tick values (1, 2, 2.5, 5 x 10^k steps) covering [lo, hi] with about ``count``."""
    if not hi > lo:
        hi = lo + 1.0
    raw = (hi - lo) / count
    step = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 2.5, 5.0, 10.0):
        if raw <= m * step:
            step *= m
            break
    start = math.ceil(lo / step - 1e-9) * step
    ticks = np.arange(start, hi + step * 1e-6, step)
    return [0.0 if abs(t) < step * 1e-9 else float(t) for t in ticks]


def _hex(rgb: Sequence[int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*(int(c) for c in rgb))


def histogram_svg(hist: Mapping, *, style: str, name: str) -> Markup:
    """Bar chart of ``hist`` (from ``stats.histogram``) on a log count axis.

    Bars take the heatmap colour of their bin centre, so the histogram doubles as a legend.
    """
    width, height, left, bottom, top = 420.0, 150.0, 8.0, 20.0, 18.0
    counts = np.asarray(hist["counts"], dtype=np.float64)
    edges = np.asarray(hist["edges"], dtype=np.float64)
    lo, hi = float(edges[0]), float(edges[-1])
    plot_w, plot_h = width - 2 * left, height - bottom - top
    peak = math.log10(counts.max() + 1.0) if counts.size else 1.0
    lut = _images.palette(style)
    parts = [
        f'<svg class="hist" viewBox="0 0 {width:g} {height:g}" role="img" '
        f'aria-label="Histogram of {escape(name)}" xmlns="http://www.w3.org/2000/svg">',
        f'<rect x="{left:g}" y="{top:g}" width="{plot_w:g}" height="{plot_h:g}" '
        'fill="#f8fafc" stroke="#e2e8f0"/>',
    ]
    bar_w = plot_w / max(len(counts), 1)
    for i, count in enumerate(counts):
        if count <= 0:
            continue
        h = plot_h * math.log10(count + 1.0) / max(peak, 1e-12)
        centre = 0.5 * (edges[i] + edges[i + 1])
        t = (centre - lo) / (hi - lo)
        colour = _hex(lut[int(round(t * (len(lut) - 1)))])
        if colour == "#000000":
            colour = "#334155"
        share = count / max(hist["total"], 1)
        parts.append(
            f'<rect x="{left + i * bar_w:.2f}" y="{top + plot_h - h:.2f}" '
            f'width="{max(bar_w - 0.6, 0.4):.2f}" height="{h:.2f}" fill="{colour}">'
            f"<title>[{fmt_number(edges[i])}, {fmt_number(edges[i + 1])}): "
            f"{int(count):,} px ({share:.2%})</title></rect>"
        )
    for value in (lo, 0.5 * (lo + hi), hi):
        x = left + plot_w * (value - lo) / (hi - lo)
        anchor = "start" if value == lo else ("end" if value == hi else "middle")
        parts.append(
            f'<text x="{x:.2f}" y="{height - 6:g}" text-anchor="{anchor}" fill="#475569" '
            f"{_FONT}>{fmt_number(value)}</text>"
        )
    parts.append(
        f'<text x="{width - left:g}" y="{top - 6:g}" text-anchor="end" fill="#64748b" '
        f"{_FONT}>log count · max {int(counts.max()) if counts.size else 0:,}</text></svg>"
    )
    return Markup("".join(parts))


def axis(
    values: Sequence[float], *, log_base: float | None, unit: float = 1.0
) -> tuple[float, float, list[float]]:
    """Axis limits and ticks: powers of ``log_base``, or round multiples of ``unit``."""
    lo, hi = min(values), max(values)
    if log_base is not None:
        lo_exp = math.floor(math.log(lo, log_base) + 1e-9)
        hi_exp = math.ceil(math.log(hi, log_base) - 1e-9)
        if hi_exp == lo_exp:
            hi_exp += 1
        stride = max(1, math.ceil((hi_exp - lo_exp) / 6))
        ticks = [float(log_base) ** e for e in range(lo_exp, hi_exp + 1, stride)]
        return float(log_base) ** lo_exp, float(log_base) ** hi_exp, ticks
    lo, hi = lo / unit, hi / unit
    pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi) * 0.1, 1.0)
    lo = 0.0 if lo >= 0.0 and lo - pad < 0.0 else lo - pad
    hi = hi + pad
    ticks = nice_ticks(lo, hi)
    lo, hi = min(lo, ticks[0]), max(hi, ticks[-1])
    return lo * unit, hi * unit, [t * unit for t in ticks]


def scatter_svg(family: Mapping, *, cost_key: str, metric: str) -> Markup:
    """Scatter of one family's points (x = cost, y = error) with its Pareto front.

    The front is drawn as a staircase through the non-dominated points (filled); dominated
    points are hollow. x is logarithmic (powers of 2 for bytes, else of 10) when all costs are
    positive and span more than 20x.
    Each point links to its case section and carries a tooltip.
    """
    width, height = 460.0, 300.0
    left, right, top, bottom = 62.0, 16.0, 14.0, 42.0
    plot_w, plot_h = width - left - right, height - top - bottom
    points = family["points"]
    costs = [float(p["cost"]) for p in points]
    errors = [float(p["error"]) for p in points]
    log_x = min(costs) > 0 and max(costs) / min(costs) > 20.0
    is_bytes = cost_key.endswith("bytes")
    log_base = (2.0 if is_bytes else 10.0) if log_x else None
    # Linear byte axes tick at round numbers of KiB/MiB/GiB, not of bytes.
    unit = 1024.0 ** max(0, math.floor(math.log(max(max(costs), 1.0), 1024))) if is_bytes else 1.0
    x_lo, x_hi, x_ticks = axis(costs, log_base=log_base, unit=unit)
    y_lo, y_hi, y_ticks = axis(errors, log_base=None)

    def sx(v: float) -> float:
        if log_x:
            t = (math.log10(v) - math.log10(x_lo)) / (math.log10(x_hi) - math.log10(x_lo))
        else:
            t = (v - x_lo) / (x_hi - x_lo)
        return left + plot_w * t

    def sy(v: float) -> float:
        return top + plot_h * (1.0 - (v - y_lo) / (y_hi - y_lo))

    label = escape(family["family"])
    parts = [
        f'<svg class="scatter" viewBox="0 0 {width:g} {height:g}" role="img" '
        f'aria-label="{escape(metric)} versus {escape(cost_key)} for {label}" '
        'xmlns="http://www.w3.org/2000/svg">',
        f'<rect x="{left:g}" y="{top:g}" width="{plot_w:g}" height="{plot_h:g}" '
        'fill="#f8fafc" stroke="#cbd5e1"/>',
    ]
    for t in x_ticks:
        x = sx(t)
        parts.append(
            f'<line x1="{x:.2f}" x2="{x:.2f}" y1="{top:g}" y2="{top + plot_h:g}" '
            'stroke="#e2e8f0"/>'
            f'<text x="{x:.2f}" y="{top + plot_h + 14:g}" text-anchor="middle" fill="#475569" '
            f"{_FONT}>{escape(fmt_cost(t, cost_key))}</text>"
        )
    for t in y_ticks:
        y = sy(t)
        parts.append(
            f'<line x1="{left:g}" x2="{left + plot_w:g}" y1="{y:.2f}" y2="{y:.2f}" '
            'stroke="#e2e8f0"/>'
            f'<text x="{left - 6:g}" y="{y + 3:.2f}" text-anchor="end" fill="#475569" '
            f"{_FONT}>{escape(fmt_number(t))}</text>"
        )
    scale = " (log)" if log_x else ""
    parts.append(
        f'<text x="{left + plot_w / 2:g}" y="{height - 8:g}" text-anchor="middle" '
        f'fill="#0f172a" {_FONT}>{escape(cost_key)}{scale} — lower is cheaper</text>'
        f'<text transform="translate(14 {top + plot_h / 2:g}) rotate(-90)" '
        f'text-anchor="middle" fill="#0f172a" {_FONT}>{escape(metric)} — lower is better</text>'
    )
    front = [points[i] for i in family["front"]]
    if front:
        xy = [(sx(p["cost"]), sy(p["error"])) for p in front]
        path = [f"M{xy[0][0]:.2f},{xy[0][1]:.2f}"]
        for x1, y1 in xy[1:]:
            path.append(f"H{x1:.2f}V{y1:.2f}")
        path.append(f"H{left + plot_w:g}")
        parts.append(
            f'<path class="front" d="{"".join(path)}" fill="none" stroke="{_ACCENT}" '
            'stroke-width="1.6" stroke-dasharray="5 3"/>'
        )
    for p in points:
        params = ", ".join(f"{k}={fmt_value(v)}" for k, v in p.get("params", {}).items())
        tip = f"{p['name']} ({p.get('technique') or '—'}{'; ' + params if params else ''}): "
        tip += f"{cost_key} = {fmt_cost(p['cost'], cost_key)}, {metric} = {fmt_number(p['error'])}"
        fill, stroke = (_ACCENT, "#1e3a8a") if p["on_front"] else ("#ffffff", _MUTED)
        css = "point on-front" if p["on_front"] else "point"
        parts.append(
            f'<a href="#{escape(p["case_id"])}"><circle class="{css}" '
            f'cx="{sx(p["cost"]):.2f}" cy="{sy(p["error"]):.2f}" r="5" fill="{fill}" '
            f'stroke="{stroke}" stroke-width="1.5"><title>{escape(tip)}</title></circle></a>'
        )
    parts.append("</svg>")
    return Markup("".join(parts))


_COLOURS = ("#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2")


def _decades(lo: float, hi: float) -> tuple[int, int]:
    a = math.floor(math.log10(lo) + 1e-9)
    b = math.ceil(math.log10(hi) - 1e-9)
    return a, b if b > a else a + 1


def loglog_svg(series: Sequence[Mapping], *, x_label: str, y_label: str, title: str = "") -> Markup:
    """A log-log line plot. ``series``: ``{"name", "x", "y", "dashed"?}`` (positive values
    only are drawn; others are left out)."""
    width, height = 560.0, 330.0
    left, right, top, bottom = 64.0, 150.0, 20.0, 40.0
    pw, ph = width - left - right, height - top - bottom
    xs = [float(v) for s in series for v in s["x"] if v and v > 0]
    ys = [float(v) for s in series for v in s["y"] if v is not None and v > 0]
    if not xs or not ys:
        return Markup('<p class="na">nothing to plot (no positive values)</p>')
    x0, x1 = _decades(min(xs), max(xs))
    y0, y1 = _decades(min(ys), max(ys))

    def sx(v: float) -> float:
        return left + pw * (math.log10(v) - x0) / (x1 - x0)

    def sy(v: float) -> float:
        return top + ph * (1.0 - (math.log10(v) - y0) / (y1 - y0))

    parts = [
        f'<svg viewBox="0 0 {width:g} {height:g}" role="img" aria-label="{escape(title)}" '
        'xmlns="http://www.w3.org/2000/svg">',
        f'<rect x="{left:g}" y="{top:g}" width="{pw:g}" height="{ph:g}" fill="#f8fafc" '
        'stroke="#cbd5e1"/>',
    ]
    for e in range(x0, x1 + 1):
        x = sx(10.0**e)
        parts.append(
            f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top:g}" y2="{top + ph:g}" stroke="#e2e8f0"/>'
            f'<text x="{x:.1f}" y="{top + ph + 14:g}" text-anchor="middle" fill="#475569" '
            f"{_FONT}>1e{e}</text>"
        )
    for e in range(y0, y1 + 1):
        y = sy(10.0**e)
        parts.append(
            f'<line x1="{left:g}" x2="{left + pw:g}" y1="{y:.1f}" y2="{y:.1f}" stroke="#e2e8f0"/>'
            f'<text x="{left - 6:g}" y="{y + 3:.1f}" text-anchor="end" fill="#475569" '
            f"{_FONT}>1e{e}</text>"
        )
    drawn = 0
    for k, s in enumerate(series):
        colour = _COLOURS[k % len(_COLOURS)]
        pts = [
            (sx(float(x)), sy(float(y)))
            for x, y in zip(s["x"], s["y"], strict=True)
            if x and x > 0 and y is not None and y > 0
        ]
        if not pts:
            continue
        dash = ' stroke-dasharray="5 3"' if s.get("dashed") else ""
        d = "M" + "L".join(f"{x:.1f},{y:.1f}" for x, y in pts)
        parts.append(f'<path d="{d}" fill="none" stroke="{colour}" stroke-width="1.6"{dash}/>')
        for x, y in pts:
            parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="2.5" fill="{colour}"/>')
        ly = top + 14 + 16 * drawn
        drawn += 1
        parts.append(
            f'<line x1="{left + pw + 10:g}" x2="{left + pw + 30:g}" y1="{ly - 4:g}" '
            f'y2="{ly - 4:g}" stroke="{colour}" stroke-width="2"{dash}/>'
            f'<text x="{left + pw + 34:g}" y="{ly:g}" fill="#0f172a" {_FONT}>'
            f"{escape(s['name'])}</text>"
        )
    parts.append(
        f'<text x="{left + pw / 2:g}" y="{height - 8:g}" text-anchor="middle" fill="#0f172a" '
        f"{_FONT}>{escape(x_label)} (log)</text>"
        f'<text transform="translate(14 {top + ph / 2:g}) rotate(-90)" text-anchor="middle" '
        f'fill="#0f172a" {_FONT}>{escape(y_label)} (log)</text></svg>'
    )
    return Markup("".join(parts))
