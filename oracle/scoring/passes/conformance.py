"""Conformance to the technique an engine claims (``score --expect``): the claimed model run
on every frame, and the candidate judged against it (:mod:`oracle.scoring.conformance`)."""

from __future__ import annotations

from ..conformance import add_conformance

NAME = "conformance"


def applies(request) -> bool:
    return request.is_file and request.options.expect is not None


def run(ctx) -> None:
    request = ctx.request
    o = request.options
    ctx.notes["conformance"] = add_conformance(
        ctx.result,
        request.frame_scenes,
        o.expect,
        kind=request.channel,
        ppd=o.ppd,
        exposure=ctx.exposure,
        into=ctx.sections,
        gate_frames=o.gate_frames,
    )
