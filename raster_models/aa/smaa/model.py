"""The ``smaa`` technique: SMAA 1x, T2x, S2x and 4x as ``SMAA.hlsl`` describes them, in display
space like ``fxaa`` (:mod:`..fxaa`).

Each sample image (one sample per pixel at the mode's position) is the oracle's shading
(one sample at a jittered position: ``trace.sample_colors``; the two samples of 2x MSAA with
the D3D standard pattern: ``msaa.multisample``, shaded once per primitive at the pixel
centre), tone-mapped by the project's pipeline (:func:`scenes.base.display.tonemap`, exposure
from the model's own sample-averaged image, as ``fxaa``) to gamma-encoded values in [0, 1]
where SMAA's thresholds are defined. SMAA 1x runs its three passes on it
(:mod:`.edges`, :mod:`.weights`, :mod:`.blending`) with the sub-sample indices of its mode:

=====  ===================================================  =================================
mode   samples (y down, from the pixel corner) and indices  combined
=====  ===================================================  =================================
1x     (0.5, 0.5) (0, 0, 0, 0)                              -
t2x    frame 0: (0.75, 0.75) (1, 1, 1, 0);                  resolve (reprojection, scale 30)
       frame 1: (0.25, 0.25) (2, 2, 2, 0)
s2x    (0.75, 0.75) (1, 1, 1, 0); (0.25, 0.25) (2, 2, 2, 0)  averaged (sRGB target blend 0.5)
4x     frame 0: (0.875, 0.625) (5, 3, 1, 3);                S2x per frame, then resolve
       (0.375, 0.125) (4, 6, 2, 3); frame 1: (0.625,
       0.875) (3, 5, 1, 4); (0.125, 0.375) (6, 4, 2, 4)
=====  ===================================================  =================================

The header's jitters assume y up: its T2x jitter (0.25, -0.25) is the D3D 2x sample 0
(+4/16, +4/16 y down), and 4x's net jitters add the camera jitter (+-0.125, +-0.125) to it.
T2x and 4x resolve frame 1 (current) with frame 0 (previous). The camera is static here:
motion vectors (the temporal-AA issue) are not available yet, so the velocity is zero, the
reprojection weight is 0.5 everywhere and the resolve is the plain average of both frames
(``diagnostics["velocity"]`` says so).

Outputs: ``color`` (linear: the radiance the pipeline maps to the displayed image; the
exact one-sample radiance where SMAA changed nothing and the samples agree), ``color_display``
(SMAA's output), ``coverage`` (the one-sample coverage masks through the same blending
weights and fetches as the colour, combined like the colour: SMAA's effective coverage),
``front_coverage`` (the weight the same fetches give to samples of the shape seen through the
pixel centre), ``smaa_edges`` (edge pixels of the first sample image). Shading events: the
displayed frame's (one per covered pixel; S2x/4x: MSAA fragments).

References
----------
J. Jimenez, J. I. Echevarria, T. Sousa, D. Gutierrez, SMAA: Enhanced Subpixel Morphological
Antialiasing, Computer Graphics Forum 31(2) (Eurographics 2012),
doi:10.1111/j.1467-8659.2012.03014.x.
J. Jimenez et al., ``SMAA.hlsl`` (``iryoku/smaa``), 2013: presets, defaults, sub-sample indices.
T. Sousa, Anti-aliasing methods in CryENGINE 3, SIGGRAPH 2011 course (velocity-weighted
reprojection).
"""

from __future__ import annotations

import time

import numpy as np

from ....scenes.base.display import (
    exposure_from_reference,
    srgb_decode,
    srgb_encode,
    tonemap,
    tonemap_inverse,
)
from .. import msaa as _msaa
from ..common import package
from ..trace import sample_colors, trace_samples
from ._sampling import Fetches
from .blending import neighborhood_blend, resolve
from .edges import detect_edges
from .params import MODES, SmaaParams, resolved
from .weights import blending_weights

