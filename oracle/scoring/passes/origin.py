"""What the run stands for: the export a scene was made from (size, light, camera path and
frame) and the platform (machine and driver; baselines are kept per platform)."""

from __future__ import annotations

from pathlib import Path

from ....scenes.inputs import read_export_record

NAME = "origin"


def applies(request) -> bool:
    # a coverage channel scored beside colour keeps its coverage metrics alone
    return not request.coverage_only


def run(ctx) -> None:
    source = Path(str(ctx.request.loaded.source))
    if source.name in ("scene.xml", "scene.glb") and source.is_file():
        ctx.sections["export"] = read_export_record(source.parent)
    ctx.sections["platform"] = ctx.request.options.platform
