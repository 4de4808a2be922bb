"""The ``smaa`` technique: SMAA 1x, T2x, S2x and 4x as ``SMAA.hlsl`` describes them, in display
space like ``fxaa`` (:mod:`..fxaa`).

Each sample image (one sample per pixel at the mode's position) is the oracle's shading
(one sample at a jittered position: ``trace.sample_colors``; the two samples of 2x MSAA with
the D3D standard pattern: ``msaa.multisample``, shaded once per primitive at the pixel
centre), tone-mapped by the project's pipeline (:func:`scenes.base.display.tonemap`, exposure
from the model's own sample-averaged image, as ``fxaa``) to gamma-encoded values in [0, 1]
where SMAA's thresholds are defined, and stored as the engine stores it (``input``:
``rgba8-srgb``, the demo's ``R8G8B8A8_UNORM_SRGB`` scene target, rounded to 1/255; edge
detection reads these gamma values, neighbourhood blending reads them decoded to linear
through the sRGB view and writes an 8-bit sRGB target; ``float``: unquantized, as before
issue 36). SMAA 1x runs its three passes on it
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
T2x and 4x resolve the scene's frame k (current, the table's frame k mod 2) with its frame
k - 1 (previous, frame (k + 1) mod 2), in the demo's phase: its ``SMAA`` starts at
``frameIndex(0)`` (iryoku/smaa 71c806a ``Demo/DX10/Code/SMAA.cpp``:110), renders frame 0 with
``getJitter``/``getSubsampleIndex`` of index 0 (:680-683, :703: the header's S0, ``SMAA.hlsl``
:220) and steps the index only after the frame (``Demo.cpp``:904 ``nextFrame``, SMAA.cpp:591),
as the demo's ``runSMAA`` does: the previous frame's
SMAA output, point-fetched at texcoord - velocity, weighted down where the packed velocity
lengths differ (``SMAAResolvePS``, ``SMAA_REPROJECTION``). The velocity buffer is what the
demo's scene pass writes (RG16F, texture units, current minus previous position of the
surface point under each sample, jitter excluded): the oracle's film motion
(:func:`scenes.geometry.motion.film_motion`) at the sample, MSAA-resolved for S2x/4x. A
still scene is its own previous frame: zero velocity, weight 0.5, the plain average
(``diagnostics["velocity"]`` says which).

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
from ....scenes.geometry.motion import film_motion
from .. import msaa as _msaa
from ..common import package
from ..trace import sample_colors, trace_samples
from ._sampling import Fetches
from .blending import neighborhood_blend, resolve, to_unorm8
from .edges import detect_edges
from .params import INPUT_8BIT, MODES, SmaaParams, resolved
from .weights import blending_weights

__all__ = ["NAME", "color_buffer", "hardware_depth", "run", "smaa_1x"]

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
    display: np.ndarray,
    cfg: dict,
    indices,
    *,
    depth=None,
    extra=None,
    match=None,
    velocity=None,
    fetches=None,
):
    """SMAA 1x on one gamma-encoded image with sub-sample ``indices``; ``cfg``:
    :func:`.params.resolved` (``input`` ``rgba8-srgb``: ``display`` holds the 8-bit buffer's
    values k/255 and the output is written to an RGBA8 target). Returns
    :func:`.blending.neighborhood_blend`'s dict plus ``edges`` and ``weights``."""
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
        display,
        wts,
        srgb=cfg["srgb_blending"],
        extra=extra,
        match=match,
        velocity=velocity,
        unorm8=cfg["input"] == INPUT_8BIT,
        fetches=fetches,
    )
    out["edges"] = edges
    out["weights"] = wts
    return out


def color_buffer(display: np.ndarray, cfg: dict) -> np.ndarray:
    """The scene colour buffer SMAA reads: the tone-mapped, gamma-encoded image as the
    engine stores it (``rgba8-srgb``: rounded to k/255, the bytes an ``R8G8B8A8_UNORM_SRGB``
    render target holds; ``float``: as computed)."""
    d = np.asarray(display, np.float32)
    if cfg["input"] != INPUT_8BIT:
        return d
    return to_unorm8(d)


