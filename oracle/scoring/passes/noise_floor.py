"""The noise floor of frame 0: what an exact candidate scores on every metric
(:func:`oracle.scoring.floors.noise_floor`). Every score gets it."""

from __future__ import annotations

from ..floors import noise_floor, noise_settings

NAME = "noise floor"


def applies(request) -> bool:
    return True


def run(ctx) -> None:
    request = ctx.request
    o = request.options
    ref, ref_ch = ctx.references[0]
    frame = ctx.result.frames[0]
    frame.noise_floor = noise_floor(
        request.frame_scenes[0],
        ref,
        ref_ch,
        frame.reference,
        channel=request.channel,
        settings=noise_settings(request),
        kw=ctx.kw,
        cache=request.cache,
        quiet=o.quiet,
        floor_cache=request.floor_cache,
    )
