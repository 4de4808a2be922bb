"""The temporal metrics' noise floors of a sequence (``flicker``, ``temporal_error``) from
every frame's second reference, and the exact surrogate frames the temporal pass judges its
own floors with (:func:`oracle.scoring.floors.temporal_floor`)."""

from __future__ import annotations

from ..floors import noise_settings, temporal_floor

NAME = "temporal floor"


def applies(request) -> bool:
    return request.sequence


def run(ctx) -> None:
    request = ctx.request
    floor = dict(ctx.floor or {})
    found, ctx.exact_frames = temporal_floor(
        ctx.result,
        request.frame_scenes,
        noise_settings(request),
        request.channel,
        cache=request.cache,
        quiet=request.options.quiet,
    )
    floor.update(found)
    ctx.result.frames[0].noise_floor = floor
