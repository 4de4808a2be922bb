"""Accumulative anti-aliasing (ACAA): a depth prepass at N samples, then one shading pass
that blends each fragment, weighted by its post-depth coverage, into a 1x colour target.

1. Depth prepass (depth test LESS) at the ``N`` standard positions: the nearest surface's
   depth per sample, stored in ``depth_format`` (D24 UNORM or D32F of the D3D-style
   ``[0, 1]`` depth ``f/(f-n) (1 - n/z)``; orthographic ``(z-n)/(f-n)``).
2. Shading pass, depth test LEQUAL, depth writes off: every fragment (primitive, pixel) is
   shaded once (pixel centre on its plane, or centroid, as :mod:`.msaa`) and added to the
   colour target with weight ``popcount(post-depth coverage) / N``, in submission order
   (shape, then primitive index). A fragment passes at a sample when its stored-format depth
   equals the prepass value there: the nearest surface, and any surface of another shape
   lying at the same quantized depth (coplanar decals, duplicated geometry), which is
   therefore counted twice, too bright, as on GPUs. The surfaces at each sample are found
   per shape: one ray per sample into a scene holding a group of shapes whose bounding
   boxes are too far apart to tie (:func:`tie_groups`; the hit there is the hit of a scene
   holding that shape alone wherever a tie is possible), traced only from samples whose
   nearest hit lies within a tie distance of a member's bounding box
   (:mod:`._acaa_ties`; the others cannot tie with the group); two coplanar triangles of
   one mesh are not told apart.
3. ``accumulation="rgba8"`` rounds the target to 8-bit UNORM (``round(255 x) / 255`` of the
   saturated sum) at every addition; ``float32`` adds in float32.

Where no depths tie the result equals :mod:`.msaa`'s box resolve up to float32 summation
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

from ... import depth as _depth
from ... import params as _params
from .. import samples as _samples
from ..common import DEPTH_FORMATS, ShadowParams, check_shadows, package, shadow_visibility
from ..trace import fragment_attributes, shade_points
from . import trace as _acaa_trace
from .groups import group_scenes, normalized_depth, tie_distance, tie_groups

__all__ = ["ACCUMULATIONS", "AcaaParams", "rgba8_accumulate", "run"]

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


def _stored_depth(camera, view_depth, valid, fmt: str) -> np.ndarray:
    """Depth as stored in ``fmt`` where ``valid``; 2 (behind everything) elsewhere."""
    z = normalized_depth(camera, np.where(valid, view_depth, camera.far))
    return np.where(valid, _depth.quantize(z, fmt), 2.0)


def rgba8_accumulate(values: np.ndarray, slot: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Blend ``values`` (F, 3) additively into ``target`` (P, 3) at ``slot`` (F,) pixels, one
    blend at a time per pixel (fragments of one pixel in order), rounding the saturated sum
    to 8-bit UNORM after each addition. Returns the target (float64, multiples of 1/255)."""
    return _blend(values, slot, target, rgba8=True)


def _blend(values, pixel, target, *, rgba8: bool, grouped: bool = False):
    """Blend of ``values`` into ``target`` (an array, or a pixel count: a zero target) in
    the order of :func:`rgba8_accumulate` (float32, or RGBA8 rounding in float64);
    ``grouped``: each pixel's values are already contiguous (in their order)."""
    values = np.asarray(values, np.float64 if rgba8 else np.float32)
    dtype = np.float64 if rgba8 else np.float32
    zero = isinstance(target, (int, np.integer))
    out = np.zeros((target, 3), dtype) if zero else np.array(target, dtype=dtype)
    pixel = np.asarray(pixel, np.int64)
    if len(pixel) == 0:
        return out
    if not grouped and np.any(pixel[1:] < pixel[:-1]):
        order = np.argsort(pixel, kind="stable")
        values, pixel = values[order], pixel[order]
    # one run a pixel: blend j adds each pixel's j-th value (its rank within its run); the
    # running sums are kept per run and written to the target once
    start = np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])
    run = np.diff(np.r_[start, len(pixel)])
    values = np.ascontiguousarray(values)
    acc = None
    for j in range(int(run.max())):  # one round per blend of the busiest pixel
        sel = np.flatnonzero(run > j) if j else slice(None)
        if acc is None:  # first blend: onto zeros (+0: the same addition) or the target
            s = (dtype(0.0) if zero else _take_rows(out, pixel[start])) + _take_rows(values, start)
        else:
            s = acc[sel] + _take_rows(values, start[sel] + j)
        if rgba8:
            s = np.floor(np.clip(s, 0.0, 1.0) * 255.0 + 0.5) / 255.0
        if acc is None:
            acc = s
        else:
            acc[sel] = s
    _rows(out)[pixel[start]] = _rows(np.ascontiguousarray(acc))
    return out


def _rows(a: np.ndarray) -> np.ndarray:
    """A C-contiguous ``(N, K)`` array as ``N`` opaque rows (fast row gathers/scatters)."""
    return a.view(np.dtype((np.void, a.itemsize * a.shape[1]))).reshape(len(a))


def _take_rows(a: np.ndarray, rows) -> np.ndarray:
    """``a[rows]`` for a C-contiguous ``(N, K)`` array (the same bytes, row by row)."""
    return _rows(a)[rows].view(a.dtype).reshape(-1, a.shape[1])


