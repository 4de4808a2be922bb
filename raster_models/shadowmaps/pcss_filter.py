"""Percentage-closer soft shadows (PCSS) as a shadow-map filter, vectorized over receivers.

Three steps per receiver (Fernando 2005; NVIDIA's sample code in Bavoil 2008):

1. **Blocker search**: point-sample the map at ``blocker_samples`` disk taps over a region
   scaled by the light's size, ``search = L_uv (z_r - n) / z_r`` (similar triangles: the part
   of the near plane through which the light can see the receiver), and average the depths
   of the taps nearer to the light than the receiver. No blocker: lit (visibility 1). ``n``
   is the depth of the nearest caster in the map (NVIDIA's ``NEAR_PLANE``, which its demo
   sets at the casters by hand): with a map's own near plane, often a thousandth of its far
   plane, the region would cover the whole map.
2. **Penumbra estimate** (parallel planes): ``w = (z_r - z_b) L / z_b`` at the receiver,
   i.e. a filter radius ``(z_r - z_b) / z_b * L_uv * n / z_r`` in map coordinates.
3. **Filter**: ``filter_samples`` hardware-PCF taps on a disk of that radius.

``z`` are linear distances from the light along its axis, ``n`` the map's near plane and
``L_uv = L / (2 n tan(fov/2))`` the light size in map coordinates at the near plane
(NVIDIA's ``LIGHT_SIZE_UV = LIGHT_WORLD_SIZE / LIGHT_FRUSTUM_WIDTH``). Orthographic maps
(directional lights) have a light of angular diameter ``theta``: the same steps with
``search = (z_r - z0) 2 tan(theta/2) / width`` and radius ``(z_r - z_b) 2 tan(theta/2) /
width``, ``width`` the map's side in world units.

NVIDIA uses ``LIGHT_WORLD_SIZE`` ``L`` as the disk *radius* in both steps; read as the
light's full width (this project's reading), the filter radius is twice the geometric
penumbra radius and its 16-tap transition (10-90 %) 2.71x a disk light's at every field of
view; ``radius_scale`` = 0.5 (the radius reading) gives 1.35x (measured:
``oracle.studies.pcss_extent``, docs/models.md). ``softness`` = ``hdrp`` replaces these
radii on perspective maps by HDRP 10.10.1's fitted mapping (:mod:`.pcss_hdrp`).

Disks: ``poisson16`` (NVIDIA's 16-point Poisson disk, Bavoil 2008, listing 1) and
``fibonacci`` (Unity HDRP ``HDPCSS.hlsl``: direction ``i * (3 - sqrt 5) pi`` modulo 2 pi,
radius ``sqrt(i / N + 0.5 / N)``), optionally rotated per pixel (HDRP: by interleaved
gradient noise, Jimenez 2014).

References
----------
.. [1] R. Fernando, "Percentage-closer soft shadows", SIGGRAPH 2005 Sketches.
   DOI: 10.1145/1187112.1187153
.. [2] L. Bavoil, "Integrating Realistic Soft Shadows into Your Game Engine", NVIDIA
   whitepaper WP-03780-001, 2008 (the PCSS sample: 16 blocker and 16 PCF samples, Poisson
   disk).
.. [3] Unity Technologies, HDRP 10.10.1 ``Runtime/Lighting/Shadow/HDPCSS.hlsl``: line 3
   (``DISK_SAMPLE_COUNT 64``), 21-87 (``fibonacciSpiralDirection``), 89-94 (sample radius),
   106-130 (``BlockerSearch``), 132-166 (``PCSS``); ``HDShadowSampling.hlsl`` 289-339
   (``SampleShadow_PCSS``: IGN rotation 297-298, minimum radius 333, lit without a blocker
   338). Published package mirror needle-mirror/com.unity.render-pipelines.high-definition,
   commit 6328cc84.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from . import filters as _filters
from . import pcss_hdrp as _hdrp

__all__ = [
    "DISKS",
    "POISSON_16",
    "blocker_search",
    "ESTIMATES",
    "disk",
    "estimates",
    "interleaved_gradient_noise",
    "linear_depth",
    "pcss_lookup",
    "penumbra_radius_uv",
    "search_radius_uv",
]

#: NVIDIA's 16-point Poisson disk (Bavoil 2008, the PCSS sample's ``poissonDisk[16]``).
POISSON_16 = np.array(
    [
        (-0.94201624, -0.39906216),
        (0.94558609, -0.76890725),
        (-0.094184101, -0.92938870),
        (0.34495938, 0.29387760),
        (-0.91588581, 0.45771432),
        (-0.81544232, -0.87912464),
        (-0.38277543, 0.27676845),
        (0.97484398, 0.75648379),
        (0.44323325, -0.97511554),
        (0.53742981, -0.47373420),
        (-0.26496911, -0.41893023),
        (0.79197514, 0.19090188),
        (-0.24188840, 0.99706507),
        (-0.81409955, 0.91437590),
        (0.19984126, 0.78641367),
        (0.14383161, -0.14100790),
    ],
    dtype=np.float64,
)

#: Disk patterns the filter knows.
DISKS = ("poisson16", "fibonacci")

#: HDRP's ``DISK_SAMPLE_COUNT`` (HDRP 10.10.1 HDPCSS.hlsl line 3): taps beyond it are never
#: read.
FIBONACCI_MAX = 64


@lru_cache(maxsize=32)
def disk(kind: str, taps: int) -> np.ndarray:
    """``(taps, 2)`` unit-disk offsets of a pattern.

    ``poisson16``: NVIDIA's table, cycled when more than 16 taps are asked for (the sample
    reads ``poissonDisk[i]`` for ``i < NUM_SAMPLES`` with both counts 16). ``fibonacci``:
    HDRP's spiral, ``min(taps, 64)`` points (its loops stop at ``DISK_SAMPLE_COUNT``).
    """
    if kind == "poisson16":
        return POISSON_16[np.arange(taps) % len(POISSON_16)].copy()
    if kind != "fibonacci":
        raise ValueError(f"unknown disk {kind!r}; choose one of {', '.join(DISKS)}")
    n = min(int(taps), FIBONACCI_MAX)
    i = np.arange(n, dtype=np.float64)
    b = math.pi * (3.0 - math.sqrt(5.0)) / (2.0 * math.pi)
    c = i * b
    theta = (c - np.floor(c)) * 2.0 * math.pi
    inv = 1.0 / float(taps)
    radius = np.sqrt(i * inv + 0.5 * inv)
    return np.stack([np.cos(theta) * radius, np.sin(theta) * radius], axis=1)


def interleaved_gradient_noise(px, py, frame: int = 0) -> np.ndarray:
    """Jimenez 2014 interleaved gradient noise in [0, 1) at pixel coordinates ``(px, py)``
    (HDRP's ``InterleavedGradientNoise``: frame offset ``(2.083, 4.867)`` per frame)."""
    x = np.asarray(px, dtype=np.float64) + frame * 2.083
    y = np.asarray(py, dtype=np.float64) + frame * 4.867
    inner = 0.06711056 * x + 0.00583715 * y
    inner = inner - np.floor(inner)
    val = 52.9829189 * inner
    return val - np.floor(val)


def linear_depth(proj, z) -> np.ndarray:
    """Linear distance along the light's axis of normalized map depths ``z``: ``tau = b /
    (a - z)`` for perspective maps, ``z0 + z (z1 - z0)`` for orthographic ones."""
    z = np.asarray(z, dtype=np.float64)
    if proj.kind == "persp":
        _, near, far = (float(x) for x in proj.extent)
        a, b = far / (far - near), far * near / (far - near)
        with np.errstate(divide="ignore"):
            return b / np.maximum(a - z, 1e-300)
    z0, z1 = float(proj.extent[4]), float(proj.extent[5])
    return z0 + z * (z1 - z0)


def _ortho_scale(proj, light_angle_deg: float) -> float:
    """``2 tan(theta / 2) / width``: map coordinates per unit of depth difference."""
    width = float(proj.extent[1] - proj.extent[0])
    return 2.0 * math.tan(math.radians(light_angle_deg) / 2.0) / width


def search_radius_uv(proj, z_r, *, light_size: float, light_angle: float, near=None):
    """Blocker-search radius in map coordinates at receiver depths ``z_r`` (linear);
    ``near``: the depth the search reaches back to (default the map's near plane)."""
    z_r = np.asarray(z_r, dtype=np.float64)
    if proj.kind == "persp":
        tan_half, n, _ = (float(x) for x in proj.extent)
        n = n if near is None else max(float(near), n)
        size_uv = light_size / (2.0 * n * tan_half)
        return size_uv * np.maximum(z_r - n, 0.0) / z_r
    z0 = float(proj.extent[4]) if near is None else max(float(near), float(proj.extent[4]))
    return np.maximum(z_r - z0, 0.0) * _ortho_scale(proj, light_angle)


def penumbra_radius_uv(proj, z_r, z_b, *, light_size: float, light_angle: float):
    """Filter radius in map coordinates of receivers at ``z_r`` with average blocker depth
    ``z_b`` (linear): ``(z_r - z_b) / z_b * L_uv * n / z_r``, or ``(z_r - z_b) 2 tan(theta/2)
    / width`` for orthographic maps."""
    z_r = np.asarray(z_r, dtype=np.float64)
    z_b = np.asarray(z_b, dtype=np.float64)
    if proj.kind == "persp":
        tan_half, near, _ = (float(x) for x in proj.extent)
        size_uv = light_size / (2.0 * near * tan_half)
        ratio = (z_r - z_b) / np.maximum(z_b, 1e-300)
        return ratio * size_uv * near / z_r
    return (z_r - z_b) * _ortho_scale(proj, light_angle)


#: The per-receiver estimates :func:`estimates` returns (the model's extra outputs).
ESTIMATES = ("penumbra_width", "blocker_distance")


def estimates(proj, ref, radius_uv, z_b, params) -> dict:
    """PCSS's estimates in world units at the receivers: ``penumbra_width``, the penumbra
    width the filter radius stands for before ``radius_scale`` (``physical``, Fernando's
    reading: the radius *is* the parallel-plane width ``(z_r - z_b) L / z_b``, or ``(z_r -
    z_b) 2 tan(theta/2)``; ``hdrp``: twice the radius, which HDRP fitted as the half-width of
    a ray-traced penumbra), at the receiver's depth, and ``blocker_distance`` (``z_r - z_b``
    along the light's axis); 0 where no blocker was found. ``params``: ``radius_scale`` and
    ``softness``."""
    z_r = linear_depth(proj, np.clip(np.asarray(ref, dtype=np.float64), 0.0, 1.0))
    found = np.asarray(z_b) > 0
    if proj.kind == "persp":
        per_uv = 2.0 * z_r * float(proj.extent[0])
    else:
        per_uv = np.full(z_r.shape, float(proj.extent[1] - proj.extent[0]))
    halves = 2.0 if (params.softness == "hdrp" and proj.kind == "persp") else 1.0
    scale = halves / params.radius_scale if params.radius_scale > 0 else 0.0
    width = np.where(found, np.asarray(radius_uv) * scale * per_uv, 0.0)
    return {"penumbra_width": width, "blocker_distance": np.where(found, z_r - z_b, 0.0)}


def _rotated(offsets: np.ndarray, rotation):
    """Per-receiver rotation of ``(taps, 2)`` offsets: HDRP's ``(x c + y s, -x s + y c)``
    with ``(s, c) = (sin, cos)`` of the angle; ``None``: unrotated."""
    if rotation is None:
        return [(ox, oy) for ox, oy in offsets]
    s, c = np.sin(rotation), np.cos(rotation)
    return [(ox * c + oy * s, -ox * s + oy * c) for ox, oy in offsets]


def _point_fetch(depth_map: np.ndarray, u, v, address: str) -> np.ndarray:
    """Nearest-texel stored depth (clamp: edge texels; border: 1, no blocker)."""
    r = depth_map.shape[0]
    ix = np.floor(np.asarray(u) * r)
    iy = np.floor(np.asarray(v) * r)
    inside = (ix >= 0) & (ix < r) & (iy >= 0) & (iy < r)
    ixc = np.clip(ix, 0, r - 1).astype(np.int64)
    iyc = np.clip(iy, 0, r - 1).astype(np.int64)
    val = depth_map[iyc, ixc].astype(np.float64)
    if address == "border":
        val = np.where(inside, val, 1.0)
    return val


def blocker_search(
    depth_map, proj, u, v, ref, radius_uv, offsets, rotation, *, address, average="linear"
):
    """Average depth of the blockers (taps with stored depth ``< ref``) and their count, per
    receiver; the average is NaN-free (0 where no tap is a blocker). ``average``: ``linear``
    (the mean linear depth) or ``stored`` (the mean stored depth: HDRP averages reversed-Z
    device depths, ``1 - z``, HDPCSS.hlsl:123-127)."""
    total = np.zeros(np.shape(u), dtype=np.float64)
    count = np.zeros(np.shape(u), dtype=np.float64)
    for dx, dy in _rotated(offsets, rotation):
        d = _point_fetch(depth_map, u + dx * radius_uv, v + dy * radius_uv, address)
        hit = d < ref
        total += np.where(hit, linear_depth(proj, d) if average == "linear" else d, 0.0)
        count += hit
    avg = np.where(count > 0, total / np.maximum(count, 1.0), 0.0)
    return avg, count


def _radii(data, proj, u, v, ref, z_r, params, rotation):
    """Blocker search and filter radius of the preset's softness mapping: ``(radius_uv,
    z_b linear, found)``. ``physical``: Fernando 2005 with the light's size; ``hdrp``:
    HDRP 10.10.1's fitted mapping of the shape radius (:mod:`.pcss_hdrp`; perspective maps)."""
    blockers = disk(params.disk, params.blocker_samples)
    common = {"address": params.address_mode}
    if params.softness == "hdrp" and proj.kind == "persp":
        res = int(data.depth.shape[0])
        shape = 0.5 * params.light_size
        search = params.radius_scale * _hdrp.search_radius_uv(shape, res)
        z_dev, count = blocker_search(
            data.depth, proj, u, v, ref, search, blockers, rotation, average="stored", **common
        )
        found = count > 0
        z_b = linear_depth(proj, np.clip(np.where(found, z_dev, ref), 0.0, 1.0))
        far = params.light_range or float(proj.extent[2])
        radius = _hdrp.filter_radius_uv(shape, res, z_r, z_b, far)
        return params.radius_scale * radius, z_b, found
    size = {"light_size": params.light_size, "light_angle": params.light_angle}
    # The search reaches back to the nearest caster in the map (NVIDIA's NEAR_PLANE, which
    # its demo places at the casters by hand; a map's own near plane can be far nearer).
    near = float(linear_depth(proj, np.min(data.depth))) if data.depth.size else None
    search = params.radius_scale * search_radius_uv(proj, z_r, near=near, **size)
    z_b, count = blocker_search(data.depth, proj, u, v, ref, search, blockers, rotation, **common)
    found = count > 0
    z_b = np.where(found, z_b, z_r)
    return params.radius_scale * penumbra_radius_uv(proj, z_r, z_b, **size), z_b, found


def pcss_lookup(data, proj, u, v, z, ref, params, rotation=None):
    """PCSS visibility of receivers at map coordinates ``(u, v)``, normalized depth ``z``,
    compare reference ``ref`` (``z`` minus the bias), from a rendered map ``data``
    (:class:`MapData`). ``params`` carries ``blocker_samples``, ``filter_samples``,
    ``disk``, ``softness``, ``light_size``, ``light_angle``, ``light_range``,
    ``radius_scale``, ``min_filter_uv``, ``address_mode`` and ``subtexel_bits``. Returns
    ``(visibility, radius_uv, z_blocker)`` (``z_blocker`` linear; radius 0 and blocker depth
    0 where no blocker was found)."""
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ref = np.broadcast_to(np.asarray(ref, dtype=np.float64), u.shape)
    z_r = linear_depth(proj, np.clip(ref, 0.0, 1.0))
    radius, z_b, found = _radii(data, proj, u, v, ref, z_r, params, rotation)
    radius = np.where(found, np.maximum(radius, params.min_filter_uv), 0.0)
    taps = disk(params.disk, params.filter_samples)
    acc = np.zeros(u.shape, dtype=np.float64)
    common = {"address": params.address_mode, "subtexel_bits": params.subtexel_bits}
    for dx, dy in _rotated(taps, rotation):
        acc += _filters.compare_bilinear(
            data.texels, u + dx * radius, v + dy * radius, ref, **common
        )
    # HDRP and NVIDIA divide by the sample count asked for (taps past the table are skipped).
    vis = acc / float(params.filter_samples)
    return np.where(found, vis, 1.0), radius, np.where(found, z_b, 0.0)
