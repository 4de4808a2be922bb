"""The pixels off the oracle's receivers of a shadow mask, hard or soft: they keep the
reference's values, so they are counted instead (``outside_receivers``: pixels, and how many
differ from the reference there). The rule is :func:`oracle.scoring.channels.on_receivers`."""

from __future__ import annotations

from ..channels import on_receivers

NAME = "receivers"


def applies(request) -> bool:
    return on_receivers(request.channel)


def run(ctx) -> None:
    frames = ctx.result.frames
    outside = {
        key: sum(int(f.metrics[k]) for f in frames)
        for key, k in (
            ("pixels", "outside_receivers"),
            ("differing", "outside_receivers_differing"),
        )
    }
    ctx.sections["outside_receivers"] = outside
    if outside["differing"]:
        ctx.notes["receivers"] = [
            f"{ctx.request.channel}: {outside['differing']} of the {outside['pixels']} pixels "
            "off the oracle's receivers (sky, back faces, outside a spot cone) differ from "
            "the reference there; they are not scored"
        ]
