"""Which surface a single-pass multisampled frame keeps at each sample: the depth test of a
rasterizer (LESS on the rasterized depth, in draw order), not the ray tracer's tie-break.

The prepass's rays find the nearest surface; where another shape's surface lies at the same
depth (a decal on a wall, a duplicated panel) the ray tracer picks one by rounding, sample by
sample, so a pixel of a coplanar decal holds fragments of both (MSAA on ``decal``: 1.149
shading events a pixel where OpenGL counts 1.011). A rasterizer compares each primitive's
depth plane at the sample, stored in the depth format (:mod:`.acaa.plane`), and with LESS
the first primitive drawn (shape order, then primitive order) among those storing the lowest
value keeps the sample.

The candidates are ACAA's (:func:`.acaa.trace.prepass`: surfaces of other tie groups near
each sample's nearest hit); scenes whose shapes can never tie (one tie group) skip the search.
A fragment that owns no sample where the ray found it is shaded through the scene of its
shape's tie group (where the ray through its sample meets it).
"""

from __future__ import annotations

import numpy as np

from .acaa import trace as _acaa_trace
from .acaa.groups import group_scenes, tie_distance, tie_groups
from .acaa.plane import depth_tests
from .common import shade_fragments, shadow_visibility
from .fragments import Fragments, sample_film_positions, shading_positions
from .trace import fragment_attributes, shade_points

__all__ = ["DRAW_KEY_SHIFT", "draw_order_owners", "reassign_samples", "shade_owned"]

#: A primitive's draw-order key: ``shape << DRAW_KEY_SHIFT | prim``.
DRAW_KEY_SHIFT = 32


