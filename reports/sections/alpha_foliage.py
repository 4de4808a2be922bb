"""The alpha-tested foliage section: coverage kept against distance by each shipped alpha
rule (plain test with box and NVTT mips, three.js and Filament alpha-to-coverage, hashed
alpha) on ``alpha-foliage``, and each rule's silhouette shift.

Data in (the record of :func:`oracle.studies.alpha_coverage.alpha_report`), section record
out; ``templates/section_alpha_foliage.html`` renders it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ._record import section_record

__all__ = ["alpha_foliage_section", "kept_series"]


def kept_series(data: Mapping) -> list[dict]:
    """One plotted line a rule: x = each band's geometric mid distance (m), y = coverage kept
    (the rule's over the truth's); bands without a value are left out."""
    mids = [math.sqrt(lo * hi) for lo, hi in data["bands"]]
    series = []
    for name, kept in data["kept"].items():
        xy = [(x, y) for x, y in zip(mids, kept, strict=True) if y is not None]
        series.append({"name": name, "x": [x for x, _ in xy], "y": [y for _, y in xy]})
    return series


def alpha_foliage_section(
    data: Mapping, *, section_id: str = "alpha-foliage", title: str = "Alpha-tested foliage"
) -> dict:
    """The section record: the data and the plotted ``series`` (:func:`kept_series`)."""
    return section_record(
        "alpha_foliage",
        section_id=section_id,
        title=title,
        data=data,
        series=kept_series(data),
    )
