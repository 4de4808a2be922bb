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

The record itself is built in :mod:`oracle.scoring.result`.
"""

from __future__ import annotations

import time

from ... import metrics as M
from ...metrics.aliasing import COVERAGE_FLOOR_RMS, COVERAGE_KEYS, coverage_metrics
from ...metrics.temporal import added_flicker
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from .channels import (
    CHANNEL_KIND,
    COVERAGE_CHANNELS,
    METRIC_KEYS,
    REFERENCE_GROUPS,
    coverage_truth,
    metrics_for,
    reference_receivers,
    rgb,
)
from .floors import engine_records, noise_floor, temporal_floor
from .result import (
    FrameScore,
    ScoreError,
    ScoreResult,
    build_record,
    metric_limit,
    summarise,
    tone_record,
)
from .temporal import TEMPORAL_AA_KEYS, add_temporal_aa

__all__ = [
    "COVERAGE_FLOOR_RMS",
    "COVERAGE_KEYS",
    "METRIC_KEYS",
    "REFERENCE_GROUPS",
    "ScoreError",
    "ScoreResult",
    "added_flicker",
    "applies",
    "coverage_metrics",
    "coverage_truth",
    "metric_limit",
    "reference_receivers",
    "score",
]


def applies(keys, channel: str) -> bool:
    """True when the metric catalogue declares one of ``keys`` for ``channel``'s kind."""
    kind = CHANNEL_KIND[channel]
    return any(kind in M.CATALOG[k].kinds for k in keys)


def _check_request(channel, flip_mode, gate_frames, frames) -> str:
    if gate_frames is not None and not 1 <= int(gate_frames) <= (frames or 1):
        raise ScoreError(f"--gate-frames must be in [1, {frames or 1}], got {gate_frames}")
    if channel not in REFERENCE_GROUPS:
        raise ScoreError(f"channel must be one of {', '.join(REFERENCE_GROUPS)}, got {channel!r}")
    flip_mode = flip_mode.upper()
    if flip_mode not in ("LDR", "HDR"):
        raise ScoreError(f"flip mode must be LDR or HDR, got {flip_mode!r}")
    return flip_mode


def _score_frames(loaded, result, *, channel, candidate_frames, frames, camera_path, opts):
    """Score every frame into ``result.frames`` (frame 0 with its noise floor); returns the
    frame scenes, the candidates' infos and motion, the tone-mapping record's inputs and
    frame 0's reference metadata and coverage truth."""
    n = frames or 1
    settings = ReferenceSettings(
        spp=opts["spp"], seed=opts["seed"], channels=opts["groups"], exact_budget=opts["budget"]
    ).validate()
    st = dict(exposure=None, flip_range=None, infos=[], engine=[], scenes=[], truth=None)
    for k in range(n):
        frame_scene = loaded.with_frame(k, path=camera_path, n_frames=n) if frames else loaded
        st["scenes"].append(frame_scene)
        ref = get_reference(frame_scene, settings, cache=opts["cache"], quiet=opts["quiet"])
        ref_ch = ref.channels()
        cand, info = candidate_frames(frame_scene, k)
        st["engine"].append((info.pop("motion", None), info.pop("disocclusion", None)))
        st["infos"].append(info)
        if k == 0 and channel == "color":
            ref_rgb = rgb(ref_ch, "color")
            st["exposure"] = M.exposure_from_reference(ref_rgb)
            if opts["flip_mode"] == "HDR":
                st["flip_range"] = M.hdr_exposure_range(ref_rgb)
        kw = dict(
            light=frame_scene.light,
            exposure=st["exposure"],
            flip_mode=opts["flip_mode"],
            flip_range=st["flip_range"],
            ppd=opts["ppd"],
            samples=opts["spp"],
            aa_samples=opts["aa_samples"],
            coverage_only=opts["coverage_only"] and channel in COVERAGE_CHANNELS,
        )
        values, maps, ref_img, rec = metrics_for(channel, ref_ch, cand, full=True, **kw)
        floor = None
        if k == 0:
            st["ref_meta"] = ref.meta
            if channel in COVERAGE_CHANNELS:
                st["truth"] = coverage_truth(ref_ch, channel)[2]
            floor = noise_floor(
                frame_scene,
                ref,
                ref_ch,
                ref_img,
                channel=channel,
                settings=opts["noise_settings"],
                kw=kw,
                cache=opts["cache"],
                quiet=opts["quiet"],
                floor_cache=opts["floor_cache"],
            )
        result.frames.append(FrameScore(values, floor, maps, ref_img, cand, rec))
        result.reference_folders.append(ref.folder)
    return st


