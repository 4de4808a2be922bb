"""The one jinja2 environment of every page: templates are package data
(``reports/templates/``), autoescape is on, undefined names fail, and every number or record
is formatted by a Python filter registered here, never in a template."""

from __future__ import annotations

import functools

import jinja2

from . import formatting, plots, svg
from .sections import aa_memory, aa_ranking, claims, converge, extremes, sweep

__all__ = ["environment"]


def _filters() -> dict:
    return {
        # numbers, values and records
        "num": formatting.fmt_number,
        "cost": formatting.fmt_cost,
        "threshold": formatting.fmt_threshold,
        "value": formatting.fmt_value,
        "sortkey": formatting.sort_key,
        "flatten": formatting.flatten,
        "json_script": formatting.json_script,
        "pretty_json": formatting.fmt_json,
        "summary": formatting.fmt_summary,
        "mb": formatting.fmt_mb,
        # plots
        "histogram_svg": lambda hist, style, name: svg.histogram_svg(hist, style=style, name=name),
        "scatter_svg": lambda fam, cost_key, metric: svg.scatter_svg(
            fam, cost_key=cost_key, metric=metric
        ),
        "loglog_svg": lambda series, x_label, y_label, title: svg.loglog_svg(
            series, x_label=x_label, y_label=y_label, title=title
        ),
        "front_svg": sweep.front_svg,
        "axis_label": plots.axis_label,
        "sensitivity_svg": sweep.sensitivity_svg,
        # one section each
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


@functools.cache
def environment() -> jinja2.Environment:
    """The shared environment (built once per process; it holds no data of a page)."""
    env = jinja2.Environment(
        loader=jinja2.PackageLoader(__package__),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(_filters())
    return env
