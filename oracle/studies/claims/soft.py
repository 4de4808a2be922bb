"""Soft-shadow claims (issue 38): PCSS's contact hardening and moment shadow maps' light
bleeding, measured against the oracle (:mod:`oracle.studies.soft_shadows`)."""

from __future__ import annotations

import numpy as np

from .base import NOT, PARTLY, REPRODUCED, ClaimContext, summary

__all__ = [
    "BLEED_BLUR",
    "BLEED_SCENES",
    "BLEED_TOL",
    "MISC_TOL",
    "_msm_bleeding",
    "_pcss_distance",
]

#: Scenes of the bleeding claim: stacked casters (two depths in a filter region) and the
#: plate (one caster).
BLEED_SCENES = ("stacked-casters", "plate")
#: Umbra leak (mean visibility) differences below this are ties.
BLEED_TOL = 0.005
#: Misclassified fractions within this of each other are ties.
MISC_TOL = 0.001
#: Moment blur of the bleeding comparison (texels), the same for every filter.
BLEED_BLUR = 5


def _msm_bleeding(ctx: ClaimContext) -> dict:
    """Light leaked into the hard reference's umbra and misclassified receivers of 16-bit
    MSM, VSM and EVSM4 (all with a 5-texel moment blur, 2048^2 maps) on each bleeding
    scene."""
    from .... import metrics as M
    from ...scoring.score import reference_receivers
    from ..soft_shadows import umbra_bleeding

    cases = []
    for name in BLEED_SCENES:
        loaded = ctx.scene(name)
        ref = ctx.reference(loaded)
        rec = reference_receivers(ref, loaded.light)
        case = {"scene": name}
        for label, tech, kw in (
            ("msm", "msm", {}),
            ("vsm", "shadow-map", {"filter": "vsm"}),
            ("evsm4", "shadow-map", {"filter": "evsm4"}),
        ):
            res = ctx.run(tech, loaded, resolution=2048, blur_size=BLEED_BLUR, **kw)
            vis = np.clip(np.asarray(res.outputs["visibility"], dtype=np.float32), 0.0, 1.0)
            leak = umbra_bleeding(ref["visibility"], vis, rec)
            sm = M.shadow_metrics(ref["visibility"], vis, receivers=rec)
            case[f"{label}_umbra_mean"] = leak["mean"]
            case[f"{label}_leak_fraction"] = leak["leak_fraction"]
            case[f"{label}_misclassified"] = sm["misclassified_fraction"]
            case["umbra_pixels"] = leak["umbra_pixels"]
        cases.append(case)
    less_leak = [c["msm_umbra_mean"] < c["vsm_umbra_mean"] - BLEED_TOL for c in cases]
    no_worse = [
        c["msm_misclassified"] <= min(c["vsm_misclassified"], c["evsm4_misclassified"]) + MISC_TOL
        for c in cases
    ]
    stacked = cases[0]
    if all(less_leak) and all(no_worse):
        verdict = REPRODUCED
    elif stacked["msm_umbra_mean"] < stacked["vsm_umbra_mean"] - BLEED_TOL:
        verdict = PARTLY
    else:
        verdict = NOT
    return {
        "value": summary(c["msm_umbra_mean"] for c in cases),
        "value_text": "mean visibility MSM leaves in the hard umbra (VSM's and EVSM4's, and "
        "the misclassified fractions, in the cases)",
        "cases": cases,
        "verdict": verdict,
    }


def _pcss_distance(ctx: ClaimContext) -> dict:
    """PCSS's penumbra width error (its estimate against the geometric width) in bins of the
    receiver-caster distance on ``soft-contact``, for both presets: does it grow with the
    distance?"""
    from ..soft_shadows import contact_hardening

    loaded = ctx.scene("soft-contact")
    cases, grows, larger_far = [], [], []
    for preset in ("nvidia", "hdrp"):
        res = ctx.run("pcss", loaded, resolution=2048, preset=preset)
        rows = [r for r in contact_hardening(loaded, res)["bins"] if r["pixels"] >= 10]
        errs = [r["abs_error"] for r in rows]
        ses = [r["abs_error_stderr"] for r in rows]
        pairs = zip(errs, errs[1:], ses, ses[1:], strict=False)
        steps = [b + 2 * sb >= a - 2 * sa for a, b, sa, sb in pairs]
        grows.append(bool(rows) and all(steps))
        larger_far.append(bool(rows) and errs[-1] > errs[0])
        cases += [{"preset": preset, **r} for r in rows]
    if all(grows):
        verdict = REPRODUCED
    elif all(larger_far):
        verdict = PARTLY
    else:
        verdict = NOT
    return {
        "value": summary(c["abs_error"] for c in cases),
        "value_text": "mean |estimated - geometric| penumbra width (m) per distance bin",
        "cases": cases,
        "verdict": verdict,
    }
