"""The one shading model every part of raster-oracle uses.

For a surface point ``x`` with albedo ``rho`` (the BSDF's diffuse reflectance, linear RGB),
unit normal ``n`` turned to face the viewer (surfaces are two-sided), unit direction to the
light ``l``, unit direction to the eye ``v`` and light visibility ``V`` in [0, 1]:

.. math::

    L_o = \\Big(\\frac{\\rho}{\\pi} + k_s \\frac{s + 8}{8 \\pi} \\max(0, n \\cdot h)^s\\Big)
          \\; E \\; \\max(0, n \\cdot l) \\; V,
    \\qquad h = \\frac{l + v}{\\lVert l + v \\rVert}

with ``E`` the light's irradiance on a surface facing it (``color`` for a directional light,
``color * falloff / d^2`` for point and spot lights; see :mod:`scenes.lights`). The specular
lobe is normalized Blinn-Phong (Akenine-Moller et al., *Real-Time Rendering*, 4th ed., eq.
9.59 approximation), off by default (``k_s = 0``); with ``k_s = 0`` the model is exactly
Mitsuba's ``diffuse`` BSDF lit by a delta light, which is what the oracle's cross-check with
Mitsuba's ``direct`` integrator relies on.

A sample "sees the light" when its shadow ray is unoccluded, ``n . l > 0`` and, for a spot
light, it lies inside the cutoff cone. Sky samples have zero radiance and count as lit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import _ops
from ..lights import Light

__all__ = ["Specular", "facing", "receiver_mask", "shade"]


@dataclass(frozen=True)
class Specular:
    """Optional normalized Blinn-Phong lobe: weight ``ks`` (scalar) and exponent ``shininess``."""

    ks: float = 0.0
    shininess: float = 32.0

    def to_json(self) -> dict:
        return {"ks": self.ks, "shininess": self.shininess, "model": "normalized Blinn-Phong"}


def facing(normal, to_eye):
    """``normal`` flipped where needed so that it faces the viewer (two-sided surfaces)."""
    d = _ops.dot(normal, to_eye)
    if _ops.is_np(d):
        import numpy as np

        return np.where(d[..., None] < 0.0, -normal, normal)
    import drjit as dr

    return dr.select(d < 0.0, -normal, normal)


def receiver_mask(*, valid, cos_l, to_light, light: Light):
    """Where a surface point receives the light (the pixels shadows are scored on).

    A receiver is a valid surface point (not sky) whose facing normal has ``n . l > 0`` and
    that lies inside a spot light's cutoff cone (other lights reach everywhere).

    Parameters
    ----------
    valid : (N,) or (H, W) bool array, or Dr.Jit Bool: the point hit geometry.
    cos_l : ``n . l`` with ``n`` facing the viewer, same shape (or Dr.Jit Float).
    to_light : unit directions towards the light, (N, 3) float64 array or Vector3f.
    light : the light.

    Returns
    -------
    bool array of the shape of ``valid`` (or Dr.Jit Bool)
    """
    cone = light.in_cone(to_light)
    if _ops.is_np(cos_l):
        import numpy as np

        cone = np.asarray(cone).reshape(np.shape(valid))
    return valid & (cos_l > 0.0) & cone


def shade(
    *,
    albedo,
    normal,
    to_light,
    to_eye,
    irradiance_scale,
    visibility,
    light: Light,
    specular: Specular | None = None,
):
    """Outgoing radiance (linear RGB) of the shading model above.

    Parameters
    ----------
    albedo : (N, 3) array or Dr.Jit Color3f, linear diffuse reflectance.
    normal : unit normals facing the viewer, (N, 3) or Vector3f.
    to_light, to_eye : unit directions, (N, 3) or Vector3f.
    irradiance_scale : (N,) factor from :meth:`Light.irradiance_scale`.
    visibility : (N,) light visibility in [0, 1].

    Returns
    -------
    (N, 3) array (NumPy input) or Color3f (Dr.Jit input).
    """
    cos_l = _ops.maximum(_ops.dot(normal, to_light), 0.0)
    weight = irradiance_scale * cos_l * visibility
    brdf = albedo * (1.0 / math.pi)
    if specular is not None and specular.ks > 0.0:
        h = _ops.normalize(to_light + to_eye)
        cos_h = _ops.maximum(_ops.dot(normal, h), 0.0)
        norm = specular.ks * (specular.shininess + 8.0) / (8.0 * math.pi)
        lobe = norm * _ops.power(cos_h, specular.shininess)
        brdf = brdf + (lobe[..., None] if _ops.is_np(lobe) else lobe)
    e = light.color
    if _ops.is_np(weight):
        import numpy as np

        return brdf * np.asarray(e)[None, :] * weight[:, None]
    import mitsuba as mi

    return brdf * mi.Color3f(*e) * weight
