"""The anti-aliasing ranking section: per scene, SMAA's presets and modes beside no AA, FXAA,
MSAA and SSAA, ranked by coverage edge error with the noise floors.

Data in (the record of :func:`oracle.studies.aa_ranking.aa_ranking`), section record out;
``templates/section_aa_ranking.html`` renders it.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..formatting import fmt_number
from ._record import section_record

__all__ = ["aa_ranking_section", "fmt_with_floor"]


def aa_ranking_section(
    data: Mapping,
    *,
    section_id: str = "aa-ranking",
    title: str = "Anti-aliasing ranking: SMAA presets and modes",
) -> dict:
    """The section record of the ranking (the data as is: its tables are the view)."""
    return section_record("aa_ranking", section_id=section_id, title=title, data=data)


def fmt_with_floor(row: Mapping, metric: str) -> str:
    """``"0.1911 (floor 0.004)"``: a row's value of ``metric`` and its noise floor."""
    value = fmt_number(row["metrics"].get(metric))
    floor = row["floors"].get(metric)
    return value if floor is None else f"{value} (floor {fmt_number(floor)})"
