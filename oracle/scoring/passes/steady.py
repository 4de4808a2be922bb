"""The yardstick of a temporal family's steady state, named by its family record
(``steady_against``): ``ssaa8`` records, next to the steady error, 8x SSAA's mean absolute
error over the same judged frames against the same references (``temporal_aa``:
``ssaa8_error``, ``steady_over_ssaa8``); ``reference`` needs no yardstick (the steady error is
against the reference already), so the pass does not run."""

from __future__ import annotations

import numpy as np

from .... import raster_models

NAME = "steady yardstick"

#: Yardstick name -> the model run on each judged frame and its parameters.
YARDSTICKS = {"ssaa8": ("ssaa", {"samples": 8})}


def applies(request) -> bool:
    family = request.family
    return (
        request.is_model
        and request.sequence
        and family is not None
        and family.temporal
        and family.steady_against in YARDSTICKS
    )


def _frame_error(ctx, k: int, technique: str, params: dict) -> float:
    """The yardstick's mean absolute error on frame ``k`` against that frame's reference.

    It depends on the frame's scene and reference alone, both named by the reference's
    content-addressed folder, so a worker keeps it (``floor_cache``) for every case of a
    sequence judged against the same references (the TAA presets of the main job)."""
    request = ctx.request
    memo = request.floor_cache
    folders = ctx.result.reference_folders
    key = None
    if memo is not None and k < len(folders) and folders[k] is not None:
        key = ("steady yardstick", str(folders[k]), request.channel, technique)
        key += (tuple(sorted(params.items())),)
        if key in memo:
            return memo[key]
    out = raster_models.run(technique, request.frame_scenes[k], **params).outputs
    channel = np.asarray(out[request.channel])
    error = float(np.abs(channel - ctx.result.frames[k].reference).mean())
    if key is not None:
        memo[key] = error
    return error


def run(ctx) -> None:
    request = ctx.request
    detail = ctx.sections.get("temporal_aa")
    if detail is None:
        return
    name = request.family.steady_against
    technique, params = YARDSTICKS[name]
    frames = request.options.frames
    n = int(request.options.gate_frames or frames)
    errors = [_frame_error(ctx, k, technique, params) for k in range(frames - n, frames)]
    error = float(np.mean(errors))
    detail[f"{name}_error"] = error
    steady = ctx.summary.get("steady_error")
    detail[f"steady_over_{name}"] = steady / error if error else None
