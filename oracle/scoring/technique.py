"""Score a technique model: run it on each frame's scene and score what it produces.

Shadow techniques are scored on visibility; anti-aliasing techniques on colour, with the
coverage metrics (against the straight-edge floor of their sample count) merged in. The model
runs once per frame whatever the number of channels scored.

Every colour candidate is linear radiance that scoring tone-maps with the reference's
exposure and the ACES curve (``tone_mapping`` in ``metrics.json``), the reference alike.
FXAA works in display space (:mod:`raster_models.aa.fxaa`): its ``color`` is the radiance the
same pipeline maps to its LDR sRGB output, so its blends are scored as displayed.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ... import raster_models
from ...metrics.aliasing import COVERAGE_KEYS
from .result import ScoreError, ScoreResult
from .score import score

__all__ = ["model_candidate", "score_model", "technique_channels"]


def technique_channels(technique: str) -> tuple[str, ...]:
    """The channels a registered technique's model produces and is scored on (first: the
    primary one; its family record's ``channels``). Raises ``raster_models.ModelError`` for
    an unknown technique."""
    return raster_models.family(technique).channels


def model_candidate(technique: str, params: dict, *, channel: str = "visibility", runs=None):
    """Candidate callable ``(frame_scene, k) -> (image, info)`` running a technique model.

    ``channel`` picks the output scored (``visibility``; ``color`` or ``coverage`` for the
    anti-aliasing family). ``runs``, a dict shared between callables, keeps each frame's
    model result so that scoring colour and coverage runs the model once per frame.
    """
    runs = {} if runs is None else runs

    def run(frame_scene, k):
        if k not in runs:
            runs[k] = raster_models.run(technique, frame_scene, **params)
        res = runs[k]
        info = {
            "frame": k,
            "technique": technique,
            "cost": res.cost,
            "params": res.params,
            "diagnostics": res.diagnostics,
            "model_seconds": res.wall_seconds,
        }
        if channel == "color" and "velocity_x" in res.outputs:
            # a temporal model's own velocity buffer and history rejection, scored as an
            # engine's motion vectors and disocclusion mask (oracle.scoring.temporal)
            info["motion"] = np.stack(
                [res.outputs["velocity_x"], res.outputs["velocity_y"]], -1
            ).astype(np.float64)
            info["disocclusion"] = np.asarray(res.outputs["rejected"]) > 0.5
        return np.asarray(res.outputs[channel], dtype=np.float32), info

    return run


def _sample_count(res) -> int:
    """Samples per pixel of an AA model run: its cost record's ``samples``, else its
    ``samples`` parameter, else 1 (no AA, FXAA: one sample at the pixel centre)."""
    n = res.cost.get("samples", res.params.get("samples", 1))
    return int(n) if isinstance(n, int | np.integer) and not isinstance(n, bool) else 1


def _merge_coverage(result: ScoreResult, coverage: ScoreResult) -> None:
    """Add the coverage metrics, floor and error map of ``coverage`` to the colour result."""
    for key in COVERAGE_KEYS:
        result.record[key] = coverage.record.get(key)
    floor = result.record.get("noise_floor")
    cov_floor = coverage.record.get("noise_floor") or {}
    if floor is not None:
        floor.update({k: v for k, v in cov_floor.items() if k in COVERAGE_KEYS})
    if result.record.get("frames") and coverage.record.get("frames"):
        for mine, theirs in zip(result.record["frames"], coverage.record["frames"], strict=True):
            mine.update({k: theirs.get(k) for k in COVERAGE_KEYS})
    for mine, theirs in zip(result.frames, coverage.frames, strict=True):
        mine.metrics.update({k: theirs.metrics.get(k) for k in COVERAGE_KEYS})
        if "coverage_error" in theirs.maps:
            mine.maps["coverage_error"] = theirs.maps["coverage_error"]
    result.record["coverage_reference"] = coverage.record["reference"]
    result.record["wall_seconds"] += coverage.record["wall_seconds"]


def score_model(
    loaded,
    technique: str,
    params: dict,
    *,
    spp: int,
    seed: int,
    cache,
    quiet: bool,
    channel: str | None = None,
    frames: int | None = None,
    camera_path: str | None = "dolly",
    flip_mode: str = "LDR",
    ppd: float = M.DEFAULT_PPD,
    floor_cache: dict | None = None,
    gate_frames: int | None = None,
    exact_budget: float | None = None,
) -> ScoreResult:
    """Score one technique configuration on ``loaded`` (``raster-oracle score --technique``).

    Parameters
    ----------
    params : the technique's parameters (validated values, e.g. from
        ``raster_models.parse_params``).
    channel : the channel asked for (None: the technique's primary one; an anti-aliasing
        model scores colour with its coverage merged whatever is asked); a channel the
        technique does not produce is a :class:`ScoreError`.
    frames, camera_path, flip_mode, ppd : as in :func:`oracle.scoring.score.score`.
    floor_cache : see :func:`oracle.scoring.score.score` (a sweep worker's noise floors).
    """
    produced = technique_channels(technique)
    cov_channel = raster_models.family(technique).coverage_channel
    if channel is not None and channel not in produced:
        raise ScoreError(
            f"technique {technique} produces {' and '.join(produced)}; "
            f"--channel {channel} does not apply"
        )
    runs: dict = {}
    aa_samples = None
    if cov_channel is not None:
        # run frame 0 first: its full parameter record gives the sample count
        scene0 = loaded.with_frame(0, path=camera_path, n_frames=frames) if frames else loaded
        model_candidate(technique, params, channel=produced[0], runs=runs)(scene0, 0)
        aa_samples = _sample_count(runs[0])
    kw = dict(
        spp=spp,
        seed=seed,
        frames=frames,
        camera_path=camera_path,
        cache=cache,
        quiet=quiet,
        flip_mode=flip_mode,
        ppd=ppd,
        aa_samples=aa_samples,
        floor_cache=floor_cache,
        gate_frames=gate_frames,
        exact_budget=exact_budget,
    )
    # the channel asked for (a soft-shadow model's light_fraction), else the primary one; an
    # AA model always scores colour with its coverage merged in
    primary = channel if channel is not None and cov_channel is None else produced[0]
    result = score(
        loaded,
        channel=primary,
        candidate_frames=model_candidate(technique, params, channel=primary, runs=runs),
        **kw,
    )
    if cov_channel is not None:
        # the coverage metrics of a model: its front-most primitive's coverage against the
        # reference's (oracle.reference.coverage), an edge on every scene, backdrops included
        coverage = score(
            loaded,
            channel=cov_channel,
            candidate_frames=model_candidate(technique, params, channel=cov_channel, runs=runs),
            coverage_only=True,  # only its COVERAGE_KEYS are kept (_merge_coverage)
            **kw,
        )
        _merge_coverage(result, coverage)
    if raster_models.family(technique).temporal and frames and frames >= 2:
        _against_ssaa8(result, loaded, frames=frames, camera_path=camera_path, judged=gate_frames)
    return result


#: The steady level of a temporal technique is compared with this supersampling rate.
STEADY_SSAA_SAMPLES = 8


def _against_ssaa8(result: ScoreResult, loaded, *, frames: int, camera_path, judged) -> None:
    """Record, next to a temporal technique's steady error, 8x SSAA's mean absolute error
    over the same judged frames against the same references (``temporal_aa``:
    ``ssaa8_error`` and ``steady_over_ssaa8``)."""
    detail = result.record.get("temporal_aa")
    if detail is None:
        return
    n = int(judged or frames)
    errors = []
    for k in range(frames - n, frames):
        frame_scene = loaded.with_frame(k, path=camera_path, n_frames=frames)
        ssaa = raster_models.run("ssaa", frame_scene, samples=STEADY_SSAA_SAMPLES)
        ref = result.frames[k].reference
        errors.append(float(np.abs(np.asarray(ssaa.outputs["color"]) - ref).mean()))
    detail["ssaa8_error"] = float(np.mean(errors))
    steady = result.record.get("steady_error")
    detail["steady_over_ssaa8"] = steady / detail["ssaa8_error"] if detail["ssaa8_error"] else None
