"""Ray work of ACAA on the Dr.Jit side: the depth prepass with its tie search, and the
shading of fragments with exact shadow rays, copying back only compact results.

- :func:`prepass`: per launch of :data:`..trace.CHUNK` rays, one kernel tracing every
  sample (nearest surface, as :func:`..trace.trace_samples`) and testing which samples can
  tie with each group (:mod:`.ties`); one lane a pixel then groups its samples into
  fragments; each group's candidates are compressed and traced against the group's scene.
  NumPy receives the nearest fragments (one row each) and the hits of the tie candidates,
  never the ``(P, N)`` sample arrays.
- :func:`shade`: fragment attributes (:func:`..trace.attributes_dr`) and the oracle's
  shading with an exact shadow ray (:func:`..trace.shade_dr`) in one kernel per group and
  launch; with a shadow technique's visibility, the same kernels with the attributes copied
  to NumPy once for the technique (:func:`..trace.fragment_attributes`,
  :func:`..trace.shade_points`).
"""

from __future__ import annotations

import numpy as np

from ....scenes import backend
from ....scenes.backend.alpha_hit import loaded_alpha, scene_hit
from ....scenes.backend.kernels import evaluate_trace
from ....scenes.backend.raycast import camera_rays_dr, shape_table
from .. import pixel_dr as _pixel_dr
from .. import trace as _trace
from ..trace import (
    attributes_dr,
    fragment_attributes,
    shade_dr,
    shade_points,
    to_numpy,
    view_depth,
)
from .ties import group_filters, near_dr, point_radius_dr

__all__ = [
    "fragments_of_pixels",
    "launch_prepass",
    "position_sums",
    "prepass",
    "shade",
]


def _cat(parts: list, dtype) -> np.ndarray:
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.zeros(0, dtype)


def _shape_of(mi, dr, table, pi):
    """Int32 index into ``scene.shape_names`` of a preliminary intersection (-1 miss)."""
    valid = pi.is_valid()
    ids = dr.select(valid, dr.reinterpret_array(mi.UInt32, pi.shape), 0)
    return dr.select(valid, dr.gather(mi.Int32, table, ids, valid), -1)


def launch_prepass(scene, table, ox, oy, base, count: int, n: int, tests: list, fmt: str):
    """Prepass of ``count`` pixels from ``base`` (``n`` lanes a pixel): ``valid``, view
    ``depth``, ``prim``, ``shape`` as :func:`..trace.trace_samples` computes them, and per
    group ``(member lut, filter)`` of ``tests`` the lanes that can tie with the group (hit,
    nearest shape not a member, near a member's box), all evaluated in one kernel."""
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    idx = dr.arange(mi.UInt32, count * n)
    ray = _rays(scene, ox, oy, base, idx, n)
    if loaded_alpha(scene) is not None:  # glTF MASK: the alpha-tested closest hit
        pi = scene_hit(scene, scene.mi_scene, ray, mi.RayFlags.Minimal)
    else:
        pi = scene.mi_scene.ray_intersect_preliminary(ray, coherent=True)
    valid = pi.is_valid()
    p_hit = ray.o + ray.d * pi.t
    depth = dr.select(valid, view_depth(cam, p_hit), 0.0)
    shape = _shape_of(mi, dr, table, pi)
    radius = point_radius_dr(dr, cam, fmt, depth, p_hit)
    shape_1 = mi.UInt32(shape + 1)
    masks = []
    for lut, filt in tests:
        outside = valid & ~dr.gather(mi.Bool, lut, shape_1)
        masks.append(near_dr(mi, dr, filt, p_hit, radius, outside))
    dr.eval(valid, depth, pi.prim_index, shape, *masks)
    return valid, depth, pi.prim_index, shape, masks


