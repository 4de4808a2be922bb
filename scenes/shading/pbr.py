"""The glTF 2.0 metallic-roughness BRDF (the specification's Appendix B) under punctual lights.

For a surface point with base colour ``c`` (linear RGB), metallic ``m``, perceptual roughness
``r``, unit shading normal ``n`` (facing the viewer), unit directions ``l`` to the light and
``v`` to the eye, ``h = normalize(l + v)``:

.. math::

    \\alpha &= r^2, \\qquad
    D = \\frac{\\alpha^2 \\chi^+(n \\cdot h)}{\\pi \\big((n \\cdot h)^2 (\\alpha^2 - 1) + 1\\big)^2}

    V &= \\frac{1}{\\big(|n \\cdot l| + \\sqrt{\\alpha^2 + (1 - \\alpha^2)(n \\cdot l)^2}\\big)
          \\big(|n \\cdot v| + \\sqrt{\\alpha^2 + (1 - \\alpha^2)(n \\cdot v)^2}\\big)}

    F_\\text{d} &= 0.04 + 0.96 (1 - |v \\cdot h|)^5, \\qquad
    F_\\text{m} = c + (1 - c)(1 - |v \\cdot h|)^5

    f &= (1 - m) \\big((1 - F_\\text{d}) \\tfrac{c}{\\pi} + F_\\text{d} V D\\big)
         + m \\, F_\\text{m} V D

(``specular_brdf = V D`` with the height-correlated Smith ``V`` already divided by
``4 |n.l| |n.v|``; the dielectric is ``fresnel_mix(ior 1.5)`` of Lambert and the specular
lobe, the metal ``conductor_fresnel(c)``; B.3.2-B.3.6 of the specification, the normative
``mix`` form, not the non-normative ``c_diff``/``f0`` shortcut, which differs for
``0 < m < 1``). The outgoing radiance is

.. math::  L_o = f \\; E \\; \\max(0, n \\cdot l) \\; V_\\text{shadow} + L_e

with ``E`` the light's irradiance on a surface facing it (:meth:`scenes.lights.Light.
irradiance_scale` times its colour; for a glTF light the KHR_lights_punctual attenuation) and
``L_e`` the emissive radiance. ``D`` is taken as 0 for ``alpha = 0`` (a mirror: a delta lobe,
measure zero under a punctual light) so no NaN is ever produced.

Every function works on NumPy arrays (``(N, 3)`` vectors, ``(N,)`` scalars) and on Dr.Jit
``Vector3f``/``Float`` alike, as :mod:`scenes.shading.phong` does.

References
----------
The Khronos Group, *glTF 2.0 Specification*, Appendix B "BRDF Implementation" (2021),
https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html#appendix-b-brdf-implementation
"""

from __future__ import annotations

import math

import numpy as np

from .. import _ops
from ..lights import Light

__all__ = ["DIELECTRIC_F0", "SHADING_MODEL", "gltf_brdf", "shade_gltf"]

#: Name recorded in provenance for scenes shaded with this model.
SHADING_MODEL = "gltf-metallic-roughness (glTF 2.0 Appendix B, KHR_lights_punctual)"
#: Fresnel reflectance at normal incidence of the dielectric (ior 1.5): ((1.5 - 1)/(1.5 + 1))^2.
DIELECTRIC_F0 = 0.04
#: Smallest squared denominator of D (float32-safe): alpha = 0 gives D = 0, never 0/0.
_TINY = 1e-30


def _sqrt(a):
    if _ops.is_np(a):
        return np.sqrt(a)
    import drjit as dr

    return dr.sqrt(a)


def _abs(a):
    if _ops.is_np(a):
        return np.abs(a)
    import drjit as dr

    return dr.abs(a)


def _col(s, like):
    """A scalar field as a colour factor: ``(N, 1)`` for NumPy, as is for Dr.Jit."""
    if _ops.is_np(s):
        return np.asarray(s)[..., None]
    return s


def gltf_brdf(*, base_color, metallic, roughness, normal, to_light, to_eye):
    """The glTF metallic-roughness BRDF ``f(l, v)`` (1/sr, linear RGB); see the module text.

    Parameters
    ----------
    base_color : (N, 3) array or Dr.Jit Color3f, linear base colour.
    metallic, roughness : (N,) arrays or Dr.Jit Float in [0, 1] (roughness perceptual:
        ``alpha = roughness ** 2``).
    normal, to_light, to_eye : unit vectors, (N, 3) or Vector3f.
    """
    n_l = _abs(_ops.dot(normal, to_light))
    n_v = _abs(_ops.dot(normal, to_eye))
    h = _ops.normalize(to_light + to_eye)
    n_h = _ops.dot(normal, h)
    v_h = _abs(_ops.dot(to_eye, h))
    alpha = roughness * roughness
    a2 = alpha * alpha
    den = n_h * n_h * (a2 - 1.0) + 1.0
    d = _ops.where(n_h > 0.0, a2 / (math.pi * _ops.maximum(den * den, _TINY)), 0.0)
    vis = 1.0 / (
        (n_l + _sqrt(a2 + (1.0 - a2) * n_l * n_l)) * (n_v + _sqrt(a2 + (1.0 - a2) * n_v * n_v))
    )
    spec = _col(vis * d, base_color)
    w = 1.0 - v_h
    w5 = _col((w * w) * (w * w) * w, base_color)
    f_d = DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * w5
    dielectric = (1.0 - f_d) * (base_color * (1.0 / math.pi)) + f_d * spec
    metal = spec * (base_color + (1.0 - base_color) * w5)
    m = _col(metallic, base_color)
    return (1.0 - m) * dielectric + m * metal


def shade_gltf(
    *,
    base_color,
    metallic,
    roughness,
    emissive,
    normal,
    to_light,
    to_eye,
    irradiance_scale,
    visibility,
    light: Light,
):
    """Outgoing radiance (linear RGB) of the glTF BRDF under one punctual light, emissive added.

    Parameters
    ----------
    base_color, emissive : (N, 3) or Color3f, linear.
    metallic, roughness : (N,) or Float.
    normal : unit shading normals facing the viewer (normal texture applied).
    to_light, to_eye : unit directions.
    irradiance_scale : (N,) factor from :meth:`Light.irradiance_scale`.
    visibility : (N,) light visibility in [0, 1].

    Returns
    -------
    (N, 3) array (NumPy input) or Color3f (Dr.Jit input).
    """
    cos_l = _ops.maximum(_ops.dot(normal, to_light), 0.0)
    weight = irradiance_scale * cos_l * visibility
    f = gltf_brdf(
        base_color=base_color,
        metallic=metallic,
        roughness=roughness,
        normal=normal,
        to_light=to_light,
        to_eye=to_eye,
    )
    if _ops.is_np(weight):
        return f * np.asarray(light.color)[None, :] * weight[:, None] + emissive
    import mitsuba as mi

    return f * mi.Color3f(*light.color) * weight + emissive
