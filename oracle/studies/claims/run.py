"""Headline claims of the seed documents, measured against the oracle.

Each :class:`Claim` quotes its source (document and slide or section), names the techniques
it needs and a measurement that returns the measured value with error bars (over scenes,
frames or frame pairs) and a verdict, ``reproduced``, ``partly`` or ``not reproduced``, by
the rule stated in the claim's ``rule`` (and applied in its code). A claim about a technique
that is not registered is not measured ("technique not available"); it is measured as soon
as the technique's model is registered, through the documented interfaces (``raster_models
.run`` with the parameter names of issues 9 and 10).

``run_claims(out, cache=..., quiet=..., echo=..., quick=...)`` is the main job's entry point;
it writes ``out/claims.json``.

Seed documents (``shared/seeds/``): ``000`` notes on Sample Distribution Shadow Maps (the
"SDSM notes"); ``001`` C. Wyman, "High-Quality Rasterization", NVIDIA GTC 2015 slides
(ACAA, AGAA, FTIZB); ``002`` A. Tardif, "SDSM. Sample distribution shadow maps" slides;
``003`` "Coherent Shadow Maps: Uncompressed Algorithm" (blog). The lossless-compression claim
is the coherent-shadow-maps paper's (Ritschel et al., EGSR 2007), as quoted in TECHNIQUES.md;
the blog in seed 003 describes the uncompressed algorithm it builds on. The soft-shadow claims
quote issue 38 and the abstract of Peters and Klein's moment-shadow-mapping paper.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ....reports.sections import claims_section
from ....scenes.base.records import jsonable
from ...errors import one_line
from ..output import write_study
from .aa import ACAA_EQUAL, ACAA_HALF, AGAA_COMPARABLE, AGAA_SAVING, _acaa, _agaa, _coherent
from .alpha import A2C_SHIFT, KEEP_BOX, KEEP_NVTT, LOSS_BEYOND_M, _a2c_shrink, _mips_loss
from .base import NOT, PARTLY, REPRODUCED, ClaimContext, summary
from .denoise import LAG_SCENE, _asvgf_lag
from .shadow import (
    BLUR_CLAIM,
    IZB_RATIO,
    KMEANS_GAIN,
    SHADOW_TOL,
    _izb,
    _kmeans,
    _latency,
    _sdsm_blur,
    _sdsm_constant_memory,
    _sdsm_crawl,
    _sdsm_vs_pssm,
)
from .soft import BLEED_BLUR, BLEED_TOL, MISC_TOL, _msm_bleeding, _pcss_distance

__all__ = [
    "ACAA_EQUAL",
    "ACAA_HALF",
    "AGAA_COMPARABLE",
    "AGAA_SAVING",
    "BLEED_BLUR",
    "BLEED_TOL",
    "BLUR_CLAIM",
    "CLAIMS",
    "IZB_RATIO",
    "KMEANS_GAIN",
    "NOT",
    "PARTLY",
    "REPRODUCED",
    "SHADOW_TOL",
    "Claim",
    "ClaimContext",
    "claim_line",
    "claims_record",
    "merge_claims",
    "run_claims",
    "summary",
    "write_claims",
]


@dataclass(frozen=True)
class Claim:
    """A headline claim: its words, where they are, what measuring it needs and the rule
    that turns the measurement into a verdict."""

    id: str
    claim: str
    source: str
    techniques: tuple[str, ...]
    rule: str
    measure: Callable[[ClaimContext], dict]
    scenes: tuple[str, ...] = ()


CLAIMS: tuple[Claim, ...] = (
    Claim(
        "sdsm-beats-pssm",
        "Worst-case scenario is PSSM quality if the entire camera space is covered in shadow "
        "[...] You're basically guaranteed to get better quality.",
        "seed 002 (A. Tardif, SDSM slides), slide 9 'Benefits'",
        ("sdsm", "csm"),
        "reproduced: SDSM's misclassified fraction is lower on average and never above "
        f"PSSM's + {SHADOW_TOL} in any case, at equal shadow-map bytes (4 x 1024^2, hw PCF, "
        "practical splits for PSSM); partly: lower on average only; not: not lower on average",
        _sdsm_vs_pssm,
    ),
    Claim(
        "sdsm-crawls-less",
        "You can apply a stable CSM algorithm [...], but you shouldn't need it because crawling "
        "should be almost non-existent.",
        "seed 002 (A. Tardif, SDSM slides), slide 8",
        ("sdsm", "csm"),
        "reproduced: SDSM's temporal error (mean change of the error between frames) is not "
        "above stable CSM's on average nor in any frame pair by more than "
        f"{SHADOW_TOL}; partly: on average only; not: above on average",
        _sdsm_crawl,
    ),
    Claim(
        "sdsm-blur",
        "Most remaining artifacts seem to come from hard edges meeting curved edges. In my "
        "experience, a little blur cleans up 98% of these.",
        "seed 002 (A. Tardif, SDSM slides), slide 8",
        ("sdsm",),
        f"reproduced: {BLUR_CLAIM:.0%} lies within (or below) mean +- 2 stderr of the edge-band "
        "error removed by a 3x3 moment blur; partly: more than half removed; not: otherwise",
        _sdsm_blur,
    ),
    Claim(
        "kmeans-not-worth-it",
        "(other z partitioning algorithms, like K-means are not worth it!)",
        "seed 000 (SDSM notes), section 'Algorithm'",
        ("sdsm",),
        "reproduced: K-means lowers the misclassified fraction by no more than "
        f"{KMEANS_GAIN:.0%} of log's (or {SHADOW_TOL}) on average and not significantly "
        "(mean - 2 stderr); partly: the gain is not significant but larger on average; "
        "not: a significant gain",
        _kmeans,
    ),
    Claim(
        "readback-latency-uncovers",
        "First Approach: use depth-buffer of previous frame [...] problem: artefacts on "
        "partition borders - when the camera moves, rendered geometry will not be covered by "
        "Z-partitions [...] new geometry might be visible!",
        "seed 000 (SDSM notes), 'Our implementation details', 'First Approach'",
        ("sdsm",),
        "reproduced: with 2 frames of readback latency some receivers of a moving camera are "
        "covered by no partition, and none are without latency; partly: more uncovered with "
        "latency than without; not: otherwise",
        _latency,
    ),
    Claim(
        "sdsm-constant-memory",
        "constant memory usage/predictable performance",
        "seed 000 (SDSM notes), first list",
        ("sdsm",),
        "reproduced: shadow-map bytes and texels rendered are identical over every scene and "
        "frame; not: otherwise",
        _sdsm_constant_memory,
    ),
    Claim(
        "izb-exact-32spp-under-2x",
        "Show 32 spp shadows are under 2x cost of 1 spp shadows (and 1 sample per pixel "
        "equals a shadow ray from the pixel: 'a raster method to render ray traced quality')",
        "seed 001 (C. Wyman, GTC 2015 slides), 'Frustum-Traced Irregular Z-Buffer Shadows', "
        "'Features'; TECHNIQUES.md (IZB, 1 sample per pixel)",
        ("izb",),
        "reproduced: 1-spp IZB agrees with the oracle's centre shadow ray on every receiver "
        "outside the epsilon band, and 32 spp needs under 2x the sample-triangle tests of "
        "1 spp; partly: one of the two; not: neither",
        _izb,
    ),
    Claim(
        "acaa-equals-msaa",
        "Same image quality as MSAA (*) - Less memory (in color buffer); caveat: fails when "
        "z-fighting occurs (paper abstract: half the multisample framebuffer memory)",
        "seed 001 (C. Wyman, GTC 2015 slides), 'ACAA algorithm' and 'ACAA caveats'; "
        "TECHNIQUES.md (ACAA)",
        ("acaa", "msaa"),
        f"reproduced: colour within {ACAA_EQUAL:g} (relative) of 8x MSAA on every scene "
        "without tied surfaces, different on the scene with ties (decal), and framebuffer "
        f"memory (RGBA8 accumulation) in [{ACAA_HALF[0]}, {ACAA_HALF[1]}] of MSAA's; "
        "partly: some of the three; not: none",
        _acaa,
    ),
    Claim(
        "agaa-vs-msaa8",
        "Requires significantly less memory (37% less with 2 aggregates v.s. 8x MSAA); "
        "shading events 1.51 / pixel (AGAA 2A) vs 6.68 (deferred 8x, Simple/Complex)",
        "seed 001 (C. Wyman, GTC 2015 slides), 'AGAA', 'Results: memory'; paper abstract "
        "(TECHNIQUES.md): about 30% less memory",
        ("agaa", "msaa"),
        f"reproduced: AGAA's colour error at most {AGAA_COMPARABLE}x 8x MSAA's on average, "
        f"memory saving >= {AGAA_SAVING[0] - 0.05:.2f} on average over deferred 8x MSAA "
        "(per-sample G-buffer, the slides' baseline), and no more shading events than "
        "deferred MSAA (Simple/Complex) on any scene; partly: some of the three; not: none",
        _agaa,
    ),
    Claim(
        "coherent-lossless",
        "Compression (paper): lossless for visibility, because any depth between the first "
        "and second surface along a texel's ray gives the same binary answer",
        "Ritschel, Grosch, Kautz, Mueller, Interactive Illumination with Coherent Shadow "
        "Maps, EGSR 2007 (as quoted in TECHNIQUES.md); seed 003 describes the uncompressed "
        "algorithm",
        ("coherent-shadow-map",),
        "reproduced: visibility with compression identical to without on every scene, no "
        "decompressed mismatch, and a compression ratio above 1; partly: lossless only; "
        "not: visibility differs",
        _coherent,
    ),
    Claim(
        "pcss-penumbra-error-grows",
        "PCSS's penumbra width error grows with the blocker-receiver distance",
        "issue 38 (soft shadows), 'Built-in scenes'",
        ("pcss",),
        "reproduced: on soft-contact, for both presets, the mean |estimated - geometric| "
        "penumbra width never falls from one receiver-caster distance bin to the next by more "
        "than 2 stderr; partly: larger in the farthest bin than in the nearest for both; "
        "not: otherwise",
        _pcss_distance,
        scenes=("soft-contact",),
    ),
    Claim(
        "msm-bleeds-less",
        "Like variance shadow mapping it allows for the application of all kinds of efficient "
        "texture filtering [...] However it is designed to provide a substantially higher "
        "quality.",
        "Peters and Klein, Moment Shadow Mapping, I3D 2015, abstract",
        ("msm", "shadow-map"),
        f"reproduced: with a {BLEED_BLUR}-texel moment blur, 16-bit MSM leaves less light "
        f"in the hard umbra than VSM (by more than {BLEED_TOL}) and misclassifies no more "
        f"receivers than VSM and EVSM4 (within {MISC_TOL}) on stacked-casters and plate; "
        "partly: less light than VSM on stacked-casters; not: otherwise",
        _msm_bleeding,
        scenes=("stacked-casters", "plate"),
    ),
    Claim(
        "asvgf-less-lag",
        "gradient-based history rejection reduces lag after a light change compared with SVGF",
        "issue 46 (ray-traced shadows denoised), after C. Schied, C. Peters, C. Dachsbacher, "
        "Gradient Estimation for Real-Time Adaptive Temporal Filtering, HPG 2018",
        ("rtshadows-svgf", "rtshadows-asvgf"),
        f"reproduced: on {LAG_SCENE}, A-SVGF's error is back within its lit steady error plus "
        "the truth's floor sooner than SVGF's both after the light goes off and after it "
        "comes back on (and never later); partly: sooner after one of them, never later; "
        "not: otherwise",
        _asvgf_lag,
        scenes=(LAG_SCENE,),
    ),
    Claim(
        "alpha-box-mips-lose-foliage",
        f"box-filtered mips lose more than {1 - KEEP_BOX:.0%} of the foliage beyond "
        f"{LOSS_BEYOND_M:g} m; coverage-preserving mips keep it",
        "issue 44 (alpha-tested foliage), after three.js issue 20522 and I. Castano, "
        "Computing Alpha Mipmaps (NVTT's coverage-preserving scaling)",
        ("alpha-test",),
        f"reproduced: on alpha-foliage, the plain alpha test (4x MSAA) with box-filtered mips "
        f"keeps under {KEEP_BOX:g} of the truth's coverage in every band beyond "
        f"{LOSS_BEYOND_M:g} m and with NVTT's mips at least {KEEP_NVTT:g} in the first of them; "
        "partly: box mips lose it and NVTT's keep more without reaching that; not: otherwise",
        _mips_loss,
        scenes=("alpha-foliage",),
    ),
    Claim(
        "alpha-threejs-a2c-shrinks",
        "three.js alpha-to-coverage shrinks silhouettes by about half a pixel",
        "issue 44 (alpha-tested foliage), after three.js PR 22172 "
        "(smoothstep(alphaTest, alphaTest + fwidth(a), a))",
        ("alpha-threejs-a2c",),
        f"reproduced: its mean silhouette shift against the cut-out truth lies in "
        f"[{A2C_SHIFT[0]:g}, {A2C_SHIFT[1]:g}] px (inwards) on a leaf card at 3 px a texel, "
        "4x MSAA; partly: inwards by another amount; not: not inwards",
        _a2c_shrink,
        scenes=("alpha-foliage",),
    ),
)


def _measure(claim: Claim, ctx: ClaimContext) -> dict:
    from .... import raster_models

    row = {
        "id": claim.id,
        "claim": claim.claim,
        "source": claim.source,
        "techniques": list(claim.techniques),
        "rule": claim.rule,
    }
    missing = [t for t in claim.techniques if t not in raster_models.TECHNIQUES]
    if missing:
        row.update(
            verdict="not measured",
            note=f"not measured: technique not available ({', '.join(missing)})",
        )
        return row
    t0 = time.perf_counter()
    try:
        result = claim.measure(ctx)
    except Exception as exc:  # a failed measurement is reported in its row
        row.update(verdict="not measured", note=f"not measured: {one_line(exc, with_type=True)}")
        return row
    row.update(result)
    row["seconds"] = time.perf_counter() - t0
    return row


def run_claims(
    out: Path | None,
    *,
    cache=None,
    quiet: bool = True,
    echo=None,
    quick: bool = True,
    only: list[str] | None = None,
    size: tuple[int, int] | None = None,
) -> dict:
    """Measure every claim (or those in ``only``); writes ``out/claims.json`` (and
    ``claims.html``).

    ``quick``: 160x90 pixels, 16-spp oracle, 4 frames (the main job's budget); otherwise
    320x180, 64 spp, 8 frames. ``size`` overrides the film size (tests).
    """
    say = echo or (lambda *_: None)
    ctx = ClaimContext(quick=quick, cache=cache, quiet=quiet)
    if not quick:
        ctx.width, ctx.height, ctx.spp, ctx.frames = 320, 180, 64, 8
    if size is not None:
        ctx.width, ctx.height = (int(v) for v in size)
    known = {c.id for c in CLAIMS}
    unknown = sorted(set(only or ()) - known)
    if unknown:
        raise ValueError(f"unknown claim(s) {', '.join(unknown)}; choose from {', '.join(known)}")
    t0 = time.perf_counter()
    rows = []
    for claim in CLAIMS:
        if only and claim.id not in only:
            continue
        row = _measure(claim, ctx)
        rows.append(row)
        say(claim_line(row))
    data = claims_record(rows, ctx=ctx, wall_seconds=time.perf_counter() - t0)
    if out is not None:
        write_claims(out, data)
    return data


def claim_line(row: dict) -> str:
    """The line a claims run prints for a measured claim: id, verdict, seconds."""
    seconds = f" ({row['seconds']:.1f} s)" if "seconds" in row else ""
    return f"claim {row['id']:<26} {row['verdict']}{seconds}"


def claims_record(rows: list[dict], *, ctx: ClaimContext, wall_seconds: float) -> dict:
    """The claims record (``claims.json``) of measured ``rows`` at ``ctx``'s sizes."""
    data = {
        "schema": "raster-oracle.studies.claims.run/1",
        "quick": ctx.quick,
        "resolution": [ctx.width, ctx.height],
        "reference_spp": ctx.spp,
        "frames": ctx.frames,
        "claims": rows,
        "counts": {
            v: sum(1 for r in rows if r["verdict"] == v)
            for v in (REPRODUCED, PARTLY, NOT, "not measured")
        },
        "wall_seconds": float(wall_seconds),
    }
    return jsonable(data)


def merge_claims(parts: list[dict]) -> dict:
    """One claims record from the records of runs over parts of the claims (``only``), each
    at the same sizes: their rows in :data:`CLAIMS` order, counts over all, seconds summed
    (the main job measures each claim on a worker of its own, :mod:`oracle.sweeps.mainjob`)."""
    if not parts:
        raise ValueError("no claims record to merge")
    order = {c.id: i for i, c in enumerate(CLAIMS)}
    rows = sorted((r for p in parts for r in p["claims"]), key=lambda r: order[r["id"]])
    first = parts[0]
    sizes = ("quick", "resolution", "reference_spp", "frames")
    if any(p[k] != first[k] for p in parts for k in sizes):
        raise ValueError("claims records at different sizes cannot be merged")
    ctx = ClaimContext(quick=first["quick"])
    ctx.width, ctx.height = first["resolution"]
    ctx.spp, ctx.frames = first["reference_spp"], first["frames"]
    return claims_record(rows, ctx=ctx, wall_seconds=sum(p["wall_seconds"] for p in parts))


def write_claims(out: Path, data: dict) -> None:
    """Write ``out/claims.json`` and its page."""
    section = claims_section(data)
    write_study(out, name="claims", data=data, section=section, title="raster-oracle claims")
