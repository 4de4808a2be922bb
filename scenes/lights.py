"""Punctual lights: directional, point and spot, as read from a Mitsuba scene.

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

Every function works on NumPy ``(N, 3)`` arrays and on Dr.Jit ``Vector3f`` alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import _ops

__all__ = ["Light"]


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

    @property
    def is_directional(self) -> bool:
        return self.kind == "directional"

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
        return out