def draw_order_owners(scene, offsets, fmt: str):
    """Samples a LESS depth test in draw order gives to another surface than the ray's
    nearest: ``((pixel, sample, shape, prim), groups, group_scenes)`` (int64 arrays), or
    None where no sample changes hands."""
    groups = tie_groups(scene, fmt)
    if len(groups) < 2:
        return None
    subs = group_scenes(scene, groups)
    cam = scene.camera
    pre = _acaa_trace.prepass(scene, offsets, groups, subs, fmt, centroid=False)
    window = float(tie_distance(cam, cam.far, fmt))
    t = depth_tests(scene, pre["candidates"], window, fmt, offsets)
    if t is None:
        return None
    _, _, h_shape, h_prim = t["rows"]
    never = np.iinfo(np.int64).max
    n_shape, n_prim = (np.asarray(a, np.int64) for a in t["near"])
    near_key = (n_shape << DRAW_KEY_SHIFT) | n_prim
    best = np.where(t["q_near"] <= t["low"], near_key, never)
    cand_key = (h_shape.astype(np.int64) << DRAW_KEY_SHIFT) | h_prim.astype(np.int64)
    np.minimum.at(best, t["inv"], np.where(t["q_hit"] <= t["low"][t["inv"]], cand_key, never))
    change = best != near_key
    if not change.any():
        return None
    n = len(offsets)
    keys, best = t["keys"][change], best[change]
    owners = (keys // n, keys % n, best >> DRAW_KEY_SHIFT, best & ((1 << DRAW_KEY_SHIFT) - 1))
    return owners, groups, subs


def reassign_samples(frags: Fragments, valid, shape, prim, owners) -> tuple[Fragments, np.ndarray]:
    """:class:`.fragments.Fragments` after giving the samples ``owners`` (``(pixel, sample,
    shape, prim)``) to those primitives: the fragments of the pixels concerned are built
    again from their samples' owners (in slot order, as the prepass groups them), the others
    kept. ``valid``, ``shape``, ``prim``: the prepass's ``(P, N)`` arrays.

    Returns the fragments, each new one represented by a sample where the ray found its
    surface if it has one, and per fragment the shape of those that have none (to be traced
    in their shape's tie-group scene), -1 for the others."""
    pixel, sample, o_shape, o_prim = owners
    busy = np.unique(pixel)
    n = valid.shape[1]
    v = valid[busy]
    orig = np.where(v, (shape[busy].astype(np.int64) << DRAW_KEY_SHIFT) | prim[busy], -1)
    key = orig.copy()
    row = np.searchsorted(busy, pixel)
    key[row, sample] = (o_shape << DRAW_KEY_SHIFT) | o_prim
    first = np.argmax(key[:, :, None] == key[:, None, :], axis=2)  # (B, N)
    slots = np.arange(n)
    is_rep = v & (first == slots)
    own = v[:, :, None] & (first[:, :, None] == slots)  # (B, sample i, fragment slot j)
    count = own.sum(axis=1)
    traced = own & (orig == key)[:, :, None]  # samples where the ray met the fragment
    has = traced.any(axis=1)
    trace_slot = np.where(has, np.argmax(traced, axis=1), slots)
    b, j = np.nonzero(is_rep)
    keep = ~np.isin(frags.pixel, busy)
    old = np.flatnonzero(keep)
    all_pixel = np.concatenate([frags.pixel[keep], busy[b]])
    order = np.argsort(all_pixel, kind="stable")
    pos = np.empty(len(order), np.int64)
    pos[order] = np.arange(len(order))
    of = np.asarray(frags.of_sample).copy()
    remap = np.full(len(frags) + 1, -1, np.int64)  # old fragment -> new position (-1: sky)
    remap[old] = pos[: len(old)]
    of = remap[np.where(of >= 0, of, len(frags))]
    rep_id = np.cumsum(is_rep.ravel()).reshape(is_rep.shape) - 1
    new_pos = pos[len(old) :]
    of[busy] = np.where(v, new_pos[np.take_along_axis(rep_id, first, axis=1)], -1)
    cat = {
        "sample": np.concatenate([frags.sample[keep], trace_slot[b, j]]),
        "count": np.concatenate([frags.count[keep], count[b, j]]),
        "regroup": np.concatenate(
            [np.full(len(old), -1, np.int64), np.where(has[b, j], -1, key[b, j] >> DRAW_KEY_SHIFT)]
        ),
    }
    out = Fragments(all_pixel[order], cat["sample"][order], cat["count"][order], of)
    return out, cat["regroup"][order]


def shade_owned(scene, frags, offsets, *, centroid, shadows, regroup=None, groups=(), subs=()):
    """:func:`.common.shade_fragments`, with the fragments whose ``regroup`` entry is a
    shape index (not -1) found through that shape's tie-group scene (``groups``, ``subs``);
    all shaded in one batch."""
    if regroup is None or not (regroup >= 0).any():
        return shade_fragments(scene, frags, offsets, centroid=centroid, shadows=shadows)
    w, n = scene.width, len(offsets)
    sx, sy = sample_film_positions(frags, offsets, w)
    cx, cy = shading_positions(frags, offsets, w, centroid, n)
    group_of = np.full(len(scene.shape_names) + 1, -1, np.int64)  # index shape + 1
    for gi, g in enumerate(groups):  # one round per group (a list-length loop)
        group_of[np.asarray(g, np.int64) + 1] = gi
    fgroup = group_of[regroup + 1]
    parts = [(np.flatnonzero(regroup < 0), None)]
    for gi, sub in enumerate(subs):
        parts.append((np.flatnonzero(fgroup == gi), sub))
    attrs = None
    for sel, sub in parts:
        if len(sel) == 0:
            continue
        a = fragment_attributes(scene, sx[sel], sy[sel], cx[sel], cy[sel], mi_scene=sub)
        if attrs is None:
            attrs = {k: np.zeros((len(frags),) + v.shape[1:], v.dtype) for k, v in a.items()}
        for k, v in a.items():
            attrs[k][sel] = v
    vis = shadow_visibility(scene, attrs, shadows)
    rgb, rays = shade_points(scene, attrs, visibility=vis)
    return attrs, rgb, rays