def _rays(scene, ox, oy, base, idx, n: int):
    """Camera rays of lanes ``idx`` (sample ``idx % n`` of pixel ``base + idx // n``)."""
    mi = backend.mitsuba()
    import drjit as dr

    w = scene.camera.width
    local = idx // n
    s = idx - local * n
    pix = base + local
    x = mi.Float(pix % w) + dr.gather(mi.Float, ox, s)
    y = mi.Float(pix // w) + dr.gather(mi.Float, oy, s)
    return camera_rays_dr(scene.camera, x, y)


def fragments_of_pixels(valid, shape, prim, count: int, n: int):
    """Nearest fragments of ``count`` pixels: per sample, the number of samples of its pixel
    with its (shape, primitive) where it is the first of them (its fragment's
    representative), else 0 (UInt32, sample layout, evaluated).

    One lane a pixel groups the pixel's ``n`` samples (:func:`..pixel_dr.first_of_key`) and
    counts them; :func:`..pixel_dr.to_sample_lanes` hands each sample its own count.
    """
    mi = backend.mitsuba()
    import drjit as dr

    first = _pixel_dr.first_of_key(
        mi,
        dr,
        _pixel_dr.slots(mi, dr, mi.Bool, valid, n),
        _pixel_dr.slots(mi, dr, mi.Int32, shape, n),
        _pixel_dr.slots(mi, dr, mi.UInt32, prim, n),
    )
    one, zero = mi.UInt32(1), mi.UInt32(0)
    counts = []
    for j in range(n):  # sample slots (at most 16 rounds): slot j's fragment size, if first
        c = zero
        for i in range(j, n):  # first[i] == j only for i >= j, and never for sky (first = n)
            c = c + dr.select(first[i] == j, one, zero)
        counts.append(c)
    return _pixel_dr.to_sample_lanes(mi, dr, counts)


def position_sums(valid, shape, prim, rep, n: int, offs64):
    """Sums of the sample positions of the fragments of representatives ``rep`` (lane
    indices), float64, added in sample-slot order."""
    mi = backend.mitsuba()
    import drjit as dr

    local = rep // n
    key = (dr.gather(mi.Int32, shape, rep), dr.gather(mi.UInt32, prim, rep))
    sums = [mi.Float64(0.0), mi.Float64(0.0)]
    for j in range(n):  # sample slots
        at = local * n + j
        same = (
            dr.gather(mi.Bool, valid, at)
            & (dr.gather(mi.Int32, shape, at) == key[0])
            & (dr.gather(mi.UInt32, prim, at) == key[1])
        )
        for a in range(2):
            sums[a] = sums[a] + dr.select(same, mi.Float64(offs64[j, a]), 0.0)
    return sums


def prepass(scene, offsets, groups: list, group_scenes: list, fmt: str, *, centroid: bool):
    """Depth prepass at ``offsets`` and the hits of the tie candidates of every group.

    Parameters
    ----------
    groups : tie groups (lists of shape indices, :func:`.groups.tie_groups`).
    group_scenes : one Mitsuba scene per group holding its members.
    fmt : depth format (the tie radius, :mod:`.ties`).
    centroid : also return the sums of each fragment's sample positions.

    Returns
    -------
    dict: ``near``, the nearest fragments in pixel order (``pixel``, ``sample``: first
    sample, uint32; ``shape`` int32; ``prim``, ``count`` uint32; with ``centroid``
    ``sum_x``, ``sum_y`` float64); ``candidates``, per group ``(pixel, sample, depth,
    hit_valid, hit_depth, hit_shape, hit_prim, near_shape, near_prim)``: the candidate
    samples in pixel-sample order with their prepass view depth, the group's nearest hit
    (float32 depths, as :func:`..trace.trace_samples` computes them) and the nearest
    surface's shape and primitive; ``traced``, the number of candidate rays.
    """
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    n_pix = cam.width * cam.height
    offs = np.asarray(offsets, np.float32).reshape(-1, 2)
    offs64 = np.asarray(offsets, np.float64).reshape(-1, 2)
    n = len(offs)
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    table = shape_table(mi, dr, scene)
    tests = []
    for g, filt in zip(groups, group_filters(scene, groups, fmt), strict=True):
        lut = np.zeros(len(scene.shape_names) + 1, bool)  # index shape + 1 (sky: 0)
        lut[np.asarray(g, np.int64) + 1] = True
        tests.append((mi.Bool(lut), filt))
    keys = ("pixel", "sample", "shape", "prim", "count") + (("sum_x", "sum_y") if centroid else ())
    near = {k: [] for k in keys}
    cands = [[[] for _ in range(9)] for _ in groups]
    traced = 0
    per_launch = max(1, _trace.CHUNK // n)
    for p0 in range(0, n_pix, per_launch):  # one launch of CHUNK rays at most
        m = min(n_pix, p0 + per_launch) - p0
        base = dr.opaque(mi.UInt32, p0)
        valid, depth, prim, shape, masks = launch_prepass(
            scene, table, ox, oy, base, m, n, tests, fmt
        )
        counts = fragments_of_pixels(valid, shape, prim, m, n)
        # nearest fragments: their representative samples, compressed
        rep = dr.compress(counts > 0)
        if dr.width(rep) > 0:  # an all-sky launch has no fragment (and no candidate)
            row = {
                "pixel": base + rep // n,
                "sample": rep % n,
                "shape": dr.gather(mi.Int32, shape, rep),
                "prim": dr.gather(mi.UInt32, prim, rep),
                "count": dr.gather(mi.UInt32, counts, rep),
            }
            if centroid:
                row["sum_x"], row["sum_y"] = position_sums(valid, shape, prim, rep, n, offs64)
            dr.eval(*row.values())
            for key in keys:
                near[key].append(to_numpy(row[key]).copy())
        for gi, mask in enumerate(masks):  # one trace per group, of its candidates only
            cand = dr.compress(mask)
            if dr.width(cand) == 0:
                continue
            ray = _rays(scene, ox, oy, base, cand, n)
            pi = group_scenes[gi].ray_intersect_preliminary(ray, coherent=True)
            hit = pi.is_valid()
            hit_depth = dr.select(hit, view_depth(cam, ray.o + ray.d * pi.t), 0.0)
            vals = (
                cand,
                dr.gather(mi.Float, depth, cand),
                hit,
                hit_depth,
                _shape_of(mi, dr, table, pi),
                pi.prim_index,
                dr.gather(mi.Int32, shape, cand),
                dr.gather(mi.UInt32, prim, cand),
            )
            dr.eval(*vals)
            c = to_numpy(cand).astype(np.int64)
            out = cands[gi]
            out[0].append(p0 + c // n)
            out[1].append(c % n)
            for k, v in enumerate(vals[1:]):
                out[k + 2].append(to_numpy(v).copy())
            traced += len(c)
    dtypes = (np.int64, np.int64, np.float32, bool, np.float32, np.int64, np.int64, np.int64)
    dtypes += (np.int64,)
    dtypes_near = {"pixel": np.uint32, "sample": np.uint32, "shape": np.int32}
    dtypes_near.update(prim=np.uint32, count=np.uint32, sum_x=np.float64, sum_y=np.float64)
    return {
        "near": {k: _cat(v, dtypes_near[k]) for k, v in near.items()},
        "candidates": [
            tuple(_cat(part, dt) for part, dt in zip(c, dtypes, strict=True)) for c in cands
        ],
        "traced": traced,
    }


def shade(
    scene, groups: list, group_scenes: list, frag: dict, offsets, centre=None, *, visibility=None
):
    """Colour of every fragment of ``frag`` (``pixel``, ``sample``: a sample it covers,
    ``shape``), shaded on the surface the ray through that sample meets in its group's scene,
    at the pixel centre or at ``centre`` (``(cx, cy)`` film positions), with an exact shadow
    ray from the shading point, or with ``visibility``: a function of the fragments'
    attributes (the dict of :func:`..trace.fragment_attributes`) giving their light
    visibility (a shadow technique, :func:`..common.shadow_visibility`).

    Film positions are formed in float32 (pixel + offset: exact, as in float64).

    Returns ``(rgb, shadow_rays)``: ``(F, 3)`` float32 linear radiance (0 where no surface)
    and the number of shadow rays cast (0 with ``visibility``).
    """
    if visibility is not None:
        return _shade_with(scene, groups, group_scenes, frag, offsets, centre, visibility)
    mi = backend.mitsuba()
    import drjit as dr

    w = scene.width
    f_shape = np.asarray(frag["shape"], np.int64)
    pix = mi.UInt32(np.asarray(frag["pixel"], np.uint32))
    smp = mi.UInt32(np.asarray(frag["sample"], np.uint32))
    offs = np.asarray(offsets, np.float32).reshape(-1, 2)
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    if centre is not None:
        centre = [mi.Float(np.asarray(a, np.float32)) for a in centre]
    rgb = [dr.zeros(mi.Float, len(f_shape)) for _ in range(3)]
    lut = np.full(len(scene.shape_names), -1, np.int64)
    for gi, g in enumerate(groups):
        lut[np.asarray(g, np.int64)] = gi
    group_of = lut[f_shape]
    rays = 0
    for gi, sub in enumerate(group_scenes):  # a fragment's ray finds its surface in its group
        sel = np.flatnonzero(group_of == gi).astype(np.uint32)
        for start in range(0, len(sel), _trace.CHUNK):
            part = mi.UInt32(sel[start : start + _trace.CHUNK])
            p = dr.gather(mi.UInt32, pix, part)
            k = dr.gather(mi.UInt32, smp, part)
            fx, fy = mi.Float(p % w), mi.Float(p // w)
            sx, sy = fx + dr.gather(mi.Float, ox, k), fy + dr.gather(mi.Float, oy, k)
            if centre is None:
                cx, cy = fx + 0.5, fy + 0.5
            else:
                cx, cy = (dr.gather(mi.Float, c, part) for c in centre)
            a = attributes_dr(scene, sub, sx, sy, cx, cy)
            # the fragments' surfaces come from the group's scene, their shadow rays from
            # the whole scene: one scene per kernel (on OptiX the second trace is disabled)
            evaluate_trace(a)
            color, tested = shade_dr(
                scene,
                a["valid"],
                a["position"],
                a["normal"],
                a["geo_normal"],
                a["albedo"],
                a["to_eye"],
                offset=a["offset"],
                visibility=None,
                material=a.get("material"),
                emissive=a.get("emissive"),
            )
            count = dr.count(tested)
            for c in range(3):
                dr.scatter(rgb[c], color[c], part)
            dr.eval(rgb, count)
            rays += int(count[0])
    rgb = np.stack([to_numpy(c) for c in rgb], axis=1)
    return rgb, rays


def _shade_with(scene, groups, group_scenes, frag, offsets, centre, visibility):
    """:func:`shade` with a visibility function: the fragments' attributes (each in its
    group's scene, the launches of the exact path) copied to NumPy for it, then shaded."""
    w = scene.width
    f_pix = np.asarray(frag["pixel"], np.int64)
    f_smp = np.asarray(frag["sample"], np.int64)
    f_shape = np.asarray(frag["shape"], np.int64)
    offs = np.asarray(offsets, np.float64)
    fx, fy = f_pix % w, f_pix // w
    sx, sy = fx + offs[f_smp, 0], fy + offs[f_smp, 1]
    cx, cy = centre if centre is not None else (fx + 0.5, fy + 0.5)
    attrs = None
    for members, sub in zip(groups, group_scenes, strict=True):  # each in its group's scene
        sel = np.flatnonzero(np.isin(f_shape, members))
        if len(sel) == 0:
            continue
        a = fragment_attributes(scene, sx[sel], sy[sel], cx[sel], cy[sel], mi_scene=sub)
        if attrs is None:
            attrs = {key: np.zeros((len(f_shape),) + v.shape[1:], v.dtype) for key, v in a.items()}
        for key, v in a.items():
            attrs[key][sel] = v
    return shade_points(scene, attrs, visibility=visibility(attrs))
