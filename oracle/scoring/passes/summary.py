"""The record's metric values: per-frame metrics averaged (over the last ``gate_frames``
when given) and, for a sequence, ``flicker`` and ``temporal_error``
(:func:`oracle.scoring.result.summarise`). Every score gets it."""

from __future__ import annotations

from ..result import summarise

NAME = "summary"


def applies(request) -> bool:
    return True


def run(ctx) -> None:
    request = ctx.request
    ctx.summary = summarise(
        ctx.result, temporal=request.sequence, gate_frames=request.options.gate_frames
    )