def hardware_depth(camera, view_depth: np.ndarray, valid: np.ndarray) -> np.ndarray:
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


def _still(scene) -> bool:
    """True where the scene is its own previous frame (no camera, light or object path)."""
    return scene.camera_path is None and scene.light_path is None and not scene.object_motion


def _velocity(scene, offsets: np.ndarray) -> np.ndarray | None:
    """The frame's velocity buffer as the demo's scene pass writes it (RG16F, texture units,
    current minus previous position of the surface point under each sample, the same jitter
    in both matrices), MSAA-resolved (the mean of the samples); None for a still scene."""
    if _still(scene):
        return None
    h, w = scene.height, scene.width
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    vel = np.zeros((h, w, 2))
    for ox, oy in offsets:
        m = film_motion(scene, x + ox, y + oy, disocclusion=False)
        vel[..., 0] -= m["motion_x"].reshape(h, w) / w
        vel[..., 1] -= m["motion_y"].reshape(h, w) / h
    return (vel / len(offsets)).astype(np.float16).astype(np.float64)


def _render(scene, frame_spec, need_depth: bool, want_velocity: bool) -> dict:
    """One frame of the mode rendered: its samples, depth, ids and velocity buffer."""
    h, w = scene.height, scene.width
    offsets = np.array([s[0] for s in frame_spec])
    col, valid, extra = _frame_samples(scene, offsets)
    tr = trace_samples(scene, offsets, keep=("valid", "shape", "depth"))
    centre = trace_samples(scene, np.array([[0.5, 0.5]]), keep=("shape",))["shape"]
    depth = None
    if need_depth:
        depth = [
            hardware_depth(scene.camera, tr["depth"][:, i], tr["valid"][:, i]).reshape(h, w)
            for i in range(len(offsets))
        ]
    return {
        "col": col,
        "valid": valid,
        "rays": extra["rays"],
        "events": extra["events"],
        "depth": depth,
        "shape": [tr["shape"][:, i].reshape(h, w) for i in range(len(offsets))],
        "centre": centre.reshape(h, w),
        "velocity": _velocity(scene, offsets) if want_velocity else None,
        "indices": [s[1] for s in frame_spec],
    }


def _smaa_frame(rf: dict, exposure: float, p, cfg: dict, fetches) -> dict:
    """SMAA on every sample of one rendered frame, the samples combined (S2x's 0.5 blend)."""
    outs = []
    for i, indices in enumerate(rf["indices"]):
        disp = color_buffer(tonemap(rf["col"][i], exposure=exposure, method=p.tone_mapper), cfg)
        outs.append(
            smaa_1x(
                disp,
                cfg,
                indices,
                depth=None if rf["depth"] is None else rf["depth"][i],
                extra={"coverage": rf["valid"][i].astype(np.float32)},
                match={"front_coverage": (rf["shape"][i], rf["centre"])},
                velocity=rf["velocity"],
                fetches=fetches,
            )
        )
    return _combine_samples(outs, cfg)


def _run_frames(scene, p, cfg, fetches):
    """Every frame of the mode: SMAA per sample, samples combined, and for T2x / 4x the
    resolve of this frame with the previous one; returns a dict."""
    frames = MODES[p.mode]
    need_depth = cfg["edge_detection"] == "depth" or cfg["predication"]
    temporal = len(frames) == 2
    # T2x / 4x: frame k is the current frame (sub-sample set k mod 2: the demo's frameIndex
    # starts at 0 and steps after each frame), frame k - 1 the previous one ((k + 1) mod 2);
    # a still scene is its own previous frame
    k = int(getattr(scene, "frame", 0) or 0)
    if temporal:
        cur_spec, prev_spec = frames[k % 2], frames[(k + 1) % 2]
        scenes_ = [scene.previous(), scene]  # a still scene is its own previous frame
        specs = [prev_spec, cur_spec]
    else:
        scenes_, specs = [scene], frames
    moving = temporal and not _still(scene)
    rendered = [_render(sc, sp, need_depth, moving) for sc, sp in zip(scenes_, specs, strict=True)]
    exposure = exposure_from_reference(np.mean([r["col"].mean(axis=0) for r in rendered], axis=0))
    first = rendered[0]["col"][0]
    unchanged = np.ones(first.shape[:2], bool)
    results = []
    for rf in rendered:
        res = _smaa_frame(rf, exposure, p, cfg, fetches)
        unchanged &= ~res["blended"] & np.all(rf["col"] == first, axis=(0, -1))
        results.append(res)
    final = results[-1]
    if temporal:
        final = _resolve(results[1], results[0], rendered[1]["velocity"], cfg, fetches)
    return {
        "display": final["color"],
        "coverage": final["coverage"],
        "front_coverage": final["front"],
        "unchanged": unchanged,
        "linear0": first,
        "edges": results[0]["edges"],
        "weights": results[0]["weights"],
        "exposure": exposure,
        "rays": sum(r["rays"] for r in rendered),
        "events": rendered[-1]["events"],  # the frame rendered for this display
        "valid": np.mean([r["valid"].mean(axis=0) for r in rendered], axis=0),
        "moving": moving,
        "temporal": temporal,
        "frame_set": k % 2 if temporal else 0,
    }


