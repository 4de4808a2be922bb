"""Which passes a score runs, decided in one place from the request: its channel's kind in
the metric catalogue and its frame count, its family record (coverage channel, temporal,
what its steady state is judged against) and its candidate (a model or files).

Each pass is a module with ``NAME``, ``applies(request) -> bool`` and ``run(context)``; they
run in :data:`PASSES` order, each reading what those before it wrote. A new family needs no
edit here: its record and the catalogue decide."""

from __future__ import annotations

from . import (
    candidate_layout,
    conformance,
    coverage_merge,
    diagnosis,
    engine_gates,
    fraction_floors,
    noise_floor,
    origin,
    receivers,
    steady,
    summary,
    temporal,
    temporal_floor,
    video,
)

__all__ = ["PASSES", "plan"]

#: Every pass of a score, in the order they run.
PASSES = (
    noise_floor,
    temporal_floor,
    summary,
    temporal,
    video,
    fraction_floors,
    engine_gates,
    receivers,
    coverage_merge,
    steady,
    conformance,
    candidate_layout,
    origin,
    diagnosis,
)


def plan(request) -> list:
    """The passes ``request`` needs, in order."""
    return [p for p in PASSES if p.applies(request)]
