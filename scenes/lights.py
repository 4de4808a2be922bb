"""Lights: punctual (directional, point, spot) and area (rectangle, disk, sphere), as read
from a Mitsuba scene.

Radiometry follows Mitsuba's emitters so that the shading model agrees with Mitsuba's own
``direct`` integrator:

- ``directional``: irradiance ``E`` (RGB, W/m^2) on a surface facing the light; rays towards
  the light are unbounded.
- ``point``: intensity ``I`` (RGB, W/sr); irradiance ``I / d^2``.
- ``spot``: intensity ``I`` times Mitsuba's falloff: 1 inside ``beam_width``, falling
  linearly in angle to 0 at ``cutoff_angle``, 0 outside; irradiance ``I * falloff / d^2``.

A light read from a glTF file (``model="gltf"``) follows KHR_lights_punctual instead:
directional ``E`` in lux, point and spot ``I`` in candela (taken as the renderer's linear
units, as the Khronos sample renderer does), the spot's smooth cone attenuation
``saturate(cos_theta * s + o)^2`` with ``s = 1 / max(0.001, cos(inner) - cos(outer))`` and
``o = -cos(outer) s`` (``beam_width`` = inner, ``cutoff_angle`` = outer cone angle), and, where
``range > 0``, the window the extension recommends: ``clamp(1 - (d / range)^4, 0, 1) / d^2``.

**Area lights** (a Mitsuba ``area`` emitter on a ``rectangle``, ``disk`` or ``sphere`` shape)
have ``area`` set to the shape's name; the emitter's ``radiance`` is uniform over the surface
(rectangle and disk: one-sided, emitting on the side of ``direction``; sphere: outwards). The
interface the models read:

- ``area``: ``"rectangle"``, ``"disk"`` or ``"sphere"`` (``""``: a punctual light);
- ``position``: the centre; ``direction``: the unit normal of the emitting side (rectangle,
  disk; ``(0, -1, 0)`` for a sphere, which has none);
- ``axes``: the two world-space half-extent vectors ``(u, v)`` spanning the rectangle
  (``centre + s u + t v``, ``s, t in [-1, 1]``; ``|u|``, ``|v|`` are the half width and half
  height, ``u x v`` is along ``direction``), or a disk's two radius vectors; :attr:`frame`
  gives the unit ``(tangent, bitangent, normal)``, :attr:`extent` the full ``(width,
  height)`` (a disk's or sphere's diameter twice);
- ``radius``: disk and sphere radius (0 for a rectangle);
- ``radiance``: RGB emitted radiance (W/m^2/sr);
- :attr:`surface_area` (the emitting area: ``4 |u| |v|``, ``pi r^2``, ``4 pi r^2``) and
  :meth:`area_point` (points on a rectangle or disk from unit-square samples).

For everything that treats lights as punctual (the hard ``visibility`` channel, the shading
of the shadow-map models, light paths' kinds) an area light is its **punctual proxy**: a
``point`` light at its centre (``kind == "point"``) whose intensity ``color`` is the area
light's on-axis far-field intensity, ``radiance x area`` (rectangle: ``radiance * 4 |u|
|v|``, disk ``radiance * pi r^2``; sphere ``radiance * pi r^2``, isotropic). A shadow ray to
a sphere light's centre stops at its surface (:attr:`shadow_end`). The reference's soft
channels (``soft_visibility``, ``light_fraction``) and its shaded colour integrate over the
true surface instead (:mod:`oracle.reference.soft`).

Every function works on NumPy ``(N, 3)`` arrays and on Dr.Jit ``Vector3f`` alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import _ops

__all__ = ["AREA_SHAPES", "Light"]

#: Shapes an area light can have (the Mitsuba shape of its ``area`` emitter).
AREA_SHAPES = ("rectangle", "disk", "sphere")


@dataclass(frozen=True)
class Light:
    """One punctual light.

    Attributes
    ----------
    kind : ``"directional"``, ``"point"`` or ``"spot"``.
    color : RGB irradiance (directional) or intensity (point, spot), linear.
    direction : unit vector the light travels along (directional, spot axis).
    position : world position (point, spot).
    cutoff_angle, beam_width : spot cone half-angles in degrees (Mitsuba's parameters; the
        outer and inner cone angles of a glTF spot).
    model : ``"mitsuba"`` (Mitsuba's emitters) or ``"gltf"`` (KHR_lights_punctual).
    range : glTF point/spot range (0: unbounded).
    area : ``""`` (punctual) or the area light's shape (:data:`AREA_SHAPES`); see the
        module docstring for the area fields ``axes``, ``radius`` and ``radiance``.
    """

    kind: str
    color: tuple[float, float, float]
    direction: tuple[float, float, float] = (0.0, -1.0, 0.0)
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cutoff_angle: float = 20.0
    beam_width: float = 15.0
    name: str = ""
    extra: dict = field(default_factory=dict, compare=False)
    model: str = "mitsuba"
    range: float = 0.0
    area: str = ""
    axes: tuple = ()
    radius: float = 0.0
    radiance: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def is_directional(self) -> bool:
        return self.kind == "directional"

    @property
    def is_area(self) -> bool:
        """True for an area light (rectangle, disk or sphere)."""
        return bool(self.area)

    @property
    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit ``(tangent, bitangent, normal)`` of a rectangle or disk light (tangent along
        ``axes[0]``, normal = ``direction``, the emitting side); world axes for a sphere."""
        if self.area in ("rectangle", "disk"):
            n = np.asarray(self.direction, dtype=np.float64)
            t = np.asarray(self.axes[0], dtype=np.float64)
            t = t / np.linalg.norm(t)
            return t, np.cross(n, t), n
        return np.eye(3)[0], np.eye(3)[2], np.asarray(self.direction, dtype=np.float64)

    @property
    def half_size(self) -> tuple[float, float]:
        """Half width and half height (along ``frame``'s tangent and bitangent); a disk's or
        sphere's radius twice; ``(0, 0)`` for a punctual light."""
        if self.area == "rectangle":
            return tuple(float(np.linalg.norm(a)) for a in self.axes)
        return (float(self.radius), float(self.radius))

    @property
    def extent(self) -> tuple[float, float]:
        """Full ``(width, height)`` of the light (diameter twice for a disk or sphere)."""
        a, b = self.half_size
        return (2.0 * a, 2.0 * b)

    @property
    def surface_area(self) -> float:
        """The emitting area (0 for a punctual light)."""
        a, b = self.half_size
        if self.area == "rectangle":
            return 4.0 * a * b
        if self.area == "disk":
            return math.pi * a * a
        if self.area == "sphere":
            return 4.0 * math.pi * a * a
        return 0.0

    @property
    def proxy_area(self) -> float:
        """The area that turns ``radiance`` into the proxy's intensity ``color``: the surface
        area of a rectangle or disk, a sphere's cross-section ``pi r^2`` (0: punctual)."""
        if self.area == "sphere":
            return math.pi * float(self.radius) ** 2
        return self.surface_area

    @property
    def shadow_end(self) -> float:
        """How far short of ``position`` a shadow ray to the light stops: a sphere light's
        radius (its centre is inside it), else 0."""
        return float(self.radius) if self.area == "sphere" else 0.0

    def area_point(self, u, v):
        """Points on a rectangle or disk light from unit-square samples ``u, v`` (NumPy
        arrays or Dr.Jit ``Float``): uniform in area (the disk through Shirley and Chiu's
        concentric map). Returns ``(N, 3)`` NumPy or a Dr.Jit ``Point3f``."""
        if self.area not in ("rectangle", "disk"):
            raise ValueError(f"area_point needs a rectangle or disk light, not {self.area!r}")
        s, t = u * 2.0 - 1.0, v * 2.0 - 1.0
        if self.area == "disk":
            s, t = _concentric(s, t)
        c = np.asarray(self.position, dtype=np.float64)
        a0 = np.asarray(self.axes[0], dtype=np.float64)
        a1 = np.asarray(self.axes[1], dtype=np.float64)
        if _ops.is_np(s):
            return c + s[..., None] * a0 + t[..., None] * a1
        import mitsuba as mi

        return mi.Point3f(*(float(c[i]) + s * float(a0[i]) + t * float(a1[i]) for i in range(3)))

    def to_light(self, points):
        """Unit direction from each point towards the light and the distance to it.

        Returns ``(wl, dist)``; ``dist`` is ``inf`` for a directional light.
        """
        if self.is_directional:
            d = np.asarray(self.direction, dtype=np.float64)
            wl = _ops.const_vec(points, -d)
            return wl, _ops.full_like_x(points, math.inf)
        delta = _ops.sub_const(points, np.asarray(self.position, dtype=np.float64))
        dist = _ops.norm(delta)
        return _ops.scale(delta, -1.0 / dist), dist

    def falloff(self, wl):
        """Spot falloff for unit directions ``wl`` towards the light (1 for other kinds)."""
        if self.kind != "spot":
            return _ops.full_like_x(wl, 1.0)
        axis = np.asarray(self.direction, dtype=np.float64)
        cos_theta = -_ops.dot_const(wl, axis)
        if self.model == "gltf":
            cos_outer = math.cos(math.radians(self.cutoff_angle))
            cos_inner = math.cos(math.radians(self.beam_width))
            s = 1.0 / max(0.001, cos_inner - cos_outer)
            att = _ops.clip(cos_theta * s - cos_outer * s, 0.0, 1.0)
            return att * att
        theta = _ops.arccos(_ops.clip(cos_theta, -1.0, 1.0))
        cutoff = math.radians(self.cutoff_angle)
        beam = math.radians(min(self.beam_width, self.cutoff_angle))
        width = max(cutoff - beam, 1e-12)
        ramp = _ops.clip((cutoff - theta) / width, 0.0, 1.0)
        return _ops.where(cos_theta > math.cos(cutoff), ramp, 0.0)

    def in_cone(self, wl):
        """True where a spot light reaches (inside the cutoff cone); True for others."""
        if self.kind != "spot":
            return _ops.full_like_x(wl, 1.0) > 0.0
        axis = np.asarray(self.direction, dtype=np.float64)
        return -_ops.dot_const(wl, axis) > math.cos(math.radians(self.cutoff_angle))

    def irradiance_scale(self, wl, dist):
        """Scalar factor multiplying ``color`` to give irradiance on a facing surface."""
        if self.is_directional:
            return _ops.full_like_x(wl, 1.0)
        if self.model == "gltf" and self.range > 0.0:
            q = dist * (1.0 / self.range)
            window = _ops.clip(1.0 - (q * q) * (q * q), 0.0, 1.0)
            return self.falloff(wl) * window / (dist * dist)
        return self.falloff(wl) / (dist * dist)

    def area_json(self) -> dict:
        """The area record of ``lights.json`` (see :meth:`to_json`)."""
        t, b, n = self.frame
        out = {
            "shape": self.area,
            "centre": list(self.position),
            "radiance": list(self.radiance),
            "units": "radiance W/m^2/sr",
            "surface_area": self.surface_area,
        }
        if self.area in ("rectangle", "disk"):
            out["normal"] = list(self.direction)
            out["tangent"] = [float(c) for c in t]
            out["bitangent"] = [float(c) for c in b]
            out["emits"] = "one-sided, towards +normal"
        else:
            out["emits"] = "outwards, uniform"
        if self.area == "rectangle":
            out["half_axes"] = [[float(c) for c in a] for a in self.axes]
            out["size"] = list(self.extent)
        else:
            out["radius"] = self.radius
        out["proxy"] = (
            "kind/position/color: a point light at the centre with the on-axis intensity "
            "radiance x area (sphere: radiance x pi r^2)"
        )
        return out

    def to_json(self) -> dict:
        out = {"kind": self.kind, "name": self.name, "color": list(self.color)}
        if self.kind in ("directional", "spot"):
            out["direction"] = list(self.direction)
        if self.kind in ("point", "spot"):
            out["position"] = list(self.position)
        if self.kind == "spot":
            out["cutoff_angle_deg"] = self.cutoff_angle
            out["beam_width_deg"] = self.beam_width
            out["falloff"] = "1 inside beam_width, linear in angle to 0 at cutoff_angle"
        out["units"] = "irradiance W/m^2" if self.is_directional else "intensity W/sr"
        if self.model == "gltf":
            out["model"] = "KHR_lights_punctual"
            out["units"] = "illuminance lux" if self.is_directional else "intensity candela"
            if self.kind == "spot":
                out["inner_cone_angle_deg"] = self.beam_width
                out["outer_cone_angle_deg"] = self.cutoff_angle
                out["falloff"] = (
                    "saturate(cos_theta * s - cos(outer) * s)^2, "
                    "s = 1 / max(0.001, cos(inner) - cos(outer))"
                )
            if not self.is_directional:
                out["range"] = self.range or None
                out["distance_falloff"] = (
                    "clamp(1 - (d / range)^4, 0, 1) / d^2" if self.range else "1 / d^2"
                )
        if self.is_area:
            out["area"] = self.area_json()
        return out


def _concentric(s, t):
    """Shirley and Chiu's concentric map of ``[-1, 1]^2`` onto the unit disk (uniform in
    area, NumPy or Dr.Jit)."""
    if _ops.is_np(s):
        s, t = np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64)
        first = np.abs(s) > np.abs(t)
        r = np.where(first, s, t)
        safe_s = np.where(s == 0.0, 1.0, s)
        safe_t = np.where(t == 0.0, 1.0, t)
        phi = np.where(first, (math.pi / 4) * t / safe_s, math.pi / 2 - (math.pi / 4) * s / safe_t)
        phi = np.where((s == 0.0) & (t == 0.0), 0.0, phi)
        return r * np.cos(phi), r * np.sin(phi)
    import drjit as dr

    first = dr.abs(s) > dr.abs(t)
    r = dr.select(first, s, t)
    safe_s = dr.select(s == 0.0, 1.0, s)
    safe_t = dr.select(t == 0.0, 1.0, t)
    phi = dr.select(first, (math.pi / 4) * t / safe_s, math.pi / 2 - (math.pi / 4) * s / safe_t)
    phi = dr.select((s == 0.0) & (t == 0.0), 0.0, phi)
    return r * dr.cos(phi), r * dr.sin(phi)
