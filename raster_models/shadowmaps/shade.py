"""Shading a G-buffer with rendered maps: map selection, shader biases, filters, cascade
blending, and the diagnostic images.

Outputs (all ``(H, W)`` float32, row 0 at the top):

- ``visibility``: 1 = lit. Sky is 1; valid pixels facing away from the light (N.L <= 0) or
  outside a spot light's cone are 0, as in the oracle's definition of visibility.
- ``cascade``: index of the partition a pixel looks up (cube face for point lights), -1 for
  sky and for pixels in no partition.
- ``texels_per_pixel``: shadow-map texels per screen pixel along the worst-sampled screen
  direction: the smallest singular value of the Jacobian ``J = d(texel) / d(pixel)`` of the
  selected map; its inverse is the texel-to-pixel ratio of the aliasing literature. 0 where
  no map is selected.
- ``resolution_error``: the Intel SDSM sample's metric, ``max(0, -log2(sqrt(fw_u fw_v)))``
  with ``fw = max(|J dx|, |J dy|)`` per texel axis (0 = at least one texel per pixel).
- ``uncovered``: 1 on receivers whose selected map does not contain them (outside its
  texture, an empty partition, or outside every partition's depth range).
- ``compare_margin`` (compare filters: point, hw_pcf, pcf, poisson, three_pcf): the
  smallest ``|reference - stored|`` in normalized depth over the texels a receiver's
  lookup compared (:mod:`.margins`); 1 elsewhere. Within the depth format's rounding an
  engine may decide the other way: conformance names those pixels implementation-defined.
"""

from __future__ import annotations

import numpy as np

from . import filters as _filters
from . import margins as _margins
from . import msm_filter as _msm
from . import pcss_filter as _pcss
from . import three_filters as _three
from .geometry import (
    DrjitColumns,
    normal_offset_in_world_units,
    normal_offset_texels,
    partition_geometry,
)
from .records import MapData, Setup

__all__ = ["linear_bias_reference", "perspective_reference", "select_partitions", "shade"]


