"""Sample distribution shadow maps (SDSM), after the Intel SDSM sample.

From the depth buffer (a depth prepass of the current frame, or a frame ``latency`` frames
earlier read back to the CPU), the technique

1. reduces min/max view depth over valid samples (``near <= z < far``, sky excluded; failure
   modes as options: a 16-bit UNORM readback, and "sky counts as far");
2. places ``partitions`` depth partitions: log over ``[zmin, zmax]`` (``scheme="log"``, the
   sample's default reduce path) with the first and last partition stretched to the camera's
   near and far (``stretch_ends``), or from the sample's 1024-bin warped histogram: log,
   adaptive log, or K-means (Lloyd iterations);
3. bounds each partition tightly in light space: min/max of its samples' light-space
   coordinates, plus a border (``border_xy`` world units for filter blur, ``border_z`` = 1
   light-space depth unit as in the sample), dilated by ``dilation_texels / resolution`` of
   the partition, zoom clamped to ``max_scale`` (kept centred), an empty partition replaced
   by a sentinel no geometry overlaps; all relative to a global light box around the view
   frustum, as the sample's ``scale``/``bias`` are. ``tight_bounds=False`` fits the frustum
   slices' corners instead (SDSM z-partitions only, as Falcor's and MJP's min/max SDSM).

The light frame uses the camera's right vector as up (``light_up="camera_right"``, the
sample's "align light to frustum": camera Z becomes light X), unless ``quantize`` (the
sample's power-of-two zoom and texel-snapped bias) is on, which forces world up and, as in
the sample, fits the global light box to the scene's bounds instead of the view frustum.

With ``latency > 0`` the partitions (depth intervals and light-space bounds) come from the
camera ``latency`` frames earlier along the scene's camera path and are applied to the
current frame: geometry newly visible after camera motion, and samples that moved across a
split, fall outside their partition's bounds. Those receivers are counted and shown in the
``uncovered`` output; their lookups clamp to the map's edge texels (``address_mode``).

Not modelled from the sample's EVSM path (the default filter): its shadow-depth pass uses
4x MSAA, resolved into the moment texture; the moments get a full mip chain; lookups use 16x
anisotropic filtering. Here each texel holds the moments of one depth sample (the texel
centre) and lookups are bilinear on the top level, so distant, minified receivers alias
more than in the sample. The ``filter`` parameter's source says "in part", and
``diagnostics["not_modelled"]`` records it.

References
----------
.. [1] A. Lauritzen, M. Salvi, A. Lefohn, "Sample Distribution Shadow Maps", I3D 2011.
   DOI: 10.1145/1944745.1944761
.. [2] Intel Corporation, "Sample Distribution Shadow Maps" DX11 sample (2010-2012):
   LogPartitions.hlsl, SDSMPartitions.hlsl, AdaptiveLogPartitions.hlsl,
   KMeansPartitions.hlsl, App.cpp.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from .. import splits as _splits
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..light_frame import Projection
from ..params import param
from .common import CommonParams
from .engine import execute
from .fit import aabb, light_box, light_frame_for
from .frustum import frustum_slice
from .records import Partition, Setup

__all__ = [
    "LIGHTS",
    "NAME",
    "SdsmParams",
    "build",
    "partition_texture_bounds",
    "run",
    "to_texture",
]

NAME = "sdsm"

#: Light kinds the technique supports.
LIGHTS = ("directional",)

#: Compute dispatches of the sample's reduce path (clear/reduce z bounds, partitions, clear/
#: reduce light-space bounds, custom partitions) and of its histogram paths.
COMPUTE_PASSES = {"log": 6, "log_histogram": 3, "adaptive_log": 3, "kmeans": 3}

#: Smallest partition extent, as a fraction of the global light box (a zoom of at most 1e6):
#: keeps degenerate partitions (one sample) finite and float64 lookups meaningful.
MIN_EXTENT = 1e-6


@dataclass(frozen=True)
class SdsmParams(CommonParams):
    """Parameters of ``sdsm`` (shared ones in :class:`CommonParams`)."""

    resolution: int = param(
        1024,
        source="Intel SDSM sample gDefaultShadowDim 1024",
        help="shadow-map texels per side of each partition",
        lo=8,
        hi=16384,
    )
    filter: str = param(
        "evsm4",
        source="Intel SDSM sample gDefaultFiltering EVSM (4-component), in part: the sample "
        "renders shadow depth with 4x MSAA resolved into the moments, builds a mip chain and "
        "samples with 16x anisotropy; this model takes 1 depth per texel and samples the top "
        "level bilinearly (no MSAA, mips or anisotropy)",
        help="point, hw_pcf, pcf (NxN), poisson, vsm, evsm2, evsm4 (moments of 1 sample per "
        "texel, bilinear, no mips: softer-edged and more aliased at a distance than the "
        "Intel sample's EVSM)",
        choices=("point", "hw_pcf", "pcf", "poisson", "vsm", "evsm2", "evsm4"),
    )
    evsm_positive: float = param(
        800.0,
        source="Intel SDSM sample positiveExponent 800 (light-space units)",
        help="EVSM positive exponent per global light-space depth; scaled by each "
        "partition's depth extent and clamped to 42 (float32) / 5.54 (float16)",
        lo=0.0,
        hi=1e5,
    )
    evsm_negative: float = param(
        100.0,
        source="Intel SDSM sample negativeExponent 100 (light-space units)",
        help="EVSM negative exponent (EVSM4), scaled like the positive one",
        lo=0.0,
        hi=1e5,
    )
    evsm_light_space: bool = param(
        True,
        source="Intel SDSM sample GetEVSMExponents: c / partition.scale.z",
        help="exponents are per global light-space depth (scaled by each partition's extent)",
    )
    partitions: int = param(
        4,
        source="Intel SDSM sample gDefaultPartitions 4",
        help="number of partitions",
        lo=1,
        hi=8,
    )
    scheme: str = param(
        "log",
        source="Intel SDSM sample default partitionScheme LOG_PARTITIONS_REDUCE",
        help="log (min/max reduction), log_histogram, adaptive_log, kmeans (histogram paths)",
        choices=("log", "log_histogram", "adaptive_log", "kmeans"),
    )
    stretch_ends: bool = param(
        True,
        source="Intel SDSM sample ComputeLogPartitionsFromZBounds (first/last expanded)",
        help="first partition starts at the camera near plane, last ends at the far plane",
    )
    tight_bounds: bool = param(
        True,
        source="Intel SDSM sample ReduceBoundsFromGBuffer",
        help="tight light-space bounds from the samples (off: frustum-slice corners)",
    )
    light_up: str = param(
        "camera_right",
        source="Intel SDSM sample alignLightToFrustum = 1",
        help="light frame up: camera_right (camera Z -> light X) or world (+Y)",
        choices=("world", "camera_right"),
    )
    border_xy: float = param(
        0.0,
        source="Intel SDSM sample: blur border = 0 with edge softening off",
        help="light-space border added around each partition's samples, world units",
        lo=0.0,
    )
    border_z: float = param(
        1.0,
        source="Intel SDSM sample partitionBorderLightSpace.z = 1 * lightProj._33",
        help="depth border added in front of and behind each partition's samples, world units",
        lo=0.0,
    )
    dilation_texels: float = param(
        10.0,
        source="Intel SDSM sample mDilationFactor = 10 / shadowTextureDim",
        help="dilation of each partition, in texels of its map (d = dilation_texels / R)",
        lo=0.0,
    )
    max_scale: float = param(
        math.inf,
        source="Intel SDSM sample maxPartitionScale FLT_MAX (edge softening off)",
        help="largest x/y zoom of a partition relative to the global light box (kept centred; "
        "inf = no limit)",
        lo=1e-6,
        allow_inf=True,
    )
    quantize: bool = param(
        False,
        source="Intel SDSM sample quantizePartitions 0",
        help="round each zoom down to a power of two and snap the bias to texels "
        "(disables align-to-frustum)",
    )
    histogram_bins: int = param(
        1024,
        source="Intel SDSM sample BINS 1024",
        help="depth histogram bins (histogram schemes)",
        lo=8,
        hi=65536,
    )
    histogram_power: float = param(
        10.0,
        source="Intel SDSM sample histogramResolutionPower 10",
        help="bin warp: bin = ((z - n) / (f - n))^(1 / power) * bins",
        lo=1.0,
        hi=30.0,
    )
    lloyd_iterations: int = param(
        32,
        source="Intel SDSM sample lloydIterations 32",
        help="K-means Lloyd iterations",
        lo=0,
        hi=1000,
    )
    depth_readback: str = param(
        "float32",
        source="Intel SDSM sample reduces float view depth",
        help="precision of the min/max depth: float32, or unorm16 (quantum (f - n) / 65535, "
        "a known failure mode)",
        choices=("float32", "unorm16"),
    )
    sky_as_far: bool = param(
        False,
        source="Intel SDSM sample excludes z >= far",
        help="failure mode: sky pixels count as depth = far (pins zmax to the far plane)",
    )
    latency: int = param(
        0,
        source="seed notes, second approach (depth prepass, partitions on the GPU)",
        help="frames between the depth used for the partitions and the frame shaded (first "
        "approach: CPU readback, 1-2 frames); earlier frames along the scene's camera path",
        lo=0,
        hi=64,
    )


def _reduce_depth(gb, camera, p: SdsmParams):
    """(zmin, zmax, sample mask) of the Intel reduction over a G-buffer."""
    z = gb.depth
    samples = gb.valid & (z >= camera.near) & (z < camera.far)
    if not samples.any():
        return None, None, samples
    # Masked reductions (no gathered copy); min/max are exact in any order.
    zmin = float(np.min(z, where=samples, initial=np.inf))
    zmax = float(np.max(z, where=samples, initial=-np.inf))
    if p.sky_as_far and (~gb.valid).any():
        zmax = camera.far
    if p.depth_readback == "unorm16":
        n, f = camera.near, camera.far
        q = 65535.0

        def unq(v):
            return n + np.round((v - n) / (f - n) * q) / q * (f - n)

        zmin, zmax = float(unq(zmin)), float(unq(zmax))
        zmin = max(zmin, n)
        zmax = max(zmax, zmin * (1.0 + 1e-9))
    return zmin, zmax, samples


def _global_box(scene, camera, frame, p: SdsmParams):
    """The sample's global light box: the view frustum's extents in the light frame, or the
    scene's bounding box when partitions are quantized (App.cpp: fixed, so that quantized
    partitions do not move with the camera)."""
    bmin, bmax = light_box(
        frame,
        scene,
        camera,
        whole_scene=p.quantize,
        precision=p.matrix_precision,
        inverse=p.view_projection_inverse,
    )
    return bmin, np.maximum(bmax - bmin, 1e-12)


def _partition_box(lo_tc, hi_tc, p: SdsmParams, gmin, gdim):
    """ComputePartitionDataFromBounds: texture-space bounds -> light-frame extent, or None."""
    if np.any(hi_tc < lo_tc):
        return None, {"empty": True}
    border = np.array([p.border_xy / gdim[0], p.border_xy / gdim[1], p.border_z / gdim[2]])
    lo = lo_tc - border
    hi = hi_tc + border
    # A partition of one sample (or of samples on a line) has zero extent: the sample's
    # 1 / (max - min) is infinite. Floor the extent so the zoom stays finite (MIN_EXTENT).
    span = np.maximum(hi - lo, MIN_EXTENT)
    scale = 1.0 / span
    bias = -lo * scale
    d = p.dilation_texels / p.resolution
    d = min(d, 0.49)
    scale = scale * (1.0 - 2.0 * d)
    bias = d + (1.0 - 2.0 * d) * bias
    # The sample clamps the x/y zoom only (maxPartitionScale.z stays FLT_MAX).
    target = scale.copy()
    target[:2] = np.minimum(scale[:2], p.max_scale)
    if p.quantize:
        target[:2] = np.maximum(1.0, np.exp2(np.floor(np.log2(target[:2]))))
    bias = (target / scale) * (bias - 0.5) + 0.5
    scale = target
    if p.quantize:
        bias[:2] = np.floor(bias[:2] * p.resolution) / p.resolution
    # Region of the global box this partition's [0, 1] texture covers.
    t0 = (0.0 - bias) / scale
    t1 = (1.0 - bias) / scale
    x0 = gmin[0] + gdim[0] * t0[0]
    x1 = gmin[0] + gdim[0] * t1[0]
    gmax_y = gmin[1] + gdim[1]
    y1 = gmax_y - gdim[1] * t0[1]
    y0 = gmax_y - gdim[1] * t1[1]
    z0 = gmin[2] + gdim[2] * t0[2]
    z1 = gmin[2] + gdim[2] * t1[2]
    info = {
        "empty": False,
        "texture_bounds_min": lo_tc.tolist(),
        "texture_bounds_max": hi_tc.tolist(),
        "scale": scale.tolist(),
        "bias": bias.tolist(),
    }
    return (x0, x1, y0, y1, z0, z1), info


def to_texture(frame, gmin, gdim, points):
    """Global light-box texture coordinates (u right, v down, z in [0, 1]) of world points."""
    return _light_to_texture(frame.to_light(points), gmin, gdim)


def _light_to_texture(lc, gmin, gdim):
    """:func:`to_texture` of light-frame coordinates ``lc`` (N, 3)."""
    u = (lc[:, 0] - gmin[0]) / gdim[0]
    v = (gmin[1] + gdim[1] - lc[:, 1]) / gdim[1]
    z = (lc[:, 2] - gmin[2]) / gdim[2]
    return np.stack([u, v, z], axis=1)


def partition_texture_bounds(frame, gmin, gdim, points, part, k):
    """Per-partition min/max of the :func:`to_texture` coordinates of ``points`` (partition
    ``part``, ``-1`` for none) and the sample counts: the sample's per-partition reduction.
    ``points`` (float64, the caller's own copy) is overwritten.

    Each texture coordinate is a monotone function of one light-frame coordinate (IEEE
    rounding is monotone; ``v`` decreases with light y), so the extremes of the texture
    coordinates are the transformed extremes of the light-frame coordinates: the same values
    as reducing :func:`to_texture` of every sample, without transforming every sample.
    """
    # frame.to_light(points), its subtraction made in place (``points`` is our own gather).
    points -= frame.origin
    lc = points @ frame.rotation().T
    lo_l = np.full((k, 3), np.inf)
    hi_l = np.full((k, 3), -np.inf)
    counts = np.zeros(k, dtype=np.int64)
    for i in range(k):  # one masked reduction per partition and axis (no copies)
        mask = part == i
        counts[i] = np.count_nonzero(mask)
        if counts[i]:
            for a in range(3):
                lo_l[i, a] = np.min(lc[:, a], where=mask, initial=np.inf)
                hi_l[i, a] = np.max(lc[:, a], where=mask, initial=-np.inf)
    lo = np.full((k, 3), np.inf)
    hi = np.full((k, 3), -np.inf)
    filled = counts > 0
    t_lo = _light_to_texture(lo_l[filled], gmin, gdim)
    t_hi = _light_to_texture(hi_l[filled], gmin, gdim)
    # u and z increase with light x and z; v decreases with light y.
    lo[filled] = np.stack([t_lo[:, 0], t_hi[:, 1], t_lo[:, 2]], axis=1)
    hi[filled] = np.stack([t_hi[:, 0], t_lo[:, 1], t_hi[:, 2]], axis=1)
    return lo, hi, counts


def _intervals(z_bounds, camera, p: SdsmParams):
    z = np.array(z_bounds, dtype=np.float64)
    if p.stretch_ends:
        z[0], z[-1] = camera.near, camera.far
    return z


def _partitions_from_depth(scene, gb, camera, light, p: SdsmParams):
    """Partitions (intervals, per-partition texture bounds) from one G-buffer."""
    zmin, zmax, samples = _reduce_depth(gb, camera, p)
    # Quantized partitions cannot follow the camera's rotation (texel jitter): world up.
    frame = light_frame_for(light, camera, "world" if p.quantize else p.light_up)
    gmin, gdim = _global_box(scene, camera, frame, p)
    k = p.partitions
    diag: dict = {
        "zmin": zmin,
        "zmax": zmax,
        "samples": int(samples.sum()),
        "light_up_used": frame.up_used,
        "global_light_box": {"min": gmin.tolist(), "size": gdim.tolist()},
    }
    if zmin is None:
        return None, frame, gmin, gdim, diag
    z = gb.depth[samples]
    if p.scheme == "log":
        bounds = _intervals(_splits.log_splits(zmin, zmax, k), camera, p)
        near_z, far_z = bounds[0], bounds[-1]
        keep = (z >= near_z) & (z < far_z)
        # Number of interior boundaries at or below z (boundaries increase).
        part = np.searchsorted(bounds[1:-1], z, side="right")
        part = np.where(keep, part, -1)
        lo, hi, counts = partition_texture_bounds(frame, gmin, gdim, gb.position[samples], part, k)
    else:
        tc = to_texture(frame, gmin, gdim, gb.position[samples])
        h = _splits.build_histogram(
            z, tc, camera.near, camera.far, p.histogram_bins, p.histogram_power
        )
        if p.scheme == "log_histogram":
            ends = _splits.log_bins(h, k)
        elif p.scheme == "adaptive_log":
            ends = _splits.adaptive_log_bins(h, k)
        else:
            ends = _splits.kmeans_bins(h, k, p.lloyd_iterations)
        starts = np.concatenate([[0], ends[:-1]])
        bin_part = np.sum(np.arange(h.bins)[:, None] >= ends[None, :-1], axis=1)
        lo = np.full((k, 3), np.inf)
        hi = np.full((k, 3), -np.inf)
        filled = h.count > 0
        for axis in range(3):
            np.minimum.at(lo[:, axis], bin_part[filled], h.lo[filled, axis])
            np.maximum.at(hi[:, axis], bin_part[filled], h.hi[filled, axis])
        counts = np.bincount(bin_part, weights=h.count, minlength=k).astype(np.int64)
        edges = np.concatenate([h.bin_to_z(starts), [h.bin_to_z(ends[-1])]])
        bounds = _intervals(edges, camera, p)
        diag["histogram"] = {
            "bins": h.bins,
            "power": h.power,
            "partition_end_bins": ends.tolist(),
            "populated_bins": int(filled.sum()),
        }
    parts = []
    for i in range(k):
        extent, info = _partition_box(lo[i], hi[i], p, gmin, gdim)
        info["samples"] = int(counts[i])
        parts.append((float(bounds[i]), float(bounds[i + 1]), extent, info))
    return parts, frame, gmin, gdim, diag


def build(scene, gbuf, p: SdsmParams) -> Setup:
    """SDSM partitions from the current frame's depth, or from ``latency`` frames earlier."""
    light = scene.light
    if light.kind not in LIGHTS:
        raise ModelError(
            f"{NAME} needs a directional light; the scene's light is a {light.kind} light "
            "(use shadow-map)"
        )
    src_frame = scene.frame
    if p.latency > 0:
        src_frame = max(scene.frame - p.latency, 0)
        src_scene = scene.with_frame(src_frame) if scene.camera_path else scene
        src_gb = trace_gbuffer(src_scene) if src_scene is not scene else gbuf
    else:
        src_scene, src_gb = scene, gbuf
    src_cam = src_scene.camera
    parts, frame, gmin, gdim, diag = _partitions_from_depth(scene, src_gb, src_cam, light, p)
    if p.filter in ("vsm", "evsm2", "evsm4"):
        diag["not_modelled"] = (
            "Intel sample: 4x MSAA shadow depth resolved into the moments, moment mip chain, "
            "16x anisotropic lookups (here: 1 sample per texel, bilinear top level)"
        )
    diag.update(
        scheme=p.scheme,
        latency_frames=p.latency,
        depth_source_frame=src_frame,
        shaded_frame=scene.frame,
        camera_path=scene.camera_path,
        light=light.to_json(),
    )
    k = p.partitions
    if parts is None:
        # No valid sample: every partition is the empty sentinel; no shadow work at all.
        cam = scene.camera
        bounds = _splits.log_splits(cam.near, cam.far, k)
        partitions = [
            Partition(None, float(bounds[i]), float(bounds[i + 1]), {"empty": True})
            for i in range(k)
        ]
        diag["note"] = "no valid depth samples: all partitions empty, shadow passes skipped"
        return Setup(
            partitions,
            selection="depth",
            outside="discard",
            diagnostics=diag,
            compute_passes=COMPUTE_PASSES[p.scheme],
            readback_latency=p.latency,
            depth_extent_reference=float(gdim[2]),
            skip_rendering=True,
        )
    partitions = []
    cur_cam = scene.camera
    for z_a, z_b, extent, info in parts:
        if not p.tight_bounds and info.get("samples", 0) > 0:
            corners = frustum_slice(
                cur_cam,
                max(z_a, cur_cam.near),
                min(z_b, cur_cam.far),
                precision=p.matrix_precision,
                inverse=p.view_projection_inverse,
            ).astype(np.float64)
            bmin, bmax = aabb(frame, corners)
            extent = (bmin[0], bmax[0], bmin[1], bmax[1], bmin[2], bmax[2])
            info = dict(info, fit="frustum_slice_corners")
        proj = None
        if extent is not None:
            proj = Projection("ortho", frame, extent, p.resolution, p.matrix_precision)
        partitions.append(Partition(proj, z_a, z_b, info))
    return Setup(
        partitions,
        selection="depth",
        outside="discard",
        diagnostics=diag,
        compute_passes=COMPUTE_PASSES[p.scheme],
        readback_latency=p.latency,
        depth_extent_reference=float(gdim[2]),
    )


def run(scene, params: SdsmParams | None = None, **kwargs):
    """Run ``sdsm`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, SdsmParams, kwargs)
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, p)
    return execute(NAME, scene, gbuf, setup, p, _params.as_dict(p), t0)
