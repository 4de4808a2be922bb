"""The jinja2 environment of every page: templates are package data
(``reports/templates/``), autoescape is on, undefined names fail, and every number or record
is formatted by a Python filter registered here, never in a template. The section pages add
their own filters (:mod:`reports.sections.page`) to an environment built here: this module
imports nothing of :mod:`reports.sections`, so the two never import each other."""

from __future__ import annotations

import functools

import jinja2

from . import formatting, plots, svg

__all__ = ["build_environment", "environment"]


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
        "loglog_svg": lambda series, x_label, y_label, title, log_y=True: svg.loglog_svg(
            series, x_label=x_label, y_label=y_label, title=title, log_y=log_y
        ),
        "axis_label": plots.axis_label,
    }


def build_environment(extra_filters: dict | None = None) -> jinja2.Environment:
    """A new environment with the shared filters and ``extra_filters`` (name -> function)."""
    env = jinja2.Environment(
        loader=jinja2.PackageLoader(__package__),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(_filters())
    env.filters.update(extra_filters or {})
    return env


@functools.cache
def environment() -> jinja2.Environment:
    """The shared environment (built once per process; it holds no data of a page)."""
    return build_environment()
