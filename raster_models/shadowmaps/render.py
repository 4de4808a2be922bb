"""Rendering shadow maps: one ray per texel centre from the light, then the depth format,
depth clamp and hardware bias a rasterizer applies (:mod:`.depth_dr`), and the VSM/EVSM
moments.

Depth clamp ("pancaking"): orthographic maps start their rays behind the scene's bounds (not
at the near plane) and clamp depths in front of the near plane to 0; perspective maps start
at the light. Without it rays start at the near plane, so casters in front are clipped.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend
from .. import depth as _depth
from ..light_frame import Projection
from . import filters as _filters
from . import msm_filter as _msm
from . import three_filters as _three
from .depth_dr import fused_bias, stored_depth_dr
from .raycast import GRID_CHUNK, iter_grid
from .records import MapData, Partition, Setup

__all__ = ["map_rays", "render_maps"]


def _scene_light_z_range(scene, proj: Projection) -> tuple[float, float]:
    lo, hi = scene.bounds()
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    lz = proj.frame.to_light(corners)[:, 2]
    return float(lz.min()), float(lz.max())


def _max_depth_slope(proj: Projection, grid, n, s, t, thit, dnorm):
    """Caster depth slope in normalized depth per texel (for SlopeScaledDepthBias)."""
    r = proj.resolution
    n = n.astype(np.float64)
    if proj.kind == "ortho":
        m2 = proj.matrix[2, :3]
        d = grid["D"]
        nd = n @ d
        nd = np.where(np.abs(nd) > 1e-12, nd, 1e-12)
        slopes = []
        for vec in (grid["U"], grid["V"]):
            dthit = -(n @ vec) / (r * nd)
            slopes.append(np.abs((m2 @ vec) / r + dthit * (m2 @ d)))
        return np.maximum(slopes[0], slopes[1])
    _, near, far = (float(v) for v in proj.extent)
    b = far * near / (far - near)
    dvec = grid["D"][None, :] + s[:, None] * grid["DS"] + t[:, None] * grid["DT"]
    nd = np.sum(n * dvec, axis=1)
    nd = np.where(np.abs(nd) > 1e-12, nd, 1e-12)
    tau = grid["z_start"] + thit / dnorm
    slopes = []
    for vec in (grid["DS"], grid["DT"]):
        dtau = -tau * (n @ vec) / nd / r
        slopes.append(np.abs(b / (tau * tau) * dtau))
    return np.maximum(slopes[0], slopes[1])


def map_rays(scene, proj: Projection, *, depth_clamp: bool) -> tuple[dict, tuple, float]:
    """The rays of a map's texel centres and how their hits become normalized depth.

    Returns ``(grid, depth, z_start)``: the affine ray description of
    :meth:`Projection.grid_rays`, the depth coefficients of :func:`.raycast.iter_grid`, and
    the light depth the rays start at. With ``depth_clamp`` ("pancaking") orthographic rays
    start behind the scene's bounds and perspective rays at the light; without it at the
    near plane, so casters in front of it are clipped.
    """
    if proj.kind == "ortho":
        z0, z1 = float(proj.extent[4]), float(proj.extent[5])
        z_start = z0
        if depth_clamp:
            scene_lo, _ = _scene_light_z_range(scene, proj)
            margin = 1e-3 * max(z1 - z0, 1e-6)
            z_start = min(z0, scene_lo - margin)
        z_end = z1
    else:
        _, near, far = (float(v) for v in proj.extent)
        z_start = 0.0 if depth_clamp else near
        z_end = far
    grid = proj.grid_rays(z_start, z_end)
    m = proj.matrix
    if proj.kind == "ortho":
        m2 = m[2, :3]
        depth = ("ortho", m2 @ grid["A"] + m[2, 3], m2 @ grid["U"], m2 @ grid["V"], m2 @ grid["D"])
    else:
        _, near, far = (float(v) for v in proj.extent)
        depth = ("persp", far / (far - near), far * near / (far - near))
    return grid, depth, z_start


def _render_one(scene, part: Partition, params, need_slope: bool) -> MapData:
    proj = part.projection
    r = proj.resolution
    grid, depth, z_start = map_rays(scene, proj, depth_clamp=params.depth_clamp)
    # One launch at a time (bounded memory at any map size): only the float32 map is whole.
    bias = fused_bias(
        params.format,
        depth_bias=params.depth_bias,
        slope_scaled=params.slope_scaled_bias,
        clamp=params.depth_bias_clamp,
    )
    if bias is not None:
        # No per-texel bias: the texels are finished in the casting kernel (same bytes).
        launches = iter_grid(
            scene,
            grid,
            r,
            depth,
            store=(params.format, bias),
            faces=params.caster_faces,
            alpha=params.caster_alpha,
        )
        if r * r <= GRID_CHUNK:
            # One launch: the map is a view of the kernel's output, which lookups reuse.
            ((_, _, hits),) = launches
            stored = hits["stored"].reshape(r, r)
            return MapData(stored, None, (0.0, 0.0), hits["covered"], z_start, hits["texels"])
        stored = np.empty(r * r, dtype=np.float32)
        covered = 0
        for start, stop, hits in launches:
            stored[start:stop] = hits["stored"]
            covered += hits["covered"]
        return MapData(stored.reshape(r, r), None, (0.0, 0.0), covered, z_start)
    stored, covered = _render_per_texel_bias(scene, proj, grid, depth, params, need_slope)
    return MapData(stored, None, (0.0, 0.0), covered, z_start)


def _render_per_texel_bias(scene, proj, grid, depth, params, need_slope: bool):
    """Stored texels ``(R, R)`` and texels hit of a map whose hardware bias varies per
    texel: computed in NumPy from each texel's depth (and caster slope), then added and
    stored by the same Dr.Jit rule as a constant bias."""
    mi = backend.mitsuba()
    r = proj.resolution
    covered = 0
    stored = np.empty(r * r, dtype=np.float32)
    chunks = iter_grid(
        scene,
        grid,
        r,
        depth,
        normals=need_slope,
        faces=params.caster_faces,
        alpha=params.caster_alpha,
    )
    for start, stop, hits in chunks:
        z = hits["z"]
        hit = np.isfinite(z)
        covered += int(hit.sum())
        slope = None
        if need_slope:
            idx = np.nonzero(hit)[0]
            texel = idx + start
            s = (texel % r + 0.5) / r
            t = (texel // r + 0.5) / r
            slope = np.zeros(stop - start)
            slope[idx] = _max_depth_slope(
                proj, grid, hits["normal"][idx], s, t, hits["t"][idx], hits["dir_norm"][idx]
            )
        texel_bias = _depth.hardware_bias(
            np.where(hit, z, 1.0),
            slope,
            params.format,
            depth_bias=params.depth_bias,
            slope_scaled=params.slope_scaled_bias,
            clamp=params.depth_bias_clamp,
        )
        texels, _ = stored_depth_dr(mi, mi.Float64(z), params.format, mi.Float64(texel_bias))
        stored[start:stop] = texels.numpy()
    return stored.reshape(r, r), covered


def _add_moments(data: MapData, part: Partition, params, setup: Setup) -> None:
    exponents = (0.0, 0.0)
    if params.filter != "vsm":
        scale = 1.0
        proj = part.projection
        if params.evsm_light_space and proj.kind == "ortho":
            extent = float(proj.extent[5] - proj.extent[4])
            scale = extent / max(setup.depth_extent_reference, 1e-30)
        exponents = _filters.evsm_exponents(
            params.evsm_positive, params.evsm_negative, params.moment_format, scale
        )
    data.moments = _filters.moment_texture(
        data.depth, params.filter, exponents, params.blur_size, params.moment_format
    )
    data.exponents = exponents


def render_maps(scene, setup: Setup, params) -> list[MapData | None]:
    """Render every non-empty partition's map (one Dr.Jit launch per map chunk): its stored
    depth and, for the compare filters, the same texels as a Dr.Jit array
    (:attr:`MapData.texels`), for VSM/EVSM its moments."""
    need_slope = params.slope_scaled_bias != 0.0
    maps: list[MapData | None] = []
    for part in setup.partitions:
        if part.projection is None or setup.skip_rendering:
            maps.append(None)
            continue
        data = _render_one(scene, part, params, need_slope)
        if params.filter in _filters.MOMENT_FILTERS:
            _add_moments(data, part, params, setup)
            data.texels = None
        elif params.filter == "three_vsm":
            data.moments = _three.vsm_texture(
                data.depth,
                radius=params.shadow_radius,
                samples=params.blur_samples,
                subtexel_bits=params.subtexel_bits,
            )
            data.texels = None
        elif params.filter == "msm":
            depth = _msm.moment_depth(part.projection, data.depth, params.moment_depth)
            data.moments = _msm.msm_texture(depth, params.blur_size, params.msm_format)
            data.texels = None
        elif data.texels is None:
            data.texels = _filters.upload_texels(data.depth)
        maps.append(data)
    return maps