__all__ = ["NAME", "run", "smaa_1x"]

NAME = "smaa"

# bytes per texel of each texture a pass reads (RGBA8 colour, D32 depth, RG8 edges, R8G8
# area, R8 search, RGBA8 weights, RG16F velocity)
TEXEL_BYTES = {
    "color": 4,
    "depth": 4,
    "edges": 2,
    "area": 2,
    "search": 1,
    "weights": 4,
    "velocity": 4,
}


def smaa_1x(
    display: np.ndarray, cfg: dict, indices, *, depth=None, extra=None, match=None, fetches=None
):
    """SMAA 1x on one gamma-encoded image with sub-sample ``indices``; ``cfg``:
    :func:`.params.resolved`. Returns :func:`.blending.neighborhood_blend`'s dict plus
    ``edges``."""
    pred = None
    if cfg["predication"]:
        pred = {k: cfg[f"predication_{k}"] for k in ("threshold", "scale", "strength")}
    edges = detect_edges(
        display,
        method=cfg["edge_detection"],
        threshold=cfg["threshold"],
        local_contrast_factor=cfg["local_contrast_factor"],
        depth=depth,
        depth_threshold=cfg["depth_threshold"],
        predication=pred,
        fetches=fetches,
    )
    wts = blending_weights(
        edges,
        max_search_steps=cfg["max_search_steps"],
        max_search_steps_diag=cfg["max_search_steps_diag"] or None,
        corner_rounding=None if cfg["corner_rounding"] >= 100 else cfg["corner_rounding"],
        subsample_indices=indices,
        fetches=fetches,
    )
    out = neighborhood_blend(
        display, wts, srgb=cfg["srgb_blending"], extra=extra, match=match, fetches=fetches
    )
    out["edges"] = edges
    return out


