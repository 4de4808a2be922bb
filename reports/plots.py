"""The reports' plots, drawn by matplotlib and inlined as SVG.

Why matplotlib: its locators and formatters give readable ticks (no repeated labels, log axes
with proper decades) and it is a dependency already. Every plot here:

- is an inline ``<svg>`` (text kept as text: ``svg.fonttype = "none"``), deterministic (a
  fixed ``svg.hashsalt`` per plot, no date in the metadata): the same inputs give the same
  bytes;
- links each data marker to its case (``<a href="#case-...">`` from matplotlib's
  ``set_urls``) with a ``<title>`` giving the values (the browser shows it on hover);
- raises :class:`EmptyPlotError` when it has no finite point to draw: an empty plot is a bug
  of the caller, which must leave the plot out and say why;
- checks its tick labels: an axis with a repeated label raises ``AssertionError``.

Units: :func:`axis_label` names a cost or metric key with its unit.
"""

from __future__ import annotations

import functools
import io
import math
import re
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
from markupsafe import Markup, escape  # noqa: E402
from matplotlib import ticker  # noqa: E402

from .formatting import fmt_cost, fmt_number, fmt_value  # noqa: E402

__all__ = [
    "DistinctFormatter",
    "EmptyPlotError",
    "axis_label",
    "front_plot",
    "loglog_plot",
    "sensitivity_plot",
    "tick_labels",
]

#: Most max/min ratio of positive values drawn on a linear axis (above it: logarithmic).
LOG_SPAN = 10.0
#: Most max/min ratio of positive errors drawn on a linear axis (above it: logarithmic).
LOG_SPAN_ERROR = 100.0
#: Figure size in inches (at 72 SVG user units per inch).
FIG_SIZE = (5.6, 3.4)
ACCENT = "#2563eb"
FLOOR_COLOUR = "#94a3b8"
_UNITS = {
    "memory_bytes": "memory (bytes)",
    "framebuffer_bytes": "framebuffer (bytes)",
    "shadow_map_bytes": "shadow maps (bytes)",
    "texels_rendered": "texels rendered (count)",
    "shading_events_mean": "shading events per pixel (mean)",
    "misclassified_fraction": "misclassified (fraction of pixels)",
    "misclassified": "misclassified (fraction of pixels)",
    "visibility_mae": "visibility MAE (0–1)",
    "visibility_rmse": "visibility RMSE (0–1)",
    "flip_mean": "FLIP mean (0–1)",
    "coverage_edge_rmse": "coverage RMSE at edges (0–1)",
    "coverage_rmse": "coverage RMSE (0–1)",
    "ssim": "SSIM (0–1)",
    "ciede2000_mean": "CIEDE2000 mean (ΔE00)",
    "edge_error": "edge error (fraction)",
    "flicker": "flicker (0–1)",
}


class EmptyPlotError(ValueError):
    """A plot was asked for with no finite point to draw."""


def axis_label(key: str) -> str:
    """``key`` with its unit (bytes, count, fraction...), for an axis."""
    if key in _UNITS:
        return _UNITS[key]
    if key.endswith("bytes"):
        return f"{key} (bytes)"
    if key.endswith("seconds"):
        return f"{key} (s)"
    return key


