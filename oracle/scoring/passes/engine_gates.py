"""The engine teams' gate metrics (Unreal, Unity, edge-aware) with their noise floors
(:func:`oracle.scoring.engine_metrics.add_engine_gate_metrics`), on the channels an engine
writes whose kind the catalogue declares them for."""

from __future__ import annotations

from ..engine_metrics import add_engine_gate_metrics, engine_gates_apply, prepared_reference

NAME = "engine gates"


def applies(request) -> bool:
    # a coverage channel scored beside colour keeps its coverage metrics alone
    return engine_gates_apply(request.channel) and not request.coverage_only


def run(ctx) -> None:
    request = ctx.request

    def prepared(k):
        return prepared_reference(
            ctx.result.frames[k].reference,
            channel=request.channel,
            exposure=ctx.exposure,
            key=ctx.references[k][0].meta.get("cache_key"),
            memo=request.floor_cache,
        )

    add_engine_gate_metrics(
        ctx.result,
        ctx.summary,
        ctx.floor,
        channel=request.channel,
        exposure=ctx.exposure,
        stderrs=ctx.stderrs,
        prepared=prepared,
    )
