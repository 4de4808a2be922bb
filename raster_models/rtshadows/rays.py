"""The shadow rays an engine traces at one ray a pixel, and NRD SIGMA's packed input.

**AMD FidelityFX hybrid shadows** (GPUOpen-LibrariesAndSDKs/FidelityFX-SDK, tag v1.1.4, commit
c6efa6bf7f2027b3ec94f28578bb5965eabb9e55):

- origin: the primary hit plus the normal times ``1e-4`` (``samples/hybridshadows/
  hybridshadowsrendermodule.cpp:606``, used as ``worldPos + normal * x`` in
  ``samples/hybridshadows/shaders/traceshadows.hlsl:91``);
- noise: ``t2d_blueNoise[pixelCoord % 128].rg + phase``, ``fmod(noise, 1)``
  (``traceshadows.hlsl:97-99``), the texture RGBA8_UNORM (``hybridshadowsrendermodule.cpp:57,
  64``: ``static_cast<byte>(f * UCHAR_MAX)``, read back as ``byte / 255``); the phase
  ``(frame & 0xff) * GOLDEN_RATIO`` with ``GOLDEN_RATIO = 1.6180339887f``
  (``hybridshadowsrendermodule.cpp:95, 608``). This project's tile replaces the sample's
  (:mod:`.bluenoise`);
- direction: ``normalize(MapToCone(s, -lightDir, sunSize))`` (``traceshadows.hlsl:99``), with
  ``MapToCone`` Shirley-Chiu's concentric map scaled by ``radius`` on the tangent plane of
  ``CreateTangentVectors`` (``framework/cauldron/framework/inc/shaders/raytracingcommon.hlsl:
  130-173``) and ``sunSize = tanf(0.5 * angle)`` for the UI's "sun solid angle" ``angle``
  (in fact the cone's full apex angle, ``hybridshadowsrendermodule.cpp:705``).

A disk area light far away is this project's sun with an angular size (the soft truth
integrates over the disk); its apex angle is ``2 atan(r / d)`` from the scene's centre. A
rectangle light has no AMD ray; the same noise picks a uniform point on it (this project's
choice, the estimator whose mean is the truth's ``light_fraction``). A directional light is a
sun of no angular size (the cone's radius 0), a point, spot or sphere light a point: hard
shadows, as their truth.

**NVIDIA NRD SIGMA input** (NVIDIA-RTX/NRD commit a822d87f6202650da1dcebaeaf1f2c5b0b7be112,
``Shaders/NRD.hlsli``): ``SIGMA_FrontEnd_PackPenumbra(distanceToOccluder,
tanOfLightAngularRadius)`` for a sun (lines 973-979) and ``(distanceToOccluder,
distanceToLight, lightSize)`` for a local light (lines 984-990), a miss being
``NRD_FP16_MAX = 65504`` (line 354; ``NRD_EPS = 1e-6``, line 356). All arithmetic is float32
as on the GPU, so a frame's rays and packed inputs are the same bits on every run.
"""

from __future__ import annotations

import numpy as np

from .bluenoise import TILE, blue_noise_tile

__all__ = [
    "GOLDEN_RATIO",
    "NRD_EPS",
    "NRD_FP16_MAX",
    "PIXEL_THICKNESS",
    "ShadowRays",
    "cone_directions",
    "map_to_cone",
    "noise_phase",
    "pack_penumbra_local",
    "pack_penumbra_sun",
    "pixel_noise",
    "sun_size",
    "tangent_vectors",
]

F32 = np.float32
#: hybridshadowsrendermodule.cpp:95
GOLDEN_RATIO = F32(1.6180339887)
#: hybridshadowsrendermodule.cpp:606 (``pixelThickness``)
PIXEL_THICKNESS = F32(1e-4)
#: NRD.hlsli:354
NRD_FP16_MAX = F32(65504.0)
#: NRD.hlsli:356
NRD_EPS = F32(1e-6)
_PI = F32(3.14159265358979)


def noise_phase(frame: int) -> np.float32:
    """``(frame & 0xff) * GOLDEN_RATIO`` in float32 (hybridshadowsrendermodule.cpp:608)."""
    return F32(F32(int(frame) & 0xFF) * GOLDEN_RATIO)


def sun_size(apex_angle_rad: float) -> np.float32:
    """``tanf(0.5 * angle)``: the cone's radius on the unit-distance plane
    (hybridshadowsrendermodule.cpp:705; the angle there is converted from degrees)."""
    return F32(np.tan(F32(0.5) * F32(apex_angle_rad)))


