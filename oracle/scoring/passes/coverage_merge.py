"""The coverage of an anti-aliasing model scored beside its colour: the family's coverage
channel (its front-most primitive's coverage against the reference's, an edge on every scene)
scored with the same model runs, and its coverage metrics, floors and error map merged in."""

from __future__ import annotations

from ....metrics.aliasing import COVERAGE_KEYS

NAME = "coverage"


def applies(request) -> bool:
    family = request.family
    return (
        request.is_model
        and family is not None
        and family.coverage_channel is not None
        and request.channel != family.coverage_channel
    )


def run(ctx) -> None:
    request = ctx.request
    # only its COVERAGE_KEYS are kept: no FLIP, SSIM or PSNR of the coverage image
    asked = request.with_channel(request.family.coverage_channel, coverage_only=True)
    coverage = ctx.rescore(asked)
    for key in COVERAGE_KEYS:
        ctx.summary[key] = coverage.record.get(key)
    floor = ctx.floor
    if floor is not None:
        theirs = coverage.record.get("noise_floor") or {}
        floor.update({k: v for k, v in theirs.items() if k in COVERAGE_KEYS})
    for mine, theirs in zip(ctx.result.frames, coverage.frames, strict=True):
        mine.metrics.update({k: theirs.metrics.get(k) for k in COVERAGE_KEYS})
        if "coverage_error" in theirs.maps:
            mine.maps["coverage_error"] = theirs.maps["coverage_error"]
    ctx.sections["coverage_reference"] = coverage.record["reference"]
    if coverage.phases is not None:
        for name, seconds in coverage.phases.seconds.items():
            ctx.phases.add(f"coverage {name}", seconds)