def _resolve(cur: dict, prev: dict, velocity, cfg: dict, fetches) -> dict:
    """``SMAAResolvePS``: the current frame with the previous one reprojected by the current
    velocity buffer; colour through the sRGB views for 8-bit input (linear-light mix)."""
    stack = [np.concatenate([r["color"], r["coverage"][..., None], r["front"][..., None]], -1)
             for r in (cur, prev)]  # fmt: skip
    eight = cfg["input"] == INPUT_8BIT
    out = resolve(
        stack[0],
        stack[1],
        alpha_current=cur["alpha"],
        alpha_previous=prev["alpha"],
        velocity=velocity,
        weight_scale=cfg["reprojection_weight_scale"],
        srgb=eight and cfg["srgb_blending"],
        unorm8=eight,
        fetches=fetches,
    )
    return {"color": out[..., :3], "coverage": out[..., 3], "front": out[..., 4]}


def _combine_samples(outs: list[dict], cfg: dict) -> dict:
    """S2x: the second sample's SMAA output alpha-blended (0.5) over the first's in the
    target (in linear light when the target is sRGB, then written: rounded to 1/255 for an
    RGBA8 target); one sample: itself."""
    if len(outs) == 1:
        return {**outs[0], "front": outs[0]["front_coverage"]}
    srgb, eight = cfg["srgb_blending"], cfg["input"] == INPUT_8BIT
    if eight:
        dest = srgb_decode(outs[0]["color"]) if srgb else outs[0]["color"]
        mixed = 0.5 * dest + 0.5 * outs[1]["linear"]
        color = srgb_encode(mixed) if srgb else mixed
        color = to_unorm8(color)
    else:
        cols = np.stack([o["color"] for o in outs])
        color = srgb_encode(srgb_decode(cols).mean(axis=0)) if srgb else cols.mean(axis=0)
    return {
        "color": color.astype(np.float32),
        "coverage": np.mean([o["coverage"] for o in outs], axis=0).astype(np.float32),
        "front": np.mean([o["front_coverage"] for o in outs], axis=0).astype(np.float32),
        # the blend state's alpha defaults (ONE, ZERO): the last pass's packed velocity
        "alpha": outs[-1]["alpha"],
        "blended": outs[0]["blended"] | outs[1]["blended"],
        "edges": outs[0]["edges"],
        "weights": outs[0]["weights"],
    }


def _velocity_note(fr: dict) -> str:
    if not fr["temporal"]:
        return "no temporal resolve in this mode (1x, S2x): no velocity buffer"
    if fr["moving"]:
        return (
            "film motion of the current frame's samples (scenes.geometry.motion), RG16F "
            "texture units; the resolve reprojects the previous frame by it"
        )
    return "still scene: zero motion vectors; reprojection weight 0.5"


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
        buffers["velocity"] = 4 * n_pix  # the scene pass's velocity target, RG16F
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
        offsets=np.array([s[0] for s in MODES[p.mode][fr["frame_set"]]]),
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
            "current_frame_set": fr["frame_set"],
            "velocity": _velocity_note(fr),
            "input": cfg["input"],
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