def _fragments(near: dict, ties: list, offsets, n_pix: int, centroid: bool) -> dict:
    """Fragments passing LEQUAL: the nearest surface's (``near``, one row per fragment in
    pixel order, from :func:`._acaa_trace.prepass`) merged with the tie samples ``(pixel,
    sample, shape, prim)`` of other shapes.

    Fragments are in pixel order and, within a pixel, in submission order (shape, then
    primitive); each with its first passing sample, its passing-sample count and, with
    ``centroid``, the sums of their positions. Only the pixels holding ties or several
    fragments are sorted and merged; their fragments are then inserted among the others.
    (The order matters beyond the blend: a ray's hit can depend on the rays traced beside
    it in a packet, so the fragments keep the order in which they have always been shaded.)
    """
    offs = np.asarray(offsets, np.float64)
    sums = ("sum_x", "sum_y") if centroid else ()
    keys = ("pixel", "sample", "shape", "prim", "count", *sums)
    pix = near["pixel"]
    busy = np.zeros(n_pix, bool)  # pixels with more than one entry
    busy[pix[1:][pix[1:] == pix[:-1]]] = True
    for t in ties:
        busy[t[0]] = True
    if not busy.any():
        return {key: near[key] for key in keys if key != "prim"}
    moved = busy[pix]
    keep = ~moved
    parts = {key: [near[key][moved]] for key in keys}
    for tpix, smp, shape, prim in ties:
        cols = (tpix, smp, shape, prim)
        for key, val in zip(("pixel", "sample", "shape", "prim"), cols, strict=True):
            parts[key].append(np.asarray(val, np.int64))
        parts["count"].append(np.ones(len(tpix), np.int64))
        for axis, key in enumerate(sums):
            parts[key].append(offs[smp, axis])
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
    # the pixels of the two parts are disjoint: insert the merged ones in pixel order
    at = np.searchsorted(pix[keep], merged["pixel"])
    return {key: np.insert(near[key][keep], at, merged[key]) for key in merged}


def _ties(cam, candidates: list, window: float, fmt: str) -> list:
    """Tie samples ``(pixel, sample, shape, prim)`` of each group from its candidates' hits
    (:func:`._acaa_trace.prepass`): a hit within the tie window whose stored depth passes
    LEQUAL against the prepass's."""
    found = []
    for pix, smp, depth, hit, hit_depth, hit_shape, hit_prim in candidates:
        near = hit.copy()
        if np.isfinite(window):  # equal stored depths lie within the tie distance
            near &= hit_depth <= depth + np.float32(window)
        ci = np.flatnonzero(near)
        one = np.ones(len(ci), bool)
        zk = _stored_depth(cam, hit_depth[ci], one, fmt)
        ci = ci[zk <= _stored_depth(cam, depth[ci], one, fmt)]
        if len(ci):
            found.append((pix[ci], smp[ci], hit_shape[ci], hit_prim[ci]))
    return found


def _shade_with(scene, groups, subs, f_shape, sx, sy, cx, cy, shadows: str):
    """Fragment colours with a shadow technique's visibility (attributes copied to NumPy for
    the technique). Returns ``(rgb, shadow_rays)``."""
    attrs = None
    for members, sub in zip(groups, subs, strict=True):  # each fragment in its group's scene
        sel = np.nonzero(np.isin(f_shape, members))[0]
        if len(sel) == 0:
            continue
        a = fragment_attributes(scene, sx[sel], sy[sel], cx[sel], cy[sel], mi_scene=sub)
        if attrs is None:
            attrs = {key: np.zeros((len(f_shape),) + v.shape[1:], v.dtype) for key, v in a.items()}
        for key, v in a.items():
            attrs[key][sel] = v
    vis = shadow_visibility(scene, attrs, shadows)
    return shade_points(scene, attrs, visibility=vis)


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
    ties_found = _ties(cam, pre["candidates"], window, p.depth_format)
    frag = _fragments(pre["near"], ties_found, offsets, n_pix, p.centroid)
    f_pix, f_smp, f_shape, count = frag["pixel"], frag["sample"], frag["shape"], frag["count"]
    n_frag = len(f_pix)
    # shading positions (centre, or centroid of the fragment's passing samples)
    target = np.zeros((n_pix, 3), np.float32)
    rays = 0
    if n_frag:
        centre = None
        if p.centroid or p.shadows != "exact":
            fx, fy = f_pix % w, f_pix // w
        if p.centroid:
            partial = count < n
            centre = (
                np.where(partial, fx + frag["sum_x"] / count, fx + 0.5),
                np.where(partial, fy + frag["sum_y"] / count, fy + 0.5),
            )
        if p.shadows == "exact":
            rgb, rays = _acaa_trace.shade_exact(scene, groups, subs, frag, offsets, centre)
        else:
            sx, sy = fx + offsets[f_smp, 0], fy + offsets[f_smp, 1]
            cx, cy = centre if centre is not None else (fx + 0.5, fy + 0.5)
            rgb, rays = _shade_with(scene, groups, subs, f_shape, sx, sy, cx, cy, p.shadows)
        weighted = rgb * (count / np.float32(n)).astype(np.float32)[:, None]
        rgba8 = p.accumulation == "rgba8"
        target = _blend(weighted, f_pix, n_pix, rgba8=rgba8, grouped=True)
    events = np.bincount(f_pix, minlength=n_pix)
    # samples with at least one tie (a sample may tie with several groups)
    keys = [pix * n + smp for pix, smp, _, _ in ties_found]
    tie_keys = np.unique(np.concatenate(keys)) if keys else np.zeros(0, np.int64)
    ties = np.bincount(tie_keys // n, minlength=n_pix)
    db = DEPTH_FORMATS[p.depth_format]
    cb = ACCUMULATIONS[p.accumulation]
    return package(
        NAME,
        scene,
        p,
        color=target.reshape(h, w, 3),
        coverage=np.bincount(pre["near"]["pixel"], pre["near"]["count"], n_pix) / n,
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
            "per_shape_rays": int(pre["traced"]),
            "tie_groups": len(groups),
            "color_target_bytes_per_pixel": cb,
        },
        t0=t0,
    )
