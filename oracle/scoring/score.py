"""Score a technique model or an engine's image against the reference.

The candidate's channel decides which metrics apply and which reference channels are
rendered (:mod:`oracle.scoring.channels`). Every metric is also computed for a second,
independently seeded reference of the same spp against the first: its noise floor
(:mod:`oracle.scoring.floors`). With ``frames`` the camera path is scored frame by frame
(per-frame metrics averaged, each frame's kept in ``frames``) and the temporal metrics are
added: ``flicker`` (:func:`metrics.temporal.added_flicker`, non-negative) and
``temporal_error``, with noise floors from every frame's second reference. The temporal
anti-aliasing pass and the engine teams' gate pass run where the metric catalogue declares
their metrics for the scored channel's kind (:mod:`metrics.catalog`).

:func:`score` scores the frames, runs the passes the plan picks for the request
(:mod:`oracle.scoring.passes.plan`: noise floors, temporal metrics, engine gates, receivers,
coverage, steady-state yardstick) and builds the record once, last
(:func:`oracle.scoring.result.build_record`).
"""

from __future__ import annotations

from ... import metrics as M
from ...metrics.aliasing import COVERAGE_FLOOR_RMS, COVERAGE_KEYS, coverage_metrics
from ...metrics.temporal import added_flicker
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from .channels import (
    COVERAGE_CHANNELS,
    METRIC_KEYS,
    REFERENCE_GROUPS,
    coverage_truth,
    metrics_for,
    reference_receivers,
    rgb,
)
from .engine_metrics import frame_stderr
from .passes import engine_gates
from .passes.context import ScoreContext
from .passes.plan import plan
from .request import ScoreRequest
from .result import FrameScore, ScoreError, ScoreResult, build_record, metric_limit

__all__ = [
    "COVERAGE_FLOOR_RMS",
    "COVERAGE_KEYS",
    "METRIC_KEYS",
    "REFERENCE_GROUPS",
    "ScoreError",
    "ScoreRequest",
    "ScoreResult",
    "added_flicker",
    "coverage_metrics",
    "coverage_truth",
    "metric_limit",
    "reference_receivers",
    "score",
]


def _frame_keywords(ctx: ScoreContext, frame_scene, ref_ch) -> dict:
    """The keywords of :func:`metrics_for` for one frame (colour: the tone mapping of frame
    0's reference, kept for every frame)."""
    request = ctx.request
    o = request.options
    if ctx.exposure is None and request.channel == "color":
        ref_rgb = rgb(ref_ch, "color")
        ctx.exposure = M.exposure_from_reference(ref_rgb)
        if o.flip_mode == "HDR":
            ctx.flip_range = M.hdr_exposure_range(ref_rgb)
    return dict(
        light=frame_scene.light,
        exposure=ctx.exposure,
        flip_mode=o.flip_mode,
        flip_range=ctx.flip_range,
        ppd=o.ppd,
        samples=o.spp,
        aa_samples=request.aa_samples,
        coverage_only=request.coverage_only and request.channel in COVERAGE_CHANNELS,
        depth_buffer=o.depth_buffer,
    )


def score_frames(ctx: ScoreContext) -> None:
    """Score every frame into ``ctx.result.frames``: its reference, its candidate, the
    channel's metrics and error maps; frame 0's reference (metadata, channels, coverage
    truth) and metric keywords are kept for the passes."""
    request = ctx.request
    o = request.options
    settings = ReferenceSettings(
        spp=o.spp, seed=o.seed, channels=request.groups, exact_budget=o.exact_budget
    ).validate()
    read = request.candidate_frames()
    for k, frame_scene in enumerate(request.frame_scenes):
        ref = get_reference(frame_scene, settings, cache=request.cache, quiet=o.quiet)
        ref_ch = ref.channels()
        cand, info = read(frame_scene, k)
        ctx.engine_motion.append((info.pop("motion", None), info.pop("disocclusion", None)))
        ctx.infos.append(info)
        kw = _frame_keywords(ctx, frame_scene, ref_ch)
        values, maps, ref_img, rec = metrics_for(request.channel, ref_ch, cand, full=True, **kw)
        if k == 0:
            ctx.kw = kw
            ctx.references.append((ref, ref_ch))
            if request.channel in COVERAGE_CHANNELS:
                ctx.coverage_truth = coverage_truth(ref_ch, request.channel)[2]
        else:
            ctx.references.append((ref, None))
        if engine_gates.applies(request):
            ctx.stderrs.append(frame_stderr(ref_ch, request.channel))
        ctx.result.frames.append(FrameScore(values, None, maps, ref_img, cand, rec))
        ctx.result.reference_folders.append(ref.folder)


def score(request: ScoreRequest) -> ScoreResult:
    """Score ``request``'s candidate frames against references of its scene.

    The frames first (each against its own reference), then the passes the plan picks for
    the request (:func:`oracle.scoring.passes.plan.plan`), then the record, built once
    (:func:`oracle.scoring.result.build_record`). A sequence (``frames`` >= 2) gets the
    temporal metrics; a candidate whose ``info`` carries ``"motion"`` (its motion vectors,
    ``(H, W, 2)`` in the oracle's convention) and optionally ``"disocclusion"`` gets their
    end-point error (the arrays leave ``info`` before it is recorded).
    """
    request = request.check()
    ctx = ScoreContext(request, rescore=score)
    with ctx.phases.phase("frames"):
        score_frames(ctx)
    for step in plan(request):
        with ctx.phases.phase(step.NAME):
            step.run(ctx)
    ctx.result.record = build_record(ctx)
    ctx.result.phases = ctx.phases
    ctx.result.notes = ctx.note_lines()
    return ctx.result