def pixel_noise(px: np.ndarray, py: np.ndarray, frame: int, tile=None) -> np.ndarray:
    """``(N, 2)`` float32 ``fmod(unorm8(tile[y % 128, x % 128]) + phase, 1)``."""
    tile = blue_noise_tile() if tile is None else tile
    texel = tile[np.asarray(py) % TILE, np.asarray(px) % TILE]
    unorm = (np.floor(texel.astype(F32) * F32(255.0)) / F32(255.0)).astype(F32)
    return np.fmod(unorm + noise_phase(frame), F32(1.0)).astype(F32)


def _normalize(v: np.ndarray) -> np.ndarray:
    return (v / np.sqrt(np.sum(v * v, axis=-1, dtype=F32))[..., None]).astype(F32)


def tangent_vectors(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``CreateTangentVectors`` (raytracingcommon.hlsl:130-139): ``t0 = normalize(up x n)``,
    ``t1 = n x t0``, ``up = +Z`` unless ``|n.z| >= 0.99999`` (then ``+X``). ``(N, 3)``."""
    n = np.asarray(n, dtype=F32).reshape(-1, 3)
    up = np.where(
        (np.abs(n[:, 2]) < F32(0.99999))[:, None],
        np.array([0, 0, 1], dtype=F32),
        np.array([1, 0, 0], dtype=F32),
    )
    t0 = _normalize(np.cross(up, n).astype(F32))
    return t0, np.cross(n, t0).astype(F32)


def map_to_cone(s: np.ndarray, n: np.ndarray, radius) -> np.ndarray:
    """``MapToCone`` (raytracingcommon.hlsl:142-173), unnormalised: ``n + radius r (cos theta
    t0 + sin theta t1)`` for the concentric map of ``2 s - 1``. ``s`` ``(N, 2)``, ``n``
    ``(N, 3)`` or ``(3,)``."""
    s = np.asarray(s, dtype=F32).reshape(-1, 2)
    n = np.broadcast_to(np.asarray(n, dtype=F32), (len(s), 3))
    off = (F32(2.0) * s - F32(1.0)).astype(F32)
    ox, oy = off[:, 0], off[:, 1]
    zero = (ox == 0) & (oy == 0)
    first = np.abs(ox) > np.abs(oy)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, ox, oy)
        theta = np.where(
            first,
            (_PI / F32(4.0)) * (oy / ox),
            (_PI / F32(2.0)) * (F32(1.0) - F32(0.5) * (ox / oy)),
        ).astype(F32)
    rad = F32(radius)
    u = (rad * r * np.cos(theta)).astype(F32)
    v = (rad * r * np.sin(theta)).astype(F32)
    t0, t1 = tangent_vectors(n)
    out = (n + u[:, None] * t0 + v[:, None] * t1).astype(F32)
    return np.where(zero[:, None], n, out)


def cone_directions(light_dir, noise: np.ndarray, radius) -> np.ndarray:
    """``normalize(MapToCone(noise, -lightDir, sunSize))`` (traceshadows.hlsl:99): ``(N, 3)``
    float32 directions towards the sun; ``light_dir`` the direction the light travels."""
    axis = -np.asarray(light_dir, dtype=F32)
    return _normalize(map_to_cone(noise, axis, radius))


def pack_penumbra_sun(hit_t: np.ndarray, tan_angular_radius) -> np.ndarray:
    """``SIGMA_FrontEnd_PackPenumbra(distanceToOccluder, tanOfLightAngularRadius)``
    (NRD.hlsli:973-979): ``0.5 hitT tan``, capped at 32768; a miss (``hitT >= 65504``) 65504."""
    h = np.asarray(hit_t, dtype=F32)
    radius = (h * F32(tan_angular_radius) * F32(0.5)).astype(F32)
    return np.where(h >= NRD_FP16_MAX, NRD_FP16_MAX, np.minimum(radius, F32(32768.0))).astype(F32)


def pack_penumbra_local(hit_t, distance_to_light, light_size) -> np.ndarray:
    """``SIGMA_FrontEnd_PackPenumbra(distanceToOccluder, distanceToLight, lightSize)``
    (NRD.hlsli:984-990): ``0.5 lightSize hitT / max(dL - hitT, NRD_EPS)``, capped; a miss
    65504."""
    h = np.asarray(hit_t, dtype=F32)
    dl = np.asarray(distance_to_light, dtype=F32)
    size = (F32(light_size) * h / np.maximum(dl - h, NRD_EPS)).astype(F32)
    radius = (size * F32(0.5)).astype(F32)
    return np.where(h >= NRD_FP16_MAX, NRD_FP16_MAX, np.minimum(radius, F32(32768.0))).astype(F32)


class ShadowRays:
    """One frame's rays: ``origin``, ``direction`` ``(N, 3)`` float32, ``tmax`` ``(N,)``
    float32 (to the light: the sampled point, or the sun disk's plane), and the light's
    geometry the NRD packing needs (``tan_radius`` for a sun, else ``light_size``)."""

    def __init__(self, origin, direction, tmax, *, sun: bool, tan_radius=0.0, light_size=0.0):
        self.origin, self.direction, self.tmax = origin, direction, tmax
        self.sun, self.tan_radius, self.light_size = sun, F32(tan_radius), F32(light_size)

    def pack(self, hit_t: np.ndarray) -> np.ndarray:
        """SIGMA's ``IN_PENUMBRA`` of this frame's hit distances (``inf``: a miss)."""
        h = np.where(np.isfinite(hit_t), hit_t, NRD_FP16_MAX).astype(F32)
        if self.sun:
            return pack_penumbra_sun(h, self.tan_radius)
        return pack_penumbra_local(h, self.tmax, self.light_size)


def _punctual_rays(light, origin) -> ShadowRays:
    """A directional light's ray (a sun of no angular size: AMD's cone of radius 0) or the
    ray to a point, spot or sphere light's centre (stopping at a sphere's surface): hard
    shadows, NRD's penumbra 0 where a ray is blocked."""
    if light.kind == "directional":
        d = cone_directions(np.asarray(light.direction, dtype=F32), np.zeros((len(origin), 2)), 0)
        tmax = np.full(len(origin), np.inf, dtype=F32)
        return ShadowRays(origin, d, tmax, sun=True, tan_radius=0.0)
    to = np.asarray(light.position, dtype=np.float64) - origin.astype(np.float64)
    dist = np.sqrt(np.einsum("ij,ij->i", to, to))
    d = (to / np.maximum(dist, 1e-30)[:, None]).astype(F32)
    tmax = ((dist - light.shadow_end) * (1.0 - 1e-5)).astype(F32)
    return ShadowRays(origin, d, tmax, sun=False, light_size=0.0)


