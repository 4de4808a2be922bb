"""The anti-aliasing memory section: framebuffer bytes per technique at 1280x736 and 1080p
from the models' own accounting, set against every figure the seed slides and papers quote.

Data in (the record of :func:`oracle.studies.aa_memory.memory_report`), section record out;
``templates/section_aa_memory.html`` renders it.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..formatting import fmt_mb, fmt_number
from ._record import section_record

__all__ = ["BUFFERS", "aa_memory_section", "fmt_computed", "fmt_note", "fmt_quoted"]

#: Columns of the bytes-per-pixel table, in order.
BUFFERS = ("color", "depth", "normal", "aggregates", "resolve", "total")


def aa_memory_section(
    data: Mapping, *, section_id: str = "aa-memory", title: str = "Anti-aliasing memory"
) -> dict:
    """The section record of the memory table: the data, the ``buffers`` columns and the
    ``resolutions`` as ``"WxH"`` labels (keys of each row's ``at``)."""
    return section_record(
        "aa_memory",
        section_id=section_id,
        title=title,
        data=data,
        buffers=list(BUFFERS),
        resolutions=[f"{w}x{h}" for w, h in data["resolutions"]],
    )


def fmt_quoted(quote: Mapping) -> str:
    """A quoted figure: ``"41 MB"`` for bytes, the bare number for ratios."""
    if quote["kind"] == "bytes":
        return f"{fmt_number(quote['quoted'])} MB"
    return f"{quote['quoted']:g}"


def fmt_computed(quote: Mapping) -> str:
    """What the models' accounting gives for a quoted figure (MB and MiB, with and without
    the resolve target), or the computed ratio."""
    c = quote.get("computed")
    if c is None:
        return "—"
    if isinstance(c, Mapping):
        return (
            f"{fmt_mb(c['total_MB'])} MB ({fmt_mb(c['framebuffer_MB'])} without the resolve "
            f"target); {fmt_mb(c['total_MiB'])} MiB ({fmt_mb(c['framebuffer_MiB'])})"
        )
    return f"{c:.3f}"


def fmt_note(quote: Mapping) -> str:
    """The note of a quoted figure, with the ratio of the quoted figures themselves."""
    note = quote.get("note") or ""
    if "from_quotes" in quote:
        agree = "consistent" if quote["consistent_with_quotes"] else "inconsistent"
        note += f" (from the quoted figures themselves: {quote['from_quotes']:.3f}, {agree})"
    return note.strip()
