"""The soft-shadow section: PCSS at the engines' presets ranked against fixed-width PCF on the
area-light truth, PCSS's contact hardening, and the light bleeding of VSM, EVSM and MSM.

Data in (the record of :func:`oracle.studies.soft_shadows.soft_report`), section record out;
``templates/section_soft_shadows.html`` renders it.
"""

from __future__ import annotations

from collections.abc import Mapping

from ._record import section_record

__all__ = ["bleeding_table", "soft_shadows_section"]


def bleeding_table(data: Mapping) -> list[dict]:
    """Rows ``{"scene", "blur", "cells": {filter: row}}`` of the bleeding record, one per
    (scene, blur), the filters in the record's order."""
    table: dict = {}
    for row in data["bleeding"]["rows"]:
        key = (row["scene"], row["blur"])
        table.setdefault(key, {"scene": row["scene"], "blur": row["blur"], "cells": {}})
        table[key]["cells"][row["filter"]] = row
    return list(table.values())


def soft_shadows_section(
    data: Mapping, *, section_id: str = "soft-shadows", title: str = "Soft shadows"
) -> dict:
    """The section record: the data, the bleeding table by (scene, blur) and its filters."""
    filters = []
    for row in data["bleeding"]["rows"]:
        if row["filter"] not in filters:
            filters.append(row["filter"])
    return section_record(
        "soft_shadows",
        section_id=section_id,
        title=title,
        data=data,
        bleeding=bleeding_table(data),
        filters=filters,
    )
