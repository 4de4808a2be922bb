"""The temporal metrics of a sequence, each frame against its own truth: convergence and
steady level, ghosting, lag, history error, flicker ratio and the motion vectors' end-point
error (:func:`oracle.scoring.temporal.add_temporal_aa`).

It runs on a sequence whose channel kind the metric catalogue declares them for (colour: a
TAA, or the baselines scored beside it), and on every sequence of a temporal family, whatever
its channels (a denoised ray-traced shadow judged over frames)."""

from __future__ import annotations

from .... import metrics as M
from ..temporal import TEMPORAL_AA_KEYS, add_temporal_aa

NAME = "temporal"


def applies(request) -> bool:
    if not request.sequence:
        return False
    temporal_family = request.family is not None and request.family.temporal
    return temporal_family or any(request.kind in M.CATALOG[k].kinds for k in TEMPORAL_AA_KEYS)


def run(ctx) -> None:
    request = ctx.request
    o = request.options
    values, ctx.sections["temporal_aa"] = add_temporal_aa(
        ctx.result,
        request.frame_scenes,
        seed=o.seed,
        cache=request.cache,
        quiet=o.quiet,
        gate_frames=o.gate_frames,
        engine_motion=ctx.engine_motion,
        exact_frames=ctx.exact_frames,
    )
    ctx.summary.update(values)
