"""Accumulative anti-aliasing (ACAA): a depth prepass at N samples, then one shading pass
that blends each fragment, weighted by its post-depth coverage, into a 1x colour target.

1. Depth prepass (depth test LESS) at the ``N`` standard positions: the nearest surface's
   depth per sample, stored in ``depth_format`` (D24 UNORM or D32F of the D3D-style
   ``[0, 1]`` depth ``f/(f-n) (1 - n/z)``; orthographic ``(z-n)/(f-n)``).
2. Shading pass, depth test LEQUAL, depth writes off: every fragment (primitive, pixel) is
   shaded once (pixel centre on its plane, or centroid, as :mod:`..msaa`) and added to the
   colour target with weight ``popcount(post-depth coverage) / N``, in submission order
   (shape, then primitive index). Both passes compare the depth a rasterizer computes
   (:mod:`.plane`): the primitive's screen-space depth plane, set up in float32 from its
   window-space vertices and evaluated at the sample, stored in ``depth_format``. The
   prepass keeps the lowest stored value; a fragment passes at a sample when its stored
   depth equals it. Surfaces of other shapes lying at the same stored depth (coplanar
   decals, duplicated geometry) pass too and are counted twice, too bright, as on GPUs;
   where another surface's plane stores a lower value than the ray-nearest surface's, only
   that one passes (z-fighting: coplanar triangles with their own vertices tie on some
   samples, not all). The surfaces at each sample are found per shape: one ray per sample
   into a scene holding a group of shapes whose bounding boxes are too far apart to tie
   (:func:`tie_groups`; the hit there is the hit of a scene holding that shape alone
   wherever a tie is possible), traced only from samples whose nearest hit lies within a
   tie distance of a member's bounding box (:mod:`.ties`; the others cannot tie with the
   group); two coplanar triangles of one mesh are not told apart. Shading events are the
   fragments passing (draw order and LEQUAL), not the ray tracer's nearest hits.
3. ``accumulation="rgba8"`` rounds the target to 8-bit UNORM (``round(255 x) / 255`` of the
   saturated sum) at every addition; ``float32`` adds in float32. NVIDIA's BlendedAA sample
   (GameWorks OpenGL samples, gl4-maxwell/BlendedAA.cpp) renders exactly so: a
   ``GL_DEPTH_COMPONENT24`` multisampled depth buffer, a z prepass with ``GL_LESS``, then
   ``GL_LEQUAL`` with depth writes off, ``glBlendFunc(GL_ONE, GL_ONE)`` additive blending
   with coverage modulation (the fragment scaled by its passing-sample fraction) into a
   single-sample ``GL_RGBA`` (linear 8-bit UNORM) target cleared to 0: the
   ``depth_format="D24", accumulation="rgba8"`` configuration.

Where no depths tie the result equals :mod:`..msaa`'s box resolve up to float32 summation
order. Memory = N x depth + one colour per pixel.

References
----------
E. Enderton, E. Lum, C. Rouet, O. Kouznetsov, Accumulative Anti-Aliasing, NVIDIA (HPG 2015
poster); NVIDIA GameWorks OpenGL samples, "Blended Anti-Aliasing".
C. Wyman, High-quality rasterization (NVIDIA slides, 2015): ACAA caveats (z-fighting).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ... import params as _params
from .. import samples as _samples
from ..common import DEPTH_FORMATS, ShadowParams, check_shadows, package, shadow_visibility
from . import trace as _acaa_trace
from .blend import blend
from .groups import group_scenes, tie_distance, tie_groups
from .plane import depth_tests

__all__ = ["ACCUMULATIONS", "AcaaParams", "find_ties", "merge_fragments", "run"]

NAME = "acaa"
#: Accumulation target formats and their bytes per pixel.
ACCUMULATIONS = {"float32": 16, "rgba8": 4}


@dataclass(frozen=True)
class AcaaParams(ShadowParams):
    """Parameters of :func:`run`."""

    samples: int = _params.param(
        8,
        source="NVIDIA HQ rasterization slides (Wyman 2015): ACAA at 8x",
        help="depth samples per pixel at the standard positions: 1, 2, 4, 8 or 16",
        lo=1,
        hi=16,
    )
    depth_format: str = _params.param(
        "D24",
        source="Wyman 2015 slides: z-fighting 'usually not an issue at 24-bit depths'",
        help="prepass depth format (D24 UNORM or D32F); ties are equal stored values",
        choices=tuple(DEPTH_FORMATS),
    )
    accumulation: str = _params.param(
        "float32",
        source="issue 9: float accumulation (RGBA8 as an option, rounding every addition)",
        help="colour target: float32 or rgba8 (linear UNORM, rounded at every blend)",
        choices=tuple(ACCUMULATIONS),
    )
    centroid: bool = _params.param(
        False,
        source="hardware default: attributes at the pixel centre",
        help="shade at the centroid of a fragment's covered samples",
    )

    def check(self, technique: str) -> None:
        _samples.check_standard_count(technique, self.samples)


def merge_fragments(
    near: dict, ties: list, offsets, n_pix: int, centroid: bool, losses=None
) -> dict:
    """Fragments passing LEQUAL: the nearest surface's (``near``, one row per fragment in
    pixel order, from :func:`.trace.prepass`) merged with the tie samples ``(pixel,
    sample, shape, prim)`` of other shapes, less the ``losses`` (samples ``(pixel,
    sample, shape, prim)`` where the nearest surface's rasterized depth lost to another's).

    Fragments are in pixel order and, within a pixel, in submission order (shape, then
    primitive); each with its first sample (a lost one may stay its representative: the
    ray through it still meets the fragment's surface), its passing-sample count and, with
    ``centroid``, the sums of their positions; a fragment left with no passing sample is
    dropped. Only the pixels holding ties, losses or several fragments are sorted and
    merged; their fragments are then inserted among the others. (The order matters beyond
    the blend: a ray's hit can depend on the rays traced beside it in a packet, so the
    fragments keep the order in which they have always been shaded.)
    """
    offs = np.asarray(offsets, np.float64)
    sums = ("sum_x", "sum_y") if centroid else ()
    keys = ("pixel", "sample", "shape", "prim", "count", *sums)
    pix = near["pixel"]
    busy = np.zeros(n_pix, bool)  # pixels with more than one entry
    busy[pix[1:][pix[1:] == pix[:-1]]] = True
    extra = [(t, 1) for t in ties]
    if losses is not None and len(losses[0]):
        extra.append((losses, -1))
    for t, _ in extra:
        busy[t[0]] = True
    if not busy.any():
        return {key: near[key] for key in keys if key != "prim"}
    moved = busy[pix]
    keep = ~moved
    parts = {key: [near[key][moved].astype(np.int64 if key == "count" else None)] for key in keys}
    for (tpix, smp, shape, prim), sign in extra:
        cols = (tpix, smp, shape, prim)
        for key, val in zip(("pixel", "sample", "shape", "prim"), cols, strict=True):
            parts[key].append(np.asarray(val, np.int64))
        parts["count"].append(np.full(len(tpix), sign, np.int64))
        for axis, key in enumerate(sums):
            parts[key].append(sign * offs[smp, axis])
    e = {key: np.concatenate(val) for key, val in parts.items()}
    order = np.lexsort((e["sample"], e["prim"], e["shape"], e["pixel"]))
    e = {key: val[order] for key, val in e.items()}
    bpix, shape, prim = e["pixel"], e["shape"], e["prim"]
    new = np.ones(len(bpix), bool)
    new[1:] = (bpix[1:] != bpix[:-1]) | (shape[1:] != shape[:-1]) | (prim[1:] != prim[:-1])
    first = np.flatnonzero(new)
    merged = {key: e[key][first] for key in ("pixel", "sample", "shape")}
    for key in ("count", *sums):
        merged[key] = np.add.reduceat(e[key], first)
    alive = merged["count"] > 0
    merged = {key: val[alive] for key, val in merged.items()}
    merged["count"] = merged["count"].astype(near["count"].dtype)
    # the pixels of the two parts are disjoint: insert the merged ones in pixel order
    at = np.searchsorted(pix[keep], merged["pixel"])
    return {key: np.insert(near[key][keep], at, merged[key]) for key in merged}


def find_ties(scene, candidates: list, window: float, fmt: str, offsets) -> dict:
    """The LEQUAL shading pass at the samples where another group's surface can tie with
    the nearest one (:func:`.plane.depth_tests` on :func:`.trace.prepass`'s candidates):
    the prepass (LESS) stores the lowest rasterized depth, and every surface storing it
    passes.

    Returns a dict: ``ties``, a list of ``(pixel, sample, shape, prim)`` arrays of the other
    groups' surfaces passing; ``losses``, the same of the samples where the nearest surface
    fails (another stores a lower depth), None when there is no candidate; ``tie_keys``,
    ``pixel * N + sample`` of the samples where two or more surfaces pass (sorted, unique).
    """
    t = depth_tests(scene, candidates, window, fmt, offsets)
    if t is None:
        return {"ties": [], "losses": None, "tie_keys": np.zeros(0, np.int64)}
    pix, smp, h_shape, h_prim = t["rows"]
    passes = t["q_hit"] <= t["low"][t["inv"]]
    near_passes = t["q_near"] <= t["low"]
    count = near_passes + np.bincount(t["inv"], weights=passes, minlength=len(t["low"]))
    lost = t["first"][~near_passes]
    n_shape, n_prim = t["near"]  # per sample
    return {
        "ties": [(pix[passes], smp[passes], h_shape[passes], h_prim[passes])],
        "losses": (pix[lost], smp[lost], n_shape[~near_passes], n_prim[~near_passes]),
        "tie_keys": t["keys"][count >= 2],
    }


def run(scene, params: AcaaParams | None = None, **kwargs):
    """Run ``acaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, AcaaParams, kwargs)
    check_shadows(scene, p.shadows)
    offsets = _samples.positions(p.samples)
    n = p.samples
    w, h = scene.width, scene.height
    n_pix = w * h
    cam = scene.camera
    groups = tie_groups(scene, p.depth_format)
    subs = group_scenes(scene, groups)
    pre = _acaa_trace.prepass(scene, offsets, groups, subs, p.depth_format, centroid=p.centroid)
    # the largest tie distance (at the far plane): a view-depth bound on every tie
    window = float(tie_distance(cam, cam.far, p.depth_format))
    found = find_ties(scene, pre["candidates"], window, p.depth_format, offsets)
    frag = merge_fragments(
        pre["near"], found["ties"], offsets, n_pix, p.centroid, losses=found["losses"]
    )
    f_pix, count = frag["pixel"], frag["count"]
    n_frag = len(f_pix)
    # shading positions (centre, or centroid of the fragment's passing samples)
    target = np.zeros((n_pix, 3), np.float32)
    rays = 0
    if n_frag:
        centre = None
        if p.centroid:
            fx, fy = f_pix % w, f_pix // w
            partial = count < n
            centre = (
                np.where(partial, fx + frag["sum_x"] / count, fx + 0.5),
                np.where(partial, fy + frag["sum_y"] / count, fy + 0.5),
            )
        visibility = None
        if p.shadows != "exact":

            def visibility(attrs):
                return shadow_visibility(scene, attrs, p.shadows)

        rgb, rays = _acaa_trace.shade(
            scene, groups, subs, frag, offsets, centre, visibility=visibility
        )
        weighted = rgb * (count / np.float32(n)).astype(np.float32)[:, None]
        rgba8 = p.accumulation == "rgba8"
        target = blend(weighted, f_pix, n_pix, rgba8=rgba8, grouped=True)
    events = np.bincount(f_pix, minlength=n_pix)
    # samples where two or more surfaces pass LEQUAL
    tie_keys = found["tie_keys"]
    ties = np.bincount(tie_keys // n, minlength=n_pix)
    lost = 0 if found["losses"] is None else len(found["losses"][0])
    db = DEPTH_FORMATS[p.depth_format]
    cb = ACCUMULATIONS[p.accumulation]
    return package(
        NAME,
        scene,
        p,
        color=target.reshape(h, w, 3),
        coverage=np.bincount(pre["near"]["pixel"], pre["near"]["count"], n_pix) / n,
        offsets=offsets,
        events=events,
        extra_outputs={"ties": ties},
        samples=n,
        buffers={"color": n_pix * cb, "depth": n_pix * n * db},
        resolve_target_bytes=0,
        geometry_passes=2,
        samples_tested=2 * n_pix * n,
        bandwidth_bytes=n_pix * n * 2 * db + n_pix * n * db + n_frag * 2 * cb,
        shadow_rays=rays,
        diagnostics={
            "sample_positions": offsets.tolist(),
            "fragments": int(n_frag),
            "tie_samples": len(tie_keys),
            "pixels_with_ties": int((ties > 0).sum()),
            "lost_samples": int(lost),
            "per_shape_rays": int(pre["traced"]),
            "tie_groups": len(groups),
            "color_target_bytes_per_pixel": cb,
        },
        t0=t0,
    )
