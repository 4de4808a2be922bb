"""The diagnoses of an engine's image (flipped, encoded twice, shifted, a material's gain:
:mod:`oracle.scoring.diagnosis`) and the notes they make. A model's output is what the
technique computes, not a file to diagnose, and a depth is not an image
(:data:`metrics.catalog.IMAGE_KINDS`): their ``diagnoses`` stay empty."""

from __future__ import annotations

from collections import ChainMap

from ....metrics.catalog import IMAGE_KINDS
from ..diagnosis import diagnose_result, explain_colour

NAME = "diagnosis"


def applies(request) -> bool:
    # a coverage channel scored beside colour keeps its coverage metrics alone
    return not request.coverage_only


def run(ctx) -> None:
    request = ctx.request
    sections = ctx.sections
    sections["diagnoses"] = []
    if not request.is_file or request.kind not in IMAGE_KINDS:
        return
    found = diagnose_result(ctx.result, channel=request.channel, floors=ctx.floor)
    sections["diagnosis"] = {k: found[k] for k in ("error", "noise_floor", "tried")}
    causes, details = [], []
    if request.channel == "color":
        names = list(request.loaded.shape_names)
        view = ChainMap(sections, ctx.summary)
        causes, details = explain_colour(ctx.result, view, exposure=ctx.exposure, names=names)
        best = sections["colour_causes"]["causes"]
        # a gain read as a transfer curve: the cause that leaves less error is the one named
        if found["likely"] and best and best[0]["error"] < found["likely"]["error"]:
            found["likely"] = None
    if found["likely"]:
        sections["diagnoses"].append(found["likely"])
    sections["diagnoses"] += [{"transform": None, "message": n} for n in found["notes"]]
    sections["diagnoses"] += [{"transform": None, "message": n} for n in causes]
    ctx.notes["diagnosis"] = [d["message"] for d in sections["diagnoses"]] + details
