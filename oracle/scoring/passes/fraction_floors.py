"""The noise floors of the fractions of pixels raised to their binomial flip bound
(:func:`oracle.scoring.floors.fraction_floors`). Every score gets it."""

from __future__ import annotations

from ..floors import fraction_floors

NAME = "fraction floors"


def applies(request) -> bool:
    # a coverage channel scored beside colour keeps its coverage metrics alone
    return not request.coverage_only


def run(ctx) -> None:
    fraction_floors(ctx.result, ctx.summary, ctx.floor)
