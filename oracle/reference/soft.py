"""Area-light truth: soft visibility, light fraction and the area-lit colour of each camera
sample (the ``soft`` channel group of :mod:`oracle.reference.render`).

For a surface point ``x`` (facing normal ``n``) and an area light ``S`` of uniform radiance
``L`` (:mod:`scenes.lights`), with ``V(x, y)`` 1 where the segment from ``x`` to the light
point ``y`` is unblocked, the point receives (``n . l > 0``) and the light emits towards
it (rectangle and disk: one-sided, ``cos_e = -l . n_light > 0``):

- ``soft_visibility(x) = int V w dA / int w dA``, ``w = max(n . l, 0) max(cos_e, 0) / d^2``:
  the unoccluded fraction of the irradiance, what an engine's shadow factor multiplies
  (0 where no light reaches: ``int w dA = 0``);
- ``light_fraction(x) = (1 / |S|) int V dA``: the unoccluded fraction of the light's area,
  uniform, what PCSS estimates. A sphere light's "area" is the cone of directions it subtends
  from ``x`` (uniform in solid angle: its silhouette disk for a small light), and its ``w`` is
  ``max(n . l, 0)`` over that cone;
- the colour ``L_o = int f(l, v) L max(n . l, 0) V dw``: the shading model of
  :mod:`scenes.shading` under the true area light, plus the radiance of emitter surfaces seen
  directly.

Each camera sample takes :data:`LIGHT_SAMPLES` light samples, one jittered sample in each cell
of a ``4 x 4`` grid over the light's parameter square, the grid shifted toroidally by a random
offset per camera sample (rectangle: its two axes; disk: Shirley and Chiu's concentric map;
sphere: the subtended cone, uniform in solid angle), from TEA hashes of (pixel, camera sample,
light sample, seed): results never depend on chunking. Its
``soft_visibility`` is the ratio of the two sums over the same samples (1 where every sample is
lit, 0 where none is, exactly; the ratio's bias is of the order of the squared relative
variation of ``w`` within a grid cell over 16 samples, far below the standard error) and its
``light_fraction`` the mean of ``V``. The reference averages both over the pixel's camera
samples; their standard errors are the sample ones over camera samples (each camera sample's
light samples are independent of the others'). Sky samples are 1, samples on an emitter's
surface 0 (not receivers). A punctual light has one light sample, its own shadow ray: both
channels equal ``visibility``.
"""

from __future__ import annotations

import math

import numpy as np

from ...metrics.stats import binomial_stderr_floor
from ...scenes import backend
from ...scenes.backend.alpha_hit import loaded_alpha
from ...scenes.backend.raycast import occluded_segment_dr
from ...scenes.shading.phong import shade
from .group import SampledGroup, mean_variance, sample_stderr, stderr_summary

__all__ = ["LIGHT_GRID", "LIGHT_SAMPLES", "SoftGroup", "light_samples", "soft_samples"]

#: Light samples per camera sample: a ``LIGHT_GRID x LIGHT_GRID`` jittered grid.
LIGHT_GRID = 4
LIGHT_SAMPLES = LIGHT_GRID * LIGHT_GRID
#: XORed into the film jitter's per-pixel key: the light samples' hash stream differs from
#: the film's (any constant would do).
LIGHT_SALT = 0x5BD1E995
#: ... and the per-camera-sample grid shift's (:func:`_unit_square`).
SHIFT_SALT = 0x27D4EB2F
#: TEA rounds of the light samples' hash (as the film jitter's, :data:`render.JITTER_ROUNDS`).
LIGHT_ROUNDS = 6


def light_samples(light) -> int:
    """Light samples per camera sample: :data:`LIGHT_SAMPLES` for an area light, else 1."""
    return LIGHT_SAMPLES if light.is_area else 1