def _hardware_depth(camera, view_depth: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Direct3D depth-buffer values in [0, 1] (near 0, far 1, sky cleared to 1)."""
    n, f = camera.near, camera.far
    d = np.maximum(view_depth.astype(np.float64), n)
    z = f * (d - n) / (d * (f - n)) if camera.kind == "perspective" else (d - n) / (f - n)
    return np.where(valid, np.clip(z, 0.0, 1.0), 1.0).astype(np.float32)


def _frame_samples(scene, offsets: np.ndarray):
    """(N, H, W, 3) linear sample images, (N, H, W) coverage masks, and a dict: shadow
    ``rays``, shading ``events`` per pixel ((H, W): one per covered pixel; MSAA: fragments)."""
    h, w = scene.height, scene.width
    if len(offsets) == 1:
        res, rays = sample_colors(scene, offsets)
        col, valid = res["color"], res["valid"]
        events = valid[:, 0].astype(np.int64)
    else:
        ms = _msaa.multisample(scene, offsets, centroid=False, shadows="exact")
        col, valid, rays = (
            _msaa.sample_colors(ms["frags"], ms["rgb"]),
            ms["buffer"]["valid"],
            ms["shadow_rays"],
        )
        events = ms["frags"].per_pixel(h * w)
    n = len(offsets)
    col = np.moveaxis(np.asarray(col, np.float32).reshape(h, w, n, 3), 2, 0)
    valid = np.moveaxis(np.asarray(valid).reshape(h, w, n), 2, 0)
    return np.ascontiguousarray(col), valid, {"rays": rays, "events": events.reshape(h, w)}


def _run_frames(scene, p, cfg, fetches):
    """Every frame of the mode: SMAA per sample, samples combined; returns a dict."""
    frames = MODES[p.mode]
    rendered = [_frame_samples(scene, np.array([s[0] for s in fr])) for fr in frames]
    exposure = exposure_from_reference(np.mean([c.mean(axis=0) for c, _, _ in rendered], axis=0))
    need_depth = cfg["edge_detection"] == "depth" or cfg["predication"]
    w, h = scene.width, scene.height
    centre = trace_samples(scene, np.array([[0.5, 0.5]]), keep=("shape",))["shape"].reshape(h, w)
    results, first_edges, unchanged = [], None, np.ones((h, w), bool)
    first = rendered[0][0][0]
    for fr, (col, valid, _) in zip(frames, rendered, strict=True):
        depth = None
        tr = trace_samples(scene, np.array([s[0] for s in fr]), keep=("valid", "shape", "depth"))
        if need_depth:
            depth = [
                _hardware_depth(scene.camera, tr["depth"][:, i], tr["valid"][:, i]).reshape(h, w)
                for i in range(len(fr))
            ]
        outs = []
        for i, (_, indices) in enumerate(fr):
            disp = tonemap(col[i], exposure=exposure, method=p.tone_mapper)
            o = smaa_1x(
                disp,
                cfg,
                indices,
                depth=None if depth is None else depth[i],
                extra={"coverage": valid[i].astype(np.float32)},
                match={"front_coverage": (tr["shape"][:, i].reshape(h, w), centre)},
                fetches=fetches,
            )
            unchanged &= ~o["blended"] & np.all(col[i] == first, axis=-1)
            outs.append(o)
            first_edges = o["edges"] if first_edges is None else first_edges
        results.append(_combine_samples(outs, cfg["srgb_blending"]))
    if len(results) == 2:  # T2x / 4x: resolve current (frame 1) with previous (frame 0)
        cur, prev = results[1], results[0]
        stacked = resolve(
            np.concatenate([cur["color"], cur["coverage"][..., None], cur["front"][..., None]], -1),
            np.concatenate(
                [prev["color"], prev["coverage"][..., None], prev["front"][..., None]], -1
            ),
            alpha_current=cur["alpha"],
            alpha_previous=prev["alpha"],
            weight_scale=cfg["reprojection_weight_scale"],
            fetches=fetches,
        )
        final = {"color": stacked[..., :3], "coverage": stacked[..., 3], "front": stacked[..., 4]}
    else:
        final = results[0]
    return {
        "display": final["color"],
        "coverage": final["coverage"],
        "front_coverage": final["front"],
        "unchanged": unchanged,
        "linear0": first,
        "edges": first_edges,
        "exposure": exposure,
        "rays": sum(r["rays"] for _, _, r in rendered),
        "events": rendered[-1][2]["events"],  # the frame rendered for this display
        "valid": np.mean([v.mean(axis=0) for _, v, _ in rendered], axis=0),
    }


def _combine_samples(outs: list[dict], srgb: bool) -> dict:
    """S2x: the per-sample results blended 0.5 into one target (in linear light when the
    target is sRGB); one sample: itself."""
    if len(outs) == 1:
        return {**outs[0], "front": outs[0]["front_coverage"]}
    cols = np.stack([o["color"] for o in outs])
    color = srgb_encode(srgb_decode(cols).mean(axis=0)) if srgb else cols.mean(axis=0)
    return {
        "color": color.astype(np.float32),
        "coverage": np.mean([o["coverage"] for o in outs], axis=0).astype(np.float32),
        "front": np.mean([o["front_coverage"] for o in outs], axis=0).astype(np.float32),
        "alpha": outs[0]["alpha"],
    }


def _costs(p, n_pix: int, fetches: Fetches) -> dict:
    """Passes, texture fetches and bytes per displayed pixel, intermediate buffers."""
    frames = MODES[p.mode]
    n_f, n_s = len(frames), len(frames[0])
    per_frame = {k: v / n_f for k, v in fetches.by_pass.items()}
    fetch_pp = {k: v / n_pix for k, v in per_frame.items()}
    bytes_pp = {k: v * TEXEL_BYTES[k.split(":")[1]] for k, v in fetch_pp.items()}
    buffers = {"edges": 2 * n_pix, "weights": 4 * n_pix}  # RG8, RGBA8 (reused per sample)
    if n_s > 1:
        buffers["separated"] = 4 * n_pix * n_s  # SMAASeparatePS targets, RGBA8
    if n_f > 1:
        buffers["history"] = 4 * n_pix  # previous frame for the resolve, RGBA8
    return {
        "passes": 3 * n_s + (1 if n_s > 1 else 0) + (1 if n_f > 1 else 0),
        "texture_fetches_per_pixel": float(sum(fetch_pp.values())),
        "texture_fetches_per_pixel_by_pass": fetch_pp,
        "texture_bytes_per_pixel": float(sum(bytes_pp.values())),
        "buffers": buffers,
    }


def run(scene, params: SmaaParams | None = None, **kwargs):
    """Run ``smaa`` on a loaded scene; see :func:`raster_models.run`."""
    from ... import params as _params

    t0 = time.perf_counter()
    p = params or _params.make(NAME, SmaaParams, kwargs)
    cfg = resolved(p)
    fetches = Fetches()
    fr = _run_frames(scene, p, cfg, fetches)
    w, h = scene.width, scene.height
    n_pix = w * h
    linear = tonemap_inverse(fr["display"], exposure=fr["exposure"], method=p.tone_mapper)
    linear = np.where(fr["unchanged"][..., None], fr["linear0"], linear).astype(np.float32)
    n_s = len(MODES[p.mode][0])
    costs = _costs(p, n_pix, fetches)
    smaa_bytes = sum(costs["buffers"].values())
    scene_pass = n_pix * n_s * (2 * 4 + 4)  # depth read + write, colour write per sample
    result = package(
        NAME,
        scene,
        p,
        color=linear,
        coverage=fr["coverage"],
        offsets=np.array([s[0] for s in MODES[p.mode][-1]]),
        events=fr["events"],
        extra_outputs={"smaa_edges": fr["edges"].any(axis=-1)},
        samples=n_s,
        buffers={"color": n_pix * 4 * n_s, "depth": n_pix * 4 * n_s},
        resolve_target_bytes=n_pix * 4,
        geometry_passes=1,
        samples_tested=n_pix * n_s,
        bandwidth_bytes=int(
            scene_pass + costs["texture_bytes_per_pixel"] * n_pix + n_pix * (2 + 4 + 4) * n_s
        ),
        shadow_rays=fr["rays"] // len(MODES[p.mode]),
        diagnostics={
            "mode": p.mode,
            "settings": cfg,
            "sample_positions": [[list(s[0]) for s in f] for f in MODES[p.mode]],
            "subsample_indices": [[list(s[1]) for s in f] for f in MODES[p.mode]],
            "velocity": "static camera: zero motion vectors (temporal-AA motion vectors not "
            "available yet); reprojection weight 0.5",
            "tone_mapping": {
                "exposure_stops": fr["exposure"],
                "tone_mapper": p.tone_mapper,
                "exposure_key": p.exposure_key,
                "encoding": "sRGB (IEC 61966-2-1), clipped to [0, 1]",
            },
            "pixels_changed": int((~fr["unchanged"]).sum()),
        },
        t0=t0,
    )
    cost = result.cost
    for k, v in costs["buffers"].items():
        cost["framebuffer_bytes_by_buffer"][f"smaa_{k}"] = int(v)
    cost["framebuffer_bytes"] += int(smaa_bytes)
    cost["smaa_passes"] = costs["passes"]
    cost["texture_fetches_per_pixel"] = costs["texture_fetches_per_pixel"]
    cost["texture_fetches_per_pixel_by_pass"] = costs["texture_fetches_per_pixel_by_pass"]
    cost["texture_bytes_per_pixel"] = costs["texture_bytes_per_pixel"]
    result.outputs["color_display"] = fr["display"]
    result.outputs["front_coverage"] = np.asarray(fr["front_coverage"], np.float32)
    return result
