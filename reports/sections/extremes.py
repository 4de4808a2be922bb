"""The numerical-extremes section: a matrix of models x extremes.

Data in (the record of :func:`oracle.studies.extremes.run.run_extremes`), section record out;
``templates/section_extremes.html`` renders it. A cell shows the model's error against the
oracle (or n/a, refused, non-finite, error), coloured by that error on a sequential colour map
(logarithmic, :data:`ERROR_RANGE`; a legend below the matrix): the size of the error is what
the colour says, also where it was expected. The documented expectation is a mark in the cell
(an upper bound, or a band for a documented weakness, with its value); a cell whose outcome
is not as documented gets a red border and a cross. The tooltip gives the numbers, the
expectation and its reason.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import matplotlib
from matplotlib import colors

from ..formatting import fmt_number
from ._record import section_record

__all__ = [
    "COLOUR_MAP",
    "ERROR_RANGE",
    "cell_class",
    "cell_mark",
    "cell_style",
    "error_legend",
    "extremes_section",
    "fmt_cell",
    "fmt_cell_tip",
]

#: Sequential colour map of the cells' errors (light: small, dark: large).
COLOUR_MAP = "YlOrRd"
#: Errors mapped onto the colour map, logarithmically; smaller ones take its first colour.
ERROR_RANGE = (1e-4, 1.0)
#: Stops of the legend's gradient.
LEGEND_STOPS = 9

#: Most cells named in one documented outcome; above it, their count.
MAX_NAMED_CELLS = 6


def _matrix(data: Mapping) -> list[dict]:
    """One row per extreme: per technique the index of its cell in ``data["cells"]``."""
    index = {(c["extreme"], c["technique"]): i for i, c in enumerate(data["cells"])}
    return [
        {"extreme": ext, "cells": [index.get((ext, t)) for t in data["techniques"]]}
        for ext in data["extremes"]
    ]


def _outcomes(data: Mapping) -> list[dict]:
    """Each distinct documented expectation (and reason) with the cells it covers."""
    groups: dict[tuple, list[str]] = {}
    for c in data["cells"]:
        if c.get("status") != "n/a":
            key = (c.get("expected"), c.get("reason"))
            groups.setdefault(key, []).append(f"{c['technique']} x {c['extreme']}")
    out = []
    for (expected, reason), who in groups.items():
        who = sorted(who)
        label = ", ".join(who) if len(who) <= MAX_NAMED_CELLS else f"{len(who)} cells"
        out.append({"expected": expected, "reason": reason or "", "cells": label})
    return out


def _colour(error: float) -> tuple[str, str]:
    """Background and text colour of a cell of ``error``."""
    lo, hi = ERROR_RANGE
    t = (math.log10(min(max(error, lo), hi)) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
    r, g, b, _ = matplotlib.colormaps[COLOUR_MAP](t)
    ink = "#ffffff" if 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.5 else "#0f172a"
    return colors.to_hex((r, g, b)), ink


def error_legend() -> dict:
    """The colour bar under the matrix: a CSS gradient and its ticks (position in %)."""
    lo, hi = (math.log10(v) for v in ERROR_RANGE)
    stops = []
    for i in range(LEGEND_STOPS):
        t = i / (LEGEND_STOPS - 1)
        stops.append(f"{_colour(10.0 ** (lo + t * (hi - lo)))[0]} {100 * t:.0f}%")
    ticks = [
        {"pos": 100.0 * (e - lo) / (hi - lo), "text": fmt_number(10.0**e)}
        for e in range(math.ceil(lo), math.floor(hi) + 1)
    ]
    return {"gradient": "linear-gradient(to right, " + ", ".join(stops) + ")", "ticks": ticks}


def extremes_section(
    data: Mapping,
    *,
    section_id: str = "extremes",
    title: str = "Numerical stability at the extremes",
) -> dict:
    """The section record of an extremes run: the data, the ``matrix`` (rows of cell
    indices, one column per technique) and the documented ``outcomes``."""
    return section_record(
        "extremes",
        section_id=section_id,
        title=title,
        data=data,
        matrix=_matrix(data),
        outcomes=_outcomes(data),
        legend=error_legend(),
    )


def cell_class(cell: Mapping) -> str:
    """``na`` for a model the extreme does not apply to, else ``met`` or ``failed`` (as
    documented or not), with ``unmeasured`` when it has no error to colour by."""
    if cell.get("status") == "n/a":
        return "na"
    css = "met" if cell.get("outcome_met") else "failed"
    return css if cell.get("status") == "ok" else css + " unmeasured"


def cell_style(cell: Mapping) -> str:
    """The inline style of a measured cell: its colour by error (empty for the others)."""
    error = cell.get("error")
    if cell.get("status") != "ok" or not isinstance(error, int | float) or error != error:
        return ""
    background, ink = _colour(float(error))
    return f"background:{background};color:{ink}"


def cell_mark(cell: Mapping) -> str:
    """The expectation as a mark: ``≤ b`` (an upper bound: expected to work), ``◆ a–b`` (a
    band: a documented weakness), or the expected status; a cross first when not met."""
    short = str(cell.get("expected_short") or cell.get("expected") or "")
    mark = ("◆ " + short.replace("..", "–")) if ".." in short else short.replace("<=", "≤")
    return ("✗ " if not cell.get("outcome_met") else "") + mark


def fmt_cell(cell: Mapping) -> str:
    """The error of a measured cell, else its status."""
    if cell.get("status") == "ok":
        return fmt_number(cell.get("error"))
    return str(cell.get("status"))


def fmt_cell_tip(cell: Mapping) -> str:
    """The tooltip of a cell: the measured numbers, its expectation, the reason and any
    message."""
    tip = f"{cell.get('technique')} x {cell.get('extreme')}: "
    if cell.get("status") == "ok":
        tip += f"{cell.get('metric') or 'error'} = {fmt_number(cell.get('error'))}"
    else:
        tip += str(cell.get("status"))
    tip += "; as documented" if cell.get("outcome_met") else "; NOT as documented"
    tip += f"; expected: {cell.get('expected')}; {cell.get('reason') or ''}"
    if cell.get("message"):
        tip += f"; {cell['message']}"
    return tip
