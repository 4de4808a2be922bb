"""ColorVideoVDP's JOD of a tone-mapped sequence (:func:`oracle.scoring.temporal.add_video_score`),
after the temporal pass, on the channel kinds the catalogue declares ``cvvdp_jod`` for."""

from __future__ import annotations

from .... import metrics as M
from . import temporal

NAME = "video"


def applies(request) -> bool:
    return temporal.applies(request) and request.kind in M.CATALOG["cvvdp_jod"].kinds


def run(ctx) -> None:
    from ..temporal import add_video_score

    request = ctx.request
    o = request.options
    values, ctx.sections["temporal_aa"]["video"] = add_video_score(
        ctx.result,
        exposure=ctx.exposure,
        ppd=o.ppd,
        gate_frames=o.gate_frames,
        exact_frames=ctx.exact_frames,
        quiet=o.quiet,
    )
    ctx.summary.update(values)