def _unit_square(mi, dr, pix_key, sample, k):
    """Sample ``k`` of a camera sample's jittered ``LIGHT_GRID x LIGHT_GRID`` grid, the whole
    grid shifted toroidally by a random offset of that camera sample (Dr.Jit).

    Without the shift, a straight shadow edge along a grid line of the light (an axis-aligned
    edge under an axis-aligned light: common) leaves every camera sample the same count of lit
    cells: no variance, so a standard error of 0 beside an error of up to one cell. The shift
    moves the cells' boundaries from one camera sample to the next; each sample stays uniform
    and each grid stratified."""
    key = pix_key ^ LIGHT_SALT
    a, b = mi.sample_tea_32(key, sample * LIGHT_SAMPLES + k, LIGHT_ROUNDS)
    sa, sb = mi.sample_tea_32(key ^ SHIFT_SALT, sample, LIGHT_ROUNDS)
    scale = 1.0 / (1 << 24)
    u = (mi.Float(k % LIGHT_GRID) + mi.Float(a >> 8) * scale) * (1.0 / LIGHT_GRID)
    v = (mi.Float(k // LIGHT_GRID) + mi.Float(b >> 8) * scale) * (1.0 / LIGHT_GRID)
    u = u + mi.Float(sa >> 8) * scale
    v = v + mi.Float(sb >> 8) * scale
    return u - dr.floor(u), v - dr.floor(v)


def _planar_samples(mi, dr, light, p, u, v):
    """Rectangle or disk: direction, distance, weight ``max(cos_e, 0) / d^2`` and the measure
    (the light's area) of uniform area samples."""
    q = light.area_point(u, v)
    to = q - p
    dist = dr.norm(to)
    wl = to / dist
    nl = [float(c) for c in light.direction]
    cos_e = -(wl.x * nl[0] + wl.y * nl[1] + wl.z * nl[2])
    return wl, dist, dr.maximum(cos_e, 0.0) / (dist * dist), light.surface_area


def _sphere_samples(mi, dr, light, p, u, v):
    """Sphere: directions uniform in the cone the sphere subtends from ``p``, the distance to
    its near surface, weight 1 (uniform solid angle) and the measure (the cone's solid angle;
    0 inside the sphere)."""
    c = mi.Point3f(*[float(t) for t in light.position])
    r = float(light.radius)
    to = c - p
    d2 = dr.squared_norm(to)
    d = dr.sqrt(d2)
    axis = to / d
    outside = d2 > r * r
    sin2_max = dr.select(outside, r * r / d2, 1.0)
    cos_max = dr.sqrt(dr.maximum(1.0 - sin2_max, 0.0))
    one_minus = sin2_max / (1.0 + cos_max)  # 1 - cos_max without cancellation
    cos_t = 1.0 - u * one_minus
    sin_t = dr.sqrt(dr.maximum(1.0 - cos_t * cos_t, 0.0))
    phi = (2.0 * math.pi) * v
    t1, t2 = mi.coordinate_system(axis)
    wl = axis * cos_t + (t1 * dr.cos(phi) + t2 * dr.sin(phi)) * sin_t
    half_chord = dr.sqrt(dr.maximum(r * r - d2 * sin_t * sin_t, 0.0))
    # the near root without cancellation: t_near * t_far = d^2 - r^2
    dist = dr.maximum(d2 - r * r, 0.0) / (d * cos_t + half_chord)
    measure = (2.0 * math.pi) * one_minus
    return wl, dist, dr.select(outside, 1.0, 0.0), measure


def _light_shape(loaded):
    """The Mitsuba shape of ``loaded``'s area light: the emitter shape of its kind whose
    bounding box is centred on the light (shapes need not have ids), or None."""
    light = loaded.light
    centre = np.asarray(light.position, dtype=np.float64)
    tol = 1e-4 * (1.0 + float(np.abs(centre).max()) + light.radius)
    for sh in loaded.mi_scene.shapes():
        if not (sh.is_emitter() and sh.class_name().lower() == light.area):
            continue
        bb = sh.bbox()
        mid = 0.5 * (np.array(bb.min, dtype=np.float64) + np.array(bb.max, dtype=np.float64))
        if float(np.abs(mid.ravel()[:3] - centre).max()) <= tol:
            return sh
    return None


def _reduce(dr, values):
    """Sum of each camera sample's ``LIGHT_SAMPLES`` consecutive values (symbolic: the
    widened arrays are never stored)."""
    return dr.block_reduce(dr.ReduceOp.Add, values, LIGHT_SAMPLES, mode="symbolic")


def soft_samples(loaded, res: dict, pix, sample, seed_key, *, color: bool) -> dict:
    """Per camera sample of ``res`` (:func:`scenes.backend.raycast.trace_film_dr` with ``keep_si``,
    and ``albedo`` with ``color``) under ``loaded``'s area light: ``soft`` and ``fraction``
    (Dr.Jit Float), ``light_rays`` (the shadow rays cast, Float) and, with ``color``, the
    area-lit ``color`` (Color3f). ``pix``, ``sample``: the camera samples' pixel and sample
    indices (UInt32); ``seed_key``: the pixels' film jitter keys
    (:func:`oracle.reference.sampling.jitter_key`)."""
    mi = backend.mitsuba()
    import drjit as dr

    light = loaded.light
    si = res["si"]
    count = dr.width(res["valid"])
    idx = dr.arange(mi.UInt32, count * LIGHT_SAMPLES)
    cam = idx // LIGHT_SAMPLES
    k = idx - cam * LIGHT_SAMPLES

    def g(value):
        return dr.gather(type(value), value, cam)

    p, ng, n, shape = g(si.p), g(si.n), g(res["normal"]), g(si.shape)
    receiver = g(res["valid"]) & ~shape.is_emitter()
    u, v = _unit_square(mi, dr, g(seed_key), g(mi.UInt32(sample)), k)
    sampler = _sphere_samples if light.area == "sphere" else _planar_samples
    wl, dist, w, measure = sampler(mi, dr, light, p, u, v)
    cos_r = dr.dot(n, wl)
    reach = receiver & (cos_r > 0.0) & (w > 0.0)
    # a ray may meet the light before its end (Mitsuba's float32 intersections of a sphere
    # light's rim or of a planar light seen at a grazing angle err by more than any margin):
    # blocked rays are traced again, ignoring the light
    blocked = occluded_segment_dr(
        loaded.mi_scene,
        p,
        ng,
        shape,
        wl,
        dist,
        reach,
        light_shape=_light_shape(loaded),
        alpha=loaded_alpha(loaded),  # alpha-tested casters block where their test keeps them
    )
    lit = reach & ~blocked
    weight = dr.select(reach, cos_r * w, 0.0)
    num = _reduce(dr, dr.select(lit, weight, 0.0))
    den = _reduce(dr, weight)
    valid = res["valid"]
    out = {
        "soft": dr.select(valid, dr.select(den > 0.0, num / den, 0.0), 1.0),
        "fraction": dr.select(
            valid, _reduce(dr, dr.select(lit, 1.0, 0.0)) * (1.0 / LIGHT_SAMPLES), 1.0
        ),
        "light_rays": _reduce(dr, dr.select(reach, 1.0, 0.0)),
    }
    if color:
        out["color"] = _colour(loaded, res, g, lit, weight, measure, (n, wl, w))
    return out


def _colour(loaded, res: dict, g, lit, weight, measure, geometry):
    """The area-lit colour of each camera sample: the shading model of
    :mod:`scenes.shading.phong` over its light samples, plus the radiance of emitter surfaces
    it sees. A diffuse model (no specular lobe) has one BRDF value per camera sample, so the
    colour is ``albedo / pi x radiance x`` the lit weighted sum (a third of the cost of
    shading every light sample)."""
    mi = backend.mitsuba()
    import drjit as dr

    light = loaded.light
    if loaded.pbr is not None:
        raise ValueError("area lights are not supported on glTF scenes")
    si, valid = res["si"], res["valid"]
    if loaded.specular.ks > 0.0:
        n, wl, w = geometry
        rgb = _reduce(
            dr,
            shade(
                albedo=g(res["albedo"]),
                normal=n,
                to_light=wl,
                to_eye=g(res["to_eye"]),
                irradiance_scale=w * (measure / (LIGHT_SAMPLES * light.proxy_area)),
                visibility=dr.select(lit, 1.0, 0.0),
                light=light,
                specular=loaded.specular,
            ),
        )
    else:
        lit_sum = _reduce(dr, dr.select(lit, weight * measure, 0.0))
        scale = lit_sum * (1.0 / (math.pi * LIGHT_SAMPLES))
        rgb = res["albedo"] * mi.Color3f(*light.radiance) * scale
    emitted = si.emitter(loaded.mi_scene).eval(si, valid)
    return dr.select(valid, rgb + emitted, 0.0)


class SoftGroup(SampledGroup):
    """Sums of the camera samples' ``soft_visibility`` and ``light_fraction`` and of their
    squares (a punctual light's are its visibility)."""

    name = "soft"

    def __init__(self, npix: int, *, output: bool = True):
        super().__init__(npix, output=output)
        for name in ("soft", "soft2", "frac", "frac2"):
            setattr(self, name, np.zeros(npix))

    def sample_values(self, res, chunk, block):
        import drjit as dr

        soft = res.get("soft", dr.select(res["lit"], 1.0, 0.0))
        frac = res.get("fraction", soft)
        add = dr.ReduceOp.Add
        return {
            "soft": (soft, add),
            "soft2": (soft * soft, add),
            "frac": (frac, add),
            "frac2": (frac * frac, add),
        }

    def add(self, host, at):
        for name in ("soft", "soft2", "frac", "frac2"):
            getattr(self, name)[at] += host[name]

    @staticmethod
    def channel_stderr(s, s2, n):
        """Standard error of a soft channel's mean (sample values in [0, 1]): the sample
        one; where every sample is 0 or every one is 1 (no variance to estimate), the
        binomial floor, as visibility's (a feature all samples missed is not excluded)."""
        se = sample_stderr(s, s2, n)
        alike = (s == 0.0) | (s == n)
        return np.where(alike, np.maximum(se, binomial_stderr_floor(n)), se)

    def finish(self, n, img):
        return {
            "soft_visibility": img(self.soft / n),
            "soft_visibility_stderr": img(self.channel_stderr(self.soft, self.soft2, n)),
            "light_fraction": img(self.frac / n),
            "light_fraction_stderr": img(self.channel_stderr(self.frac, self.frac2, n)),
        }

    def summary(self, channels):
        out = stderr_summary(channels, "soft_visibility_stderr")
        return {**out, **stderr_summary(channels, "light_fraction_stderr")}

    def stderr(self, n):
        """The larger standard error of the two channels."""
        return np.maximum(
            self.channel_stderr(self.soft, self.soft2, n),
            self.channel_stderr(self.frac, self.frac2, n),
        )

    def refine_stderr(self, n):
        # penumbra values are not binary: their sample standard error
        return self.stderr(n)

    def feature(self, n):
        # a penumbra: soft values other than all 0 or all 1
        return (self.soft > 0) & (self.soft < n), [self.soft > 0, self.soft < n]

    def variance(self, n):
        return [mean_variance(self.soft, self.soft2, n), mean_variance(self.frac, self.frac2, n)]
