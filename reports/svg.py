"""Inline SVG plots of the reports: the error histograms (hand-drawn bars, a colour bar of
the heat map), and the cost-versus-error scatters and log-log plots, which
:mod:`reports.plots` draws with matplotlib (its locators and formatters make the ticks).

Each function returns ``markupsafe.Markup``; every piece of user text it embeds (case names,
techniques, parameters) is escaped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from markupsafe import Markup, escape

from . import images as _images
from . import plots
from .formatting import fmt_number

__all__ = ["histogram_svg", "loglog_svg", "scatter_svg"]

_FONT = 'font-family="system-ui, sans-serif" font-size="11"'


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


def scatter_svg(family: Mapping, *, cost_key: str, metric: str) -> Markup:
    """Scatter of one family's points (x = cost, y = error) with its Pareto front, drawn by
    :func:`reports.plots.front_plot` (class ``scatter``); each point links to its case."""
    front = {**family, "cost_key": cost_key, "metric": metric}
    salt = f"scatter-{family.get('family')}-{cost_key}-{metric}"
    return plots.front_plot(front, colours={}, salt=salt, css="scatter")


def loglog_svg(
    series: Sequence[Mapping], *, x_label: str, y_label: str, title: str = "", log_y: bool = True
) -> Markup:
    """A log-log line plot (:func:`reports.plots.loglog_plot`; ``log_y=False``: linear y);
    with no value to draw, one line that says so instead of an empty plot."""
    try:
        return plots.loglog_plot(series, x_label=x_label, y_label=y_label, title=title, log_y=log_y)
    except plots.EmptyPlotError:
        return Markup('<p class="na">not plotted: no positive value to draw on log axes</p>')
