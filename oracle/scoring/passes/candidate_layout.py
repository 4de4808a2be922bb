"""What was read from an engine's files, and as what (``candidate_layout``)."""

from __future__ import annotations

NAME = "candidate layout"


def applies(request) -> bool:
    return request.is_file


def run(ctx) -> None:
    ctx.sections["candidate_layout"] = ctx.request.candidate.layout_record()