def frame_rays(light, position, normal, px, py, frame: int, *, centre=None) -> ShadowRays:
    """The rays of pixels ``(px, py)`` whose primary hits are ``position`` with shading
    normals ``normal`` (``(N, 3)``), frame ``frame``, towards ``light``
    (:class:`scenes.lights.Light`: a disk area light is a sun of angular size, a rectangle
    one is sampled over its area, other lights give hard rays). ``centre``: the point the
    sun's angular size is measured from (default the origin)."""
    p = np.asarray(position, dtype=F32).reshape(-1, 3)
    n = np.asarray(normal, dtype=F32).reshape(-1, 3)
    origin = (p + n * PIXEL_THICKNESS).astype(F32)
    s = pixel_noise(px, py, frame)
    lpos = np.asarray(light.position, dtype=np.float64)
    ln = np.asarray(light.direction, dtype=np.float64)
    if light.area == "disk":
        c = np.zeros(3) if centre is None else np.asarray(centre, dtype=np.float64)
        dist = float(np.linalg.norm(lpos - c))
        half = float(np.arctan(light.radius / dist))
        tan_r = sun_size(2.0 * half)
        d = cone_directions(ln.astype(F32), s, tan_r)
        # to the disk's plane, a hair short of it: the emitter is not an occluder
        denom = np.einsum("ij,j->i", d.astype(np.float64), ln)
        t = np.einsum("ij,j->i", lpos - origin.astype(np.float64), ln) / np.minimum(denom, -1e-12)
        tmax = (t * (1.0 - 1e-5)).astype(F32)
        return ShadowRays(origin, d, tmax, sun=True, tan_radius=np.tan(half))
    if light.area != "rectangle":
        return _punctual_rays(light, origin)
    q = np.asarray(light.area_point(s[:, 0].astype(np.float64), s[:, 1].astype(np.float64)))
    q = q.reshape(-1, 3)
    to = q - origin.astype(np.float64)
    dist = np.sqrt(np.einsum("ij,ij->i", to, to))
    d = (to / dist[:, None]).astype(F32)
    w, h = light.extent
    size = float(np.sqrt(w * h))
    return ShadowRays(origin, d, (dist * (1.0 - 1e-5)).astype(F32), sun=False, light_size=size)