def _finite(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _is_log(values: Sequence[float]) -> bool:
    lo, hi = min(values), max(values)
    return lo > 0 and hi / lo > LOG_SPAN


class DistinctFormatter(ticker.Formatter):
    """Tick labels with as many significant digits as it takes to tell the ticks apart
    (at least three): bytes in binary units, other values as plain numbers."""

    def __init__(self, *, is_bytes: bool):
        self.is_bytes = is_bytes

    def _one(self, value: float, digits: int) -> str:
        value = float(value)
        if self.is_bytes:
            for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
                if abs(value) < 1024.0 or unit == "TiB":
                    return f"{value:.{digits}g} {unit}"
                value /= 1024.0
        if value == 0.0:
            return "0"
        for scale, suffix in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")):
            if abs(value) >= scale:  # counts: 500k, 2M, not 5e+05
                return f"{value / scale:.{digits}g}{suffix}"
        return f"{value:.{digits}g}".replace("-", "−")

    def __call__(self, x, pos=None) -> str:
        return self._one(x, 3)

    def format_ticks(self, values) -> list[str]:
        labels = [self._one(v, 3) for v in values]
        for digits in range(4, 13):
            if len(set(labels)) == len(labels):
                break
            labels = [self._one(v, digits) for v in values]
        return labels


def _cost_axis(axis, key: str, *, log: bool) -> None:
    """Locator and formatter of a cost axis: binary units for bytes, else plain numbers."""
    is_bytes = key.endswith("bytes")
    if log:
        # powers of 2 for bytes; 1, 2, 5 x 10^k otherwise (a decade and a bit has 3+ ticks)
        subs = (1.0,) if is_bytes else (1.0, 2.0, 5.0)
        axis.set_major_locator(
            ticker.LogLocator(base=2.0 if is_bytes else 10.0, subs=subs, numticks=10)
        )
        axis.set_minor_formatter(ticker.NullFormatter())
    elif is_bytes:
        axis.set_major_locator(ticker.MaxNLocator(nbins=6, steps=[1, 2, 4, 5, 8, 10]))
    else:
        axis.set_major_locator(ticker.MaxNLocator(nbins=6))
    axis.set_major_formatter(DistinctFormatter(is_bytes=is_bytes))


#: Text stays text in the SVG; the page's sans-serif font draws it.
_RC = {
    "svg.fonttype": "none",
    "font.family": "sans-serif",
    "font.sans-serif": ["DejaVu Sans"],
    "axes.edgecolor": "#94a3b8",
}


def _styled(plot):
    """Run ``plot`` under :data:`_RC` (text properties are read when text is made)."""

    @functools.wraps(plot)
    def wrapper(*args, **kwargs):
        with plt.rc_context(_RC):
            return plot(*args, **kwargs)

    return wrapper


def _figure(size=FIG_SIZE):
    fig, ax = plt.subplots(figsize=size, dpi=72)
    fig.subplots_adjust(left=0.15, right=0.97, top=0.95, bottom=0.17)
    ax.grid(True, color="#e2e8f0", linewidth=0.6)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.tick_params(labelsize=8.5, colors="#475569")
    return fig, ax


def tick_labels(ax) -> dict[str, list[str]]:
    """The visible major tick labels of ``ax`` per axis (after a draw)."""
    out = {}
    for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
        lo, hi = sorted(axis.get_view_interval())
        labels = [
            t.get_text()
            for t, loc in zip(axis.get_majorticklabels(), axis.get_majorticklocs(), strict=False)
            if t.get_text() and lo - 1e-12 * abs(lo) <= loc <= hi + 1e-12 * abs(hi)
        ]
        out[name] = labels
    return out


def _svg(fig, ax, *, salt: str, css: str, label: str, tips: Mapping[str, str], on=frozenset()):
    """The figure as inline SVG: each marker's ``<a>`` (class ``point``, and ``on-front`` for
    the ids in ``on``) given its ``<title>`` from ``tips``."""
    buf = io.StringIO()
    with plt.rc_context({"svg.hashsalt": salt}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    plt.close(fig)
    for name, labels in tick_labels(ax).items():  # as drawn by savefig
        if len(labels) != len(set(labels)):
            raise AssertionError(f"{label}: repeated {name} tick labels {labels}")
    text = buf.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(
        r'<svg xmlns:xlink="http://www.w3.org/1999/xlink" width="[^"]*" height="[^"]*"',
        f'<svg class="plot {css}" role="img" aria-label="{escape(label)}"',
        text,
        count=1,
    )
    text = re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.S)
    # matplotlib's group ids (figure_1, xtick_3, ...) repeat in every plot of a page: classes
    text = re.sub(r'<g id="([A-Za-z]+)_\d+">', r'<g class="\1">', text)

    def titled(m: re.Match) -> str:
        tip = tips.get(m.group(1))
        cls = "point on-front" if m.group(1) in on else "point"
        link = f'<a href="#{m.group(1)}" class="{cls}">'
        return link + (f"<title>{escape(tip)}</title>" if tip else "")

    text = re.sub(r'<a xlink:href="#([^"]+)"(?: target="_blank")?>', titled, text)
    # inline in HTML: SVG 2's plain href, no XLink namespace to declare
    text = text.replace(" xlink:href=", " href=")
    return Markup(text)


def _floor_band(ax, floor: float | None, *, bottom: float = 0.0) -> None:
    """The noise floor as a band from ``bottom`` (0 on a linear axis; named in the legend)."""
    if floor is not None and floor > bottom:
        style = {"color": FLOOR_COLOUR, "alpha": 0.3, "linewidth": 0, "zorder": 0.5}
        ax.axhspan(bottom, floor, label="noise floor", **style)


def _value_axis(axis) -> None:
    """A linear value axis: round ticks, labels without an offset, told apart."""
    axis.set_major_locator(ticker.MaxNLocator(nbins=6))
    axis.set_major_formatter(DistinctFormatter(is_bytes=False))


@_styled
def front_plot(
    front: Mapping,
    *,
    colours: Mapping[str, str] | None = None,
    salt: str = "",
    css: str = "front",
) -> Markup:
    """Cost against error of one family and scene (``reports.sweep`` front record): each
    technique in its colour, the Pareto front as a dashed staircase (its points filled,
    dominated ones hollow), the noise floor (the largest of the points' floors) as a band.
    x is logarithmic when the costs span more than :data:`LOG_SPAN` times."""
    pts = [p for p in front["points"] if _finite(p.get("cost")) and _finite(p.get("error"))]
    cost_key, metric = front["cost_key"], front["metric"]
    label = f"{metric} against {cost_key} ({front.get('family', '')})"
    if not pts:
        raise EmptyPlotError(f"{label}: no point with a finite cost and error")
    colours = dict(colours or {})
    fig, ax = _figure()
    techs = list(dict.fromkeys(p.get("technique") or "" for p in pts))
    tips = {}
    for k, tech in enumerate(techs):
        mine = [p for p in pts if (p.get("technique") or "") == tech]
        colour = colours.get(tech) or plt.get_cmap("tab10")(k % 10)
        for on in (True, False):
            sel = [p for p in mine if bool(p.get("on_front")) is on]
            if not sel:
                continue
            coll = ax.scatter(
                [p["cost"] for p in sel],
                [p["error"] for p in sel],
                s=34,
                facecolors=colour if on else "white",
                edgecolors=colour,
                linewidths=1.4,
                zorder=3,
                label=tech if on or not any(p.get("on_front") for p in mine) else None,
            )
            coll.set_urls([f"#{p['case_id']}" for p in sel])
            for p in sel:
                tips[p["case_id"]] = _point_tip(p, cost_key, metric)
    order = [front["points"][i] for i in front.get("front", [])]
    order = [p for p in order if _finite(p.get("cost")) and _finite(p.get("error"))]
    if order:
        xs = [p["cost"] for p in order]
        ys = [p["error"] for p in order]
        ax.step(xs, ys, where="post", color=ACCENT, linestyle="--", linewidth=1.1, zorder=2)
    costs = [p["cost"] for p in pts]
    log = _is_log(costs)
    if log:
        ax.set_xscale("log", base=2.0 if cost_key.endswith("bytes") else 10.0)
    _cost_axis(ax.xaxis, cost_key, log=log)
    floors = [p["floor"] for p in pts if _finite(p.get("floor"))]
    errors = [p["error"] for p in pts]
    log_y = min(errors) > 0 and max(errors) / min(errors) > LOG_SPAN_ERROR
    floor = max(floors) if floors else None
    if log_y:
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(ticker.LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_minor_formatter(ticker.NullFormatter())
        ax.yaxis.set_major_formatter(DistinctFormatter(is_bytes=False))
        _floor_band(ax, floor, bottom=min([*errors, floor or math.inf]) / 4.0)
    else:
        _floor_band(ax, floor)
        ax.set_ylim(bottom=0.0)
        _value_axis(ax.yaxis)
    ax.set_xlabel(axis_label(cost_key) + (", log scale" if log else ""), fontsize=9)
    ax.set_ylabel(axis_label(metric) + (", log" if log_y else ""), fontsize=9)
    ax.legend(fontsize=8, frameon=True, framealpha=0.85, edgecolor="none", loc="best")
    on = frozenset(p["case_id"] for p in pts if p.get("on_front"))
    return _svg(fig, ax, salt=salt or label, css=css, label=label, tips=tips, on=on)


def _point_tip(p: Mapping, cost_key: str, metric: str) -> str:
    params = ", ".join(f"{k}={fmt_value(v)}" for k, v in (p.get("params") or {}).items())
    tip = f"{p.get('name') or p.get('technique')}"
    if params:
        tip += f" ({params})"
    tip += f": {cost_key} = {fmt_cost(p['cost'], cost_key)}, {metric} = {fmt_number(p['error'])}"
    if _finite(p.get("floor")):
        tip += f", noise floor {fmt_number(p['floor'])}"
    return tip


@_styled
def sensitivity_plot(item: Mapping, *, salt: str = "") -> Markup:
    """The metric against one parameter (``reports.sweep`` sensitivity record): every case
    (hollow, linked to it) and the mean per setting (line). Numeric parameters on a value axis
    (base 2 log when positive and spanning more than 4x), others as categories."""
    pts = [p for p in item["points"] if _finite(p.get("y"))]
    label = f"{item['metric']} against {item['param']} ({item['technique']} on {item['scene']})"
    if not pts:
        raise EmptyPlotError(f"{label}: no finite value")
    fig, ax = _figure((5.0, 3.0))
    levels = item["levels"]
    if item["numeric"]:
        xs = [float(level["x"]) for level in levels]

        def pos(v):
            return float(v)

        if min(xs) > 0 and max(xs) / min(xs) > 4.0:
            ax.set_xscale("log", base=2.0)
            ax.xaxis.set_minor_formatter(ticker.NullFormatter())
        if len(xs) <= 8:
            ax.xaxis.set_major_locator(ticker.FixedLocator(xs))
            ax.xaxis.set_minor_locator(ticker.NullLocator())
        ax.xaxis.set_major_formatter(DistinctFormatter(is_bytes=False))
    else:
        names = list(dict.fromkeys(fmt_value(level["x"]) for level in levels))

        def pos(v):
            return float(names.index(fmt_value(v)))

        ax.xaxis.set_major_locator(ticker.FixedLocator(range(len(names))))
        ax.xaxis.set_major_formatter(ticker.FixedFormatter(names))
        ax.set_xlim(-0.5, len(names) - 0.5)
    coll = ax.scatter(
        [pos(p["x"]) for p in pts],
        [p["y"] for p in pts],
        s=22,
        facecolors="white",
        edgecolors="#64748b",
        linewidths=1.1,
        zorder=3,
    )
    tips = {}
    urls = []
    for p in pts:
        cid = p.get("case_id")
        urls.append(f"#{cid}" if cid else None)
        if cid:
            tips[cid] = f"{item['param']} = {fmt_value(p['x'])}: {fmt_number(p['y'])}"
    coll.set_urls(urls)
    ax.plot(
        [pos(level["x"]) for level in levels],
        [level["mean"] for level in levels],
        color=ACCENT,
        marker="o",
        markersize=4,
        linewidth=1.4,
        zorder=2,
        label="mean",
    )
    _value_axis(ax.yaxis)
    ax.set_xlabel(axis_label(item["param"]), fontsize=9)
    ax.set_ylabel(axis_label(item["metric"]), fontsize=9)
    return _svg(fig, ax, salt=salt or label, css="sensitivity", label=label, tips=tips)


@_styled
def loglog_plot(
    series: Sequence[Mapping],
    *,
    x_label: str,
    y_label: str,
    title: str = "",
    salt: str = "",
    log_y: bool = True,
) -> Markup:
    """Log-log lines of ``series`` (``{"name", "x", "y", "dashed"?}``; positive values only
    are drawn), with a legend; each point's ``<title>`` gives its values. ``log_y=False``:
    a linear y axis (log x), on which zeros and negative values are drawn too."""
    fig, ax = _figure((6.4, 3.6))
    drawn = 0
    tips = {}
    for k, s in enumerate(series):
        xy = [
            (float(x), float(y))
            for x, y in zip(s["x"], s["y"], strict=True)
            if _finite(x) and _finite(y) and x > 0 and (y > 0 or not log_y)
        ]
        if not xy:
            continue
        drawn += 1
        colour = plt.get_cmap("tab10")(k % 10)
        ax.plot(
            *zip(*xy, strict=True),
            color=colour,
            linestyle="--" if s.get("dashed") else "-",
            linewidth=1.4,
            label=s["name"],
        )
        coll = ax.scatter(*zip(*xy, strict=True), s=12, color=colour, zorder=3)
        ids = [f"s{k}-p{i}" for i in range(len(xy))]
        coll.set_urls([f"#{i}" for i in ids])
        for i, (x, y) in zip(ids, xy, strict=True):
            tips[i] = f"{s['name']}: {x_label} = {fmt_number(x)}, {y_label} = {fmt_number(y)}"
    if not drawn:
        plt.close(fig)
        raise EmptyPlotError(f"{title or y_label}: no positive value")
    ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis) if log_y else (ax.xaxis,):  # 1, 2, 5 x 10^k ticks
        axis.set_major_locator(ticker.LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        axis.set_minor_formatter(ticker.NullFormatter())
        axis.set_major_formatter(DistinctFormatter(is_bytes=False))
    ax.set_xlabel(f"{x_label}, log scale", fontsize=9)
    ax.set_ylabel(f"{y_label}, log scale" if log_y else y_label, fontsize=9)
    ax.legend(fontsize=8, frameon=True, framealpha=0.85, edgecolor="none", loc="best")
    text = _svg(fig, ax, salt=salt or title, css="loglog", label=title, tips=tips)
    # the series' points are not cases: their links go nowhere, keep the titles only
    return Markup(re.sub(r'<a href="#s\d+-p\d+" ', "<a ", str(text)))
