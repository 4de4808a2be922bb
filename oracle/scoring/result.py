"""What ``score`` computes: the result (the ``metrics.json`` record and the images behind
it), the record's summary over frames, and the metric-limit parser of gates."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ... import metrics as M
from ...scenes.backend import provenance
from ..errors import InputError
from .channels import METRIC_KEYS, REFERENCE_GROUPS

__all__ = [
    "SECTIONS",
    "FrameScore",
    "ScoreError",
    "ScoreResult",
    "build_record",
    "metric_limit",
    "summarise",
    "tone_record",
]


class ScoreError(InputError):
    """Bad scoring request (unknown channel, bad threshold, ...)."""


@dataclass
class FrameScore:
    metrics: dict
    noise_floor: dict | None
    maps: dict
    reference: np.ndarray
    candidate: np.ndarray
    receivers: np.ndarray | None


@dataclass
class ScoreResult:
    """What ``score`` computed: the metrics record and the images behind it."""

    record: dict
    frames: list[FrameScore] = field(default_factory=list)
    reference_folders: list[Path] = field(default_factory=list)
    #: wall seconds by pass (:class:`oracle.phases.Phases`; None: not timed)
    phases: object = None
    #: the notes the passes made for the verdict (diagnoses, conformance, receivers)
    notes: list = field(default_factory=list)


def summarise(result, *, temporal: bool, gate_frames: int | None = None) -> dict:
    """Per-frame metrics averaged over the frames (the last ``gate_frames`` only, when
    given: warm-up does not pass or fail a gate), and the temporal metrics of the path."""
    per_frame = [f.metrics for f in result.frames][-(gate_frames or len(result.frames)) :]
    summary = {}
    for key in METRIC_KEYS:
        vals = [m[key] for m in per_frame if m.get(key) is not None]
        summary[key] = float(np.mean(vals)) if vals else None
    if temporal:
        refs = np.stack([f.reference for f in result.frames])
        cands = np.stack([f.candidate for f in result.frames])
        summary["flicker"] = M.added_flicker(refs, cands)
        summary["temporal_error"] = M.temporal_error(refs, cands)
    return summary


def tone_record(channel, exposure, flip_mode, flip_range) -> dict | None:
    """The record's ``tone_mapping`` (colour only)."""
    if channel != "color":
        return None
    return {
        "exposure_stops": exposure,
        "tone_mapper": "aces",
        "flip_mode": flip_mode,
        "flip_exposure_range": list(flip_range) if flip_range else None,
    }


#: The record's sections after its reference, in this order when present (a pass's
#: section not named here follows them, in the order the passes ran).
SECTIONS = (
    "outside_receivers",
    "candidate_info",
    "gate_frames",
    "temporal_aa",
    "wall_seconds",
    "coverage_reference",
)


def build_record(ctx) -> dict:
    """The ``metrics.json`` record of a score (before thresholds and the candidate's cost),
    built once from what the frames and the passes of ``ctx``
    (:class:`oracle.scoring.passes.context.ScoreContext`) computed."""
    request = ctx.request
    o = request.options
    loaded = request.loaded
    ref_meta = ctx.references[0][0].meta
    frames = ctx.result.frames
    record = {
        "schema": "raster-oracle/metrics/1",
        "channel": request.channel,
        # this run's backend, device and self-check (a model ran here; the reference's
        # own are under "reference")
        "provenance": provenance(),
        **ctx.summary,
        "noise_floor": frames[0].noise_floor,
        "frames": [f.metrics for f in frames] if o.frames else None,
        "camera_path": o.camera_path if o.frames else None,
        "light_path": loaded.light_path,
        "tone_mapping": tone_record(request.channel, ctx.exposure, o.flip_mode, ctx.flip_range),
        "ppd": o.ppd,
        "reference": {
            # the cached reference may have been rendered from another file of the same content
            # (an export copied into CI's folder): the scene is named as this run loaded it
            "scene": {**ref_meta["scene"], "name": loaded.name, "source": loaded.source},
            "spp": o.spp,
            "seed": o.seed,
            "noise_floor_seed": o.seed + 1,
            "channels": list(REFERENCE_GROUPS[request.channel]),
            "variant": ref_meta["variant"],
            # the machine that rendered the reference and its self-check (older cache
            # entries have neither)
            "device": ref_meta.get("device"),
            "self_check": ref_meta.get("self_check"),
            "versions": ref_meta["versions"],
            "cache_key": ref_meta["cache_key"],
            "filter": ref_meta["filter"],
        },
    }
    if ctx.coverage_truth is not None:
        # which truth the coverage metrics used: exact (noise floor 0 there) or Monte Carlo
        record["reference"]["coverage_truth"] = ctx.coverage_truth
    sections = dict(ctx.sections)
    sections.update(candidate_info=ctx.infos, gate_frames=o.gate_frames)
    sections.setdefault("temporal_aa", None)
    sections["wall_seconds"] = time.perf_counter() - ctx.started
    for name in SECTIONS:
        if name in sections:
            record[name] = sections.pop(name)
    record.update(sections)
    return record


def metric_limit(
    text: str, *, separator: str, option: str, error: type[Exception] = ScoreError
) -> tuple[str, float]:
    """``"flip_mean<sep>0.1"`` -> ``("flip_mean", 0.1)``: a metric key and a finite limit.

    Raises ``error`` with a message naming ``option`` (the command-line option) for a missing
    separator, an unknown metric (listing the valid ones) or a value that is not a finite
    number.
    """
    metric, sep, value = str(text).partition(separator)
    metric, value = metric.strip(), value.strip()
    if not sep:
        raise error(f"{option} expects METRIC{separator}VALUE, got {text!r}")
    if metric not in M.CATALOG:
        raise error(f"{option}: unknown metric {metric!r}; choose from {', '.join(M.CATALOG)}")
    try:
        limit = float(value)
    except ValueError:
        raise error(f"{option} {metric}: expected a number, got {value!r}") from None
    if not math.isfinite(limit):
        raise error(f"{option} {metric}: expected a finite number, got {value!r}")
    return metric, limit
