"""Alpha-tested foliage claims (issue 44), measured with the registered alpha-test rules
(:mod:`raster_models.alpha`) against the cut-out truth on ``alpha-foliage``
(:mod:`oracle.studies.alpha_coverage`)."""

from __future__ import annotations

import numpy as np

from .base import NOT, PARTLY, REPRODUCED, ClaimContext, summary

__all__ = [
    "A2C_SHIFT",
    "FOLIAGE_N",
    "KEEP_BOX",
    "KEEP_NVTT",
    "LOSS_BEYOND_M",
    "MIPS_SIZE",
    "_a2c_shrink",
    "_mips_loss",
]

#: The claim's distance (metres): the band edge beyond which box-filtered mips lose it.
LOSS_BEYOND_M = 5.0
#: Box-filtered mips "lose more than half": coverage kept below this in every band beyond.
KEEP_BOX = 0.5
#: Coverage-preserving mips "keep it": coverage kept at least this in the first band beyond.
KEEP_NVTT = 0.9
#: "About half a pixel": the three.js shift within this interval (pixels, negative: inwards).
A2C_SHIFT = (-0.75, -0.25)
#: Cards of the foliage view.
FOLIAGE_N = 1000
#: Film size of the mips claim (the study's, docs/research.md).
MIPS_SIZE = (320, 180)


def _mips_loss(ctx: ClaimContext) -> dict:
    """Coverage kept (the rule's mean coverage over the truth's) per distance band by the
    plain alpha test with box-filtered and with NVTT's coverage-preserving mips, 4x MSAA, at
    :data:`MIPS_SIZE` whatever the claims' film size: the texels a pixel covers at a
    distance, which decide the mip level, are set by the film size."""
    from ....scenes.catalogue.alpha_foliage import band_edges
    from ..alpha_coverage import FoliageView, truth_and_depth

    loaded = ctx.scene(f"alpha-foliage:n={FOLIAGE_N}", size=MIPS_SIZE)
    view = FoliageView(loaded.mi_scene, loaded.alpha, loaded.camera)
    truth, depth = truth_and_depth(view, 4)
    edges = band_edges()
    band = np.searchsorted(edges, depth, side="right") - 1
    kept = {}
    for mips in ("box", "nvtt"):
        cov = ctx.run("alpha-test", loaded, samples=4, mips=mips).outputs["coverage"]
        kept[mips] = []
        for b in range(len(edges) - 1):
            sel = (band == b) & (depth > 0)
            kept[mips].append(float(cov[sel].mean() / max(truth[sel].mean(), 1e-12)))
    beyond = [b for b in range(len(edges) - 1) if edges[b] >= LOSS_BEYOND_M - 1e-9]
    cases = [
        {
            "band_m": [float(edges[b]), float(edges[b + 1])],
            "kept_box": kept["box"][b],
            "kept_nvtt": kept["nvtt"][b],
        }
        for b in range(len(edges) - 1)
    ]
    box_loses = all(kept["box"][b] < KEEP_BOX for b in beyond)
    first = beyond[0]
    if box_loses and kept["nvtt"][first] >= KEEP_NVTT:
        verdict = REPRODUCED
    elif box_loses and kept["nvtt"][first] > kept["box"][first]:
        verdict = PARTLY
    else:
        verdict = NOT
    return {
        "value": summary(kept["box"][b] for b in beyond),
        "value_text": f"coverage kept by box-filtered mips per band beyond {LOSS_BEYOND_M:g} m "
        f"(NVTT's in the cases; {loaded.width}x{loaded.height}, {FOLIAGE_N} cards, 4x MSAA)",
        "cases": cases,
        "verdict": verdict,
    }


def _a2c_shrink(ctx: ClaimContext) -> dict:
    """Mean silhouette shift (pixels, negative: inwards) of three.js alpha-to-coverage and of
    the plain test on one leaf card magnified to 3 pixels a texel, 4x MSAA."""
    from ..alpha_coverage import silhouette_shift

    size = 192 if not ctx.quick else 96
    cases = [
        {"rule": preset, **silhouette_shift(preset, size=size, samples=4)}
        for preset in ("threejs-a2c/box", "test/box")
    ]
    shift = cases[0]["shift_px"]
    if A2C_SHIFT[0] <= shift <= A2C_SHIFT[1]:
        verdict = REPRODUCED
    elif shift < 0:
        verdict = PARTLY
    else:
        verdict = NOT
    return {
        "value": summary([shift]),
        "value_text": f"three.js alpha-to-coverage's silhouette shift (px; the plain test's in "
        f"the cases), a {size}x{size} close-up at 3 px a texel",
        "cases": cases,
        "verdict": verdict,
    }
