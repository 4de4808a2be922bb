"""The numerical-extremes section: a matrix of models x extremes.

Data in (the record of :func:`oracle.studies.extremes.run.run_extremes`), section record out;
``templates/section_extremes.html`` renders it. A cell shows the model's error against the
oracle (or n/a, refused, non-finite, error), green when the measured outcome matches the
documented expectation and red when it does not; the expectation and its reason are in the
cell's tooltip and in the list below the matrix.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..formatting import fmt_number
from ._record import section_record

__all__ = ["cell_class", "extremes_section", "fmt_cell", "fmt_cell_tip"]

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
    )


def cell_class(cell: Mapping) -> str:
    """``na`` for a model the extreme does not apply to, else ``ok`` or ``bad`` (as
    documented or not)."""
    if cell.get("status") == "n/a":
        return "na"
    return "ok" if cell.get("outcome_met") else "bad"


def fmt_cell(cell: Mapping) -> str:
    """The error of a measured cell, else its status."""
    if cell.get("status") == "ok":
        return fmt_number(cell.get("error"))
    return str(cell.get("status"))


def fmt_cell_tip(cell: Mapping) -> str:
    """The tooltip of a cell: its expectation, the reason and any message."""
    tip = f"expected: {cell.get('expected')}; {cell.get('reason') or ''}"
    if cell.get("message"):
        tip += f"; {cell['message']}"
    return tip