def score(
    loaded,
    *,
    channel: str,
    candidate_frames,
    spp: int = 64,
    seed: int = 0,
    frames: int | None = None,
    camera_path: str = "dolly",
    cache=None,
    quiet: bool = True,
    flip_mode: str = "LDR",
    ppd: float = M.DEFAULT_PPD,
    aa_samples: int | None = None,
    floor_cache: dict | None = None,
    coverage_only: bool = False,
    gate_frames: int | None = None,
    exact_budget: float | None = None,
) -> ScoreResult:
    """Score candidate frames against references of ``loaded``.

    Parameters
    ----------
    channel : ``"visibility"``, ``"color"``, ``"coverage"`` or ``"front_coverage"``.
    candidate_frames : callable ``(frame_scene, k) -> (image, info)`` giving the candidate of
        frame ``k`` (a model run, or an image file read and validated) and a plain record
        (cost, diagnostics, file name) for the report.
    frames : score ``frames`` frames of ``camera_path`` (None: the scene's own camera only).
    aa_samples : samples per pixel of an anti-aliasing technique: picks the straight-edge
        coverage floor ``coverage_floor_rms`` (None: no floor).
    floor_cache : a dict shared between calls (a sweep worker's): the noise floor depends on
        the references and scoring options only, so it is computed once per reference.
    coverage_only : a coverage channel whose coverage metrics alone are kept (an AA model's
        ``front_coverage`` beside its colour): no FLIP, SSIM or PSNR of it.
    gate_frames : average the per-frame metrics over the last ``gate_frames`` frames only
        (None: all), and judge convergence against their level.

    A sequence (``frames`` >= 2) of a kind the temporal AA metrics apply to (colour) also
    gets them (:mod:`oracle.scoring.temporal`); a candidate whose ``info`` carries
    ``"motion"`` (its motion vectors, ``(H, W, 2)`` in the oracle's convention) and
    optionally ``"disocclusion"`` gets their end-point error (the arrays leave ``info``
    before it is recorded).
    """
    flip_mode = _check_request(channel, flip_mode, gate_frames, frames)
    t0 = time.perf_counter()
    groups = REFERENCE_GROUPS[channel]
    opts = dict(spp=spp, seed=seed, groups=groups, cache=cache, quiet=quiet, ppd=ppd)
    opts.update(flip_mode=flip_mode, aa_samples=aa_samples, coverage_only=coverage_only)
    opts.update(floor_cache=floor_cache, budget=exact_budget)
    noise = ReferenceSettings(
        spp=spp, seed=seed + 1, channels=groups, exact_budget=exact_budget
    ).validate()
    opts["noise_settings"] = noise
    result = ScoreResult(record={})
    st = _score_frames(
        loaded,
        result,
        channel=channel,
        candidate_frames=candidate_frames,
        frames=frames,
        camera_path=camera_path,
        opts=opts,
    )
    sequence = bool(frames) and len(result.frames) >= 2
    exact_frames = None
    if sequence:
        floor = dict(result.frames[0].noise_floor or {})
        tf, exact_frames = temporal_floor(
            result, st["scenes"], noise, channel, cache=cache, quiet=quiet
        )
        floor.update(tf)
        result.frames[0].noise_floor = floor
    tone = tone_record(channel, st["exposure"], flip_mode, st["flip_range"])
    summary = summarise(result, temporal=sequence, gate_frames=gate_frames)
    taa_detail = None
    if sequence and applies(TEMPORAL_AA_KEYS, channel):
        taa, taa_detail = add_temporal_aa(
            result,
            st["scenes"],
            seed=seed,
            cache=cache,
            quiet=quiet,
            gate_frames=gate_frames,
            engine_motion=st["engine"],
            exact_frames=exact_frames,
            display=(st["exposure"], ppd),
        )
        summary.update(taa)
    result.record = build_record(
        result,
        loaded,
        st["ref_meta"],
        channel=channel,
        summary=summary,
        frames=frames,
        camera_path=camera_path,
        tone=tone,
        ppd=ppd,
        spp=spp,
        seed=seed,
    )
    engine_records(result, channel=channel, exposure=st["exposure"])
    if st["truth"] is not None:
        # which truth the coverage metrics used: exact (noise floor 0 there) or Monte Carlo
        result.record["reference"]["coverage_truth"] = st["truth"]
    result.record["candidate_info"] = st["infos"]
    result.record["gate_frames"] = gate_frames
    result.record["temporal_aa"] = taa_detail
    result.record["wall_seconds"] = time.perf_counter() - t0
    return result
