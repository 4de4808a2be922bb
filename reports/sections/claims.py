"""The claims section: each headline claim of the seeds, its source, the measured value with
error bars and the verdict.

Data in (the record of :func:`oracle.studies.claims.run.run_claims`), section record out;
``templates/section_claims.html`` renders it (autoescaped).
"""

from __future__ import annotations

import json
from collections.abc import Mapping

from ..formatting import fmt_number, fmt_summary
from ._record import section_record

__all__ = ["claims_section", "fmt_extra", "verdict_class"]

_VERDICT_CLASS = {"reproduced": "ok", "partly": "part", "not reproduced": "bad"}


def claims_section(data: Mapping, *, section_id: str = "claims", title: str = "Claims") -> dict:
    """The section record of a claims run (its rows are shown as measured; no view)."""
    return section_record("claims", section_id=section_id, title=title, data=data)


def verdict_class(verdict: object) -> str:
    """CSS class of a verdict cell: ``ok``, ``part``, ``bad`` or ``na`` (not measured)."""
    return _VERDICT_CLASS.get(str(verdict), "na")


def fmt_extra(value: object) -> str:
    """One value of a claim's ``extra`` record: a summary, a number, or its JSON."""
    if isinstance(value, Mapping) and "mean" in value:
        return fmt_summary(value)
    if isinstance(value, float | int) and not isinstance(value, bool):
        return fmt_number(value)
    return json.dumps(value, default=str)