def perspective_reference(params, proj, z):
    """Compare reference of perspective maps with a linear-depth bias, or ``None``.

    ``tau = b / (a - z)`` is the receiver's light-view depth; the reference is the
    hyperbolic depth of ``tau (1 - k)`` with ``k = perspective_bias * 2 tan(fov/2) / R``:
    ``perspective_bias`` texel footprints at the receiver's distance, in world units along
    the light's axis. ``None`` where the technique has no such bias (the constant ``bias`` is
    subtracted from normalized depth instead).
    """
    k_texels = getattr(params, "perspective_bias", None)
    if proj is None or proj.kind != "persp" or not k_texels:
        return None
    tan_half, near, far = (float(x) for x in proj.extent)
    a, b = far / (far - near), far * near / (far - near)
    k = float(k_texels) * 2.0 * tan_half / proj.resolution
    z = np.asarray(z, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = b / (a - z)
        ref = a - b / (tau * max(1.0 - k, 1e-6))
    return np.where(np.isfinite(ref), ref, z)


def select_partitions(setup: Setup, gbuf, idx: np.ndarray, params) -> np.ndarray:
    """Partition index per pixel of ``idx`` (-1: none)."""
    parts = setup.partitions
    k = len(parts)
    z = gbuf.depth[idx]
    if setup.selection == "single":
        return np.zeros(len(idx), dtype=np.int64)
    if setup.selection == "depth":
        ends = np.array([p.z_end for p in parts[:-1]])
        if np.all(np.diff(ends) >= 0):
            # Number of interior ends at or below z (the same count, without an (N, k) mask).
            sel = np.searchsorted(ends, z, side="right").astype(np.int64)
        else:
            sel = np.sum(z[:, None] >= ends[None, :], axis=1).astype(np.int64)
        if setup.outside == "discard":
            outside = (z < parts[0].z_begin) | (z >= parts[-1].z_end)
            sel[outside] = -1
        return sel
    if setup.selection == "cube":
        # The face of the lookup direction, normal offset included (a cube-map fetch is
        # seamless: the offset may carry a lookup onto the neighbouring face).
        proj0 = parts[0].projection
        d = gbuf.position[idx] - proj0.frame.origin
        offset = normal_offset_texels(params, proj0)
        if offset > 0.0 and normal_offset_in_world_units(params, proj0):
            d = d + gbuf.normal[idx] * offset
        elif offset > 0.0:
            texel = 2.0 * float(proj0.extent[0]) * np.max(np.abs(d), axis=1) / proj0.resolution
            n_dot_l = np.clip(gbuf.cos_l[idx], 0.0, 1.0)
            scale = offset * texel * (1.0 - n_dot_l)
            d = d + gbuf.normal[idx] * scale[:, None]
        axis = np.argmax(np.abs(d), axis=1)
        sign = np.take_along_axis(d, axis[:, None], axis=1)[:, 0] < 0
        return (2 * axis + sign).astype(np.int64)
    # projection: first map whose texture volume ([0, 1]^3) contains the pixel
    sel = np.full(len(idx), -1, dtype=np.int64)
    pos = gbuf.position[idx]
    for i in range(k - 1, -1, -1):
        proj = parts[i].projection
        if proj is None:
            continue
        u, v, z, w = proj.project(pos)
        # The whole texture volume: x, y and depth (a pixel beyond a cascade's depth range
        # is not represented by its map even where x, y fall inside).
        inside = (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1) & (z >= 0) & (z <= 1) & (w > 0)
        sel[inside] = i
    return sel


def _receiver_plane(j3: np.ndarray):
    """MJP's ComputeReceiverPlaneDepthBias: (dz/du, dz/dv) from the (u, v, z) derivatives."""
    dx, dy = j3[:, :, 0], j3[:, :, 1]
    det = dx[:, 0] * dy[:, 1] - dx[:, 1] * dy[:, 0]
    ok = np.abs(det) > 1e-30
    safe = np.where(ok, det, 1.0)
    bu = (dy[:, 1] * dx[:, 2] - dx[:, 1] * dy[:, 2]) / safe
    bv = (dx[:, 0] * dy[:, 2] - dy[:, 0] * dx[:, 2]) / safe
    bu = np.where(ok & np.isfinite(bu), bu, 0.0)
    bv = np.where(ok & np.isfinite(bv), bv, 0.0)
    return bu, bv


def _lookup(params, data: MapData, u, v, z, plane, rotation, *, ref=None, proj=None, extras=None):
    """Visibility of receivers from one map (the filter of ``params``); ``ref``: a compare
    reference replacing ``z - bias`` (perspective linear-depth bias); ``proj``: the map's
    projection (PCSS converts depths to linear distances with it); ``extras``: a dict PCSS
    fills with its per-receiver penumbra estimate (:func:`pcss_filter.estimates`)."""
    kind = params.filter
    if kind in _filters.MOMENT_FILTERS:
        return _filters.moment_lookup(
            data.moments,
            u,
            v,
            z,
            kind,
            exponents=data.exponents,
            min_variance=params.vsm_bias,
            bleed_reduction=params.light_bleeding_reduction,
            subtexel_bits=params.subtexel_bits,
        )
    r = data.depth.shape[0]
    if params.receiver_plane_bias:
        frac = np.minimum((np.abs(plane[0]) + np.abs(plane[1])) / r, 0.01)
        ref = z - frac
    else:
        ref = z - params.bias if ref is None else ref
        plane = None
    if kind == "msm":
        # The compare reference (bias toward the light, as HDRP's depth + depthBias).
        return _msm.msm_lookup(
            data.moments,
            u,
            v,
            _msm.moment_depth(proj, np.clip(ref, 0.0, 1.0), params.moment_depth),
            fmt=params.msm_format,
            moment_bias=params.moment_bias,
            bleed_reduction=params.light_bleeding_reduction,
            subtexel_bits=params.subtexel_bits,
        )
    common = {"address": params.address_mode, "subtexel_bits": params.subtexel_bits}
    if kind == "three_vsm":
        return _three.lookup_vsm(data.moments, u, v, ref, subtexel_bits=params.subtexel_bits)
    tex = data.texels
    if kind == "three_pcf":
        return _three.lookup_pcf(
            tex, u, v, ref, radius=params.shadow_radius, phi=rotation, **common
        )
    if kind == "point":
        return _filters.compare_point(tex, u, v, ref, address=params.address_mode)
    if kind == "hw_pcf":
        return _filters.compare_bilinear(tex, u, v, ref, **common)
    if kind == "pcss":
        vis, radius, z_b = _pcss.pcss_lookup(data, proj, u, v, z, ref, params, rotation)
        if extras is not None:
            extras.update(_pcss.estimates(proj, ref, radius, z_b, params))
        return vis
    if kind == "pcf":
        return _filters.pcf_grid(tex, u, v, ref, params.pcf_size, plane=plane, **common)
    return _filters.pcf_poisson(
        tex,
        u,
        v,
        ref,
        taps=params.poisson_taps,
        diameter=params.filter_size,
        rotation=rotation,
        plane=plane,
        seed=params.seed,
        **common,
    )


def linear_bias_reference(params, proj, z):
    """Compare reference with ``bias_space="linear"``, or ``None``: the receiver's
    light-view depth minus ``bias * (far - near)``, converted to the map's normalized depth
    (on an orthographic map exactly ``z - bias``)."""
    if getattr(params, "bias_space", "hyperbolic") != "linear" or proj is None:
        return None
    z = np.asarray(z, dtype=np.float64)
    if proj.kind != "persp":
        return z - params.bias
    _, near, far = (float(x) for x in proj.extent)
    a, b = far / (far - near), far * near / (far - near)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = b / (a - z) - params.bias * (far - near)
        ref = a - b / np.maximum(tau, 1e-300)
    return np.where(np.isfinite(ref), ref, z)


def _lookup_subset(params, data, geo, mask, rotation, extras=None, margin=None):
    """Visibility of the pixels ``mask`` of a `partition_geometry` record; ``margin``: a
    dict that receives the receivers' compare margins (:mod:`.margins`) under ``"margin"``
    for the filters that have one."""
    plane = _receiver_plane(geo["j3"][mask]) if params.receiver_plane_bias else None
    z = geo["z"][mask]
    ref = perspective_reference(params, geo.get("proj"), z)
    if ref is None:
        ref = linear_bias_reference(params, geo.get("proj"), z)
    u, v = geo["u"][mask], geo["v"][mask]
    proj = geo.get("proj")
    vis = _lookup(params, data, u, v, z, plane, rotation, ref=ref, proj=proj, extras=extras)
    if margin is not None and params.filter in _margins.MARGIN_FILTERS:
        r = data.depth.shape[0]
        if params.receiver_plane_bias:
            compare = z - np.minimum((np.abs(plane[0]) + np.abs(plane[1])) / r, 0.01)
        else:
            compare = z - params.bias if ref is None else ref
        du, dv = _margins.tap_offsets(params, r, rotation, len(u))
        point = params.filter == "point"
        margin["margin"] = _margins.compare_margin(data.depth, u, v, compare, du, dv, point=point)
    return vis


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _blend_cascades(
    gbuf, setup, maps, params, rec_idx, rec_sel, *, vis, lookups, rotation_all, columns, per_lookup
) -> int:
    """Blend band between consecutive cascades (MJP ``FilterAcrossCascades``): receivers
    ``rec_idx`` (selected partitions ``rec_sel``) within ``blend_band`` of their cascade's
    far end also look up the next cascade and blend with a smoothstep. Updates ``vis`` and
    ``lookups`` in place; returns the number of receivers blended."""
    k = len(setup.partitions)
    blended = 0
    if not (setup.blend_band > 0.0 and setup.selection == "depth" and k > 1):
        return blended
    for i in range(k - 1):
        part, nxt = setup.partitions[i], setup.partitions[i + 1]
        if part.projection is None or nxt.projection is None or maps[i + 1] is None:
            continue
        rec = rec_idx[rec_sel == i]
        z = gbuf.depth[rec]
        start = 0.0 if i == 0 else setup.partitions[i - 1].z_end
        size = part.z_end - start
        split_dist = (part.z_end - z) / size
        band = rec[split_dist <= setup.blend_band]
        if len(band) == 0:
            continue
        rot = rotation_all[band] if rotation_all is not None else None
        geo = partition_geometry(params, nxt, gbuf, band, columns)
        nxt_vis = _lookup_subset(params, maps[i + 1], geo, np.ones(len(band), bool), rot)
        amt = _smoothstep(0.0, setup.blend_band, (part.z_end - gbuf.depth[band]) / size)
        vis[band] = nxt_vis * (1.0 - amt) + vis[band] * amt
        lookups[band] += per_lookup
        blended += len(band)
    return blended


def _rotations(gbuf, params):
    """Per-pixel disk rotation angles (all pixels), or ``None``: seeded uniform angles for
    a rotated Poisson disc, interleaved gradient noise at pixel centres for PCSS's ``ign``
    and at ``gl_FragCoord`` (lower-left origin) for ``three_pcf``."""
    if params.filter == "poisson" and params.poisson_rotate:
        rng = np.random.default_rng(params.seed)
        return rng.uniform(0.0, 2.0 * np.pi, gbuf.size)
    if params.filter == "three_pcf":
        px, py = _three.frag_coord(gbuf.width, gbuf.height)
        return _three.interleaved_gradient_noise(px, py) * (2.0 * np.pi)
    if params.filter == "pcss" and params.rotation == "ign":
        idx = np.arange(gbuf.size)
        px, py = idx % gbuf.width + 0.5, idx // gbuf.width + 0.5
        return _pcss.interleaved_gradient_noise(px, py) * 2.0 * np.pi
    return None


def _lookups_per_pixel(params) -> int:
    """Texture sample instructions one lookup issues (PCSS: blocker taps plus PCF taps)."""
    if params.filter == "pcss":
        return int(params.blocker_samples + params.filter_samples)
    return _filters.lookups_per_pixel(
        params.filter, pcf_size=params.pcf_size, taps=params.poisson_taps
    )


def _partition_stats(st: dict, geo: dict, rmask, uncovered_rec, data) -> dict:
    """``st`` completed with a rendered partition's statistics over its receivers."""
    tpp_rec = geo["tpp"][rmask]
    st.update(
        empty=False,
        uncovered=int(uncovered_rec.sum()) if len(uncovered_rec) else 0,
        texels_per_pixel_min=float(tpp_rec.min()) if len(tpp_rec) else None,
        texels_per_pixel_mean=float(tpp_rec.mean()) if len(tpp_rec) else None,
        resolution_error_mean=float(geo["err"][rmask].mean()) if rmask.any() else None,
        texels_covered=int(data.texels_covered) if data is not None else 0,
    )
    return st


def shade(gbuf, setup: Setup, maps, params) -> tuple[dict, dict]:
    """Outputs (see module docstring) and per-partition statistics."""
    n = gbuf.size
    vis = np.ones(n)
    cascade = np.full(n, -1.0)
    tpp = np.zeros(n)
    err = np.zeros(n)
    uncovered = np.zeros(n)
    lookups = np.zeros(n)
    valid_idx = np.nonzero(gbuf.valid)[0]
    columns = DrjitColumns(gbuf)
    vis[valid_idx] = 0.0
    sel = (
        select_partitions(setup, gbuf, valid_idx, params)
        if len(valid_idx)
        else np.zeros(0, np.int64)
    )
    cascade[valid_idx] = sel
    receiver = gbuf.receiver
    rotation_all = _rotations(gbuf, params)
    # PCSS's penumbra estimate per receiver (world units; 0 where no blocker was found)
    pcss_out = {k: np.zeros(n) for k in _pcss.ESTIMATES} if params.filter == "pcss" else {}
    per_lookup = _lookups_per_pixel(params)
    # Compare margin per receiver (normalized depth; 1 where no compare was made).
    margin = np.ones(n) if params.filter in _margins.MARGIN_FILTERS else None
    stats = []
    for i, part in enumerate(setup.partitions):
        pix = valid_idx[sel == i]
        rec = pix[receiver[pix]]
        st = {"index": i, "pixels": int(len(pix)), "receivers": int(len(rec))}
        if part.projection is None:
            uncovered[rec] = 1.0
            vis[rec] = 0.0 if setup.outside == "discard" else 1.0
            st.update(empty=True, uncovered=int(len(rec)))
            stats.append(st)
            continue
        data = maps[i]
        geo = partition_geometry(params, part, gbuf, pix, columns)
        tpp[pix] = geo["tpp"]
        err[pix] = geo["err"]
        rmask = receiver[pix]
        if len(rec) and data is not None:
            rot = rotation_all[rec] if rotation_all is not None else None
            extras = {} if pcss_out else None
            got: dict | None = {} if margin is not None else None
            vis[rec] = _lookup_subset(params, data, geo, rmask, rot, extras, got)
            if got:
                margin[rec] = got["margin"]
            for key, img in pcss_out.items():
                img[rec] = extras[key]
            uncovered[rec] = (~geo["inside"][rmask]).astype(np.float64)
            lookups[rec] = per_lookup
        stats.append(_partition_stats(st, geo, rmask, uncovered[rec], data))
    # Outside every depth range (Intel: the lighting pass discards the pixel).
    none = valid_idx[sel < 0]
    rec_none = none[receiver[none]]
    uncovered[rec_none] = 1.0
    vis[rec_none] = 0.0 if setup.outside == "discard" else 1.0
    blended = _blend_cascades(
        gbuf,
        setup,
        maps,
        params,
        valid_idx[receiver[valid_idx]],
        sel[receiver[valid_idx]],
        vis=vis,
        lookups=lookups,
        rotation_all=rotation_all,
        columns=columns,
        per_lookup=per_lookup,
    )
    # Receivers only see the light where the oracle says the light reaches them.
    non_rec = gbuf.valid & ~receiver
    vis[non_rec] = 0.0
    vis = np.clip(vis, 0.0, 1.0)
    vis[~gbuf.valid] = 1.0
    outputs = {
        "visibility": gbuf.image(vis),
        "cascade": gbuf.image(cascade),
        "texels_per_pixel": gbuf.image(tpp),
        "resolution_error": gbuf.image(err),
        "uncovered": gbuf.image(uncovered),
    }
    outputs.update({k: gbuf.image(img) for k, img in pcss_out.items()})
    if margin is not None:
        outputs["compare_margin"] = gbuf.image(np.minimum(margin, 1.0))
    n_rec = int(receiver.sum())
    summary = {
        "partitions": stats,
        "receivers": n_rec,
        "uncovered_receivers": int(uncovered.sum()),
        "blended_receivers": blended,
        "outside_all_partitions": int(len(rec_none)),
        "lookups_mean": float(lookups[receiver].mean()) if n_rec else 0.0,
    }
    return outputs, summary
