"""Unity HDRP 10.10.1's PCSS softness mapping for spot and point (perspective) maps: how a
light's shape radius becomes the blocker-search and filter radii (``preset=hdrp``).

Transcribed from the published package of HDRP 10.10.1 (needle-mirror/com.unity.render-
pipelines.high-definition, tag ``10.10.1``, commit 6328cc84c83b4143a5939859d76f9ccdc7a5b08f),
per constant:

- ``HDAdditionalLightData.cs``:443 ``m_ShapeRadius = 0.025`` (the default shape radius);
  :2347-2350 the "softness" of a punctual light, a quartic in ``x = shapeRadius *
  softnessScale`` fitted "against raytracing reference ... with a resolution of 512"::

      softness = (0.02403461 + 3.452916 x - 1.362672 x^2 + 0.6700115 x^3 + 0.2159474 x^4) / 100

  :2354 ``softness *= viewportWidth / 512`` (``viewportWidth``: the map's side in texels);
  :1170 and :2376 ``minFilterSize = 0.1 * 0.001``; :2272 ``zBufferParam = ((f - n) / n, 1,
  (f - n) / (n f), 1 / f)`` (``n`` the shadow near plane, ``f`` the light's range: the
  reversed-Z form, ``LinearEyeDepth(d) = 1 / (zBufferParam.z d + zBufferParam.w)``).
- ``HDShadowSampling.hlsl`` ``SampleShadow_PCSS`` (:289-339): :303 ``atlasResFactor = 4096 /
  atlasSize`` (offsets in atlas coordinates; in the map's own coordinates a radius ``s`` of
  the shader is ``s * 4096 / R``); :307 ``maxSoftness = 0.04 R / 512``; :312 the blocker search
  over a disk of radius ``min(softness + 1e-6, maxSoftness)``; :316-328 for perspective maps
  with a blocker found, ``dist = LinearEyeDepth(averageBlockerDepth)`` clamped to 7.5 (:319),
  ``softness *= 3.298300241 - 2.001364639 d + 0.4967311427 d^2 - 0.05464058455 d^3 + 0.0021974
  d^4`` (:323, "fitted curve to match ray trace reference") and clamped again to
  ``maxSoftness`` (:327); :331 ``filterSize = softness * PenumbraSizePunctual(tcs.z,
  averageBlockerDepth)``; :333 ``max(filterSize, minFilterRadius)``.
- ``HDPCSS.hlsl``: :96-99 ``PenumbraSizePunctual(r, b) = abs((r - b) / b)`` on *device* depths;
  :106-130 ``BlockerSearch`` averages the device depths of the taps closer than the receiver.
- ``HDShadowAlgorithms.hlsl``:22 ``PUNCTUAL_FILTER_ALGORITHM`` passes ``shadowFilterParams0.x``
  (the softness), ``.w`` (the minimum filter size) and ``sd.zBufferParam`` to it.

Device depths are reversed Z (``UNITY_REVERSED_Z``: D3D11/12, Vulkan, Metal, consoles; the
``zBufferParam`` above is the reversed form): ``d = 1 - z`` with ``z`` this project's
normalized map depth (0 at the near plane), so the average device depth is one minus the
average stored depth, and ``PenumbraSizePunctual`` is ``f (t_r - t_b) / (t_r (f - t_b))`` in
linear depths ``t`` (the near plane cancels): it grows as the blocker nears the far plane
``f``, which HDRP sets at the light's range (``light_range``; by default the map's own far
plane, where this project's map ends). Distances are in scene units read as metres (the
fits' unit). Orthographic (directional) maps are not
transcribed here: ``pcss_filter`` keeps the angular-diameter model for them.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DEFAULT_SHAPE_RADIUS",
    "DIST_CLAMP",
    "DIST_FIT",
    "FIT_ATLAS",
    "MAX_SOFTNESS",
    "MIN_FILTER_SIZE",
    "SOFTNESS_BASE_RES",
    "SOFTNESS_FIT",
    "device_ratio",
    "distance_scale",
    "filter_radius_uv",
    "min_filter_uv",
    "search_radius_uv",
    "softness",
]

#: ``m_ShapeRadius`` default (HDAdditionalLightData.cs:443).
DEFAULT_SHAPE_RADIUS = 0.025
#: Quartic of the shape radius, coefficients of x^0..x^4, then / 100 (:2349-2350).
SOFTNESS_FIT = (0.02403461, 3.452916, -1.362672, 0.6700115, 0.2159474)
#: The fit's resolution (:2354; HDShadowSampling.hlsl:307).
SOFTNESS_BASE_RES = 512.0
#: The atlas size of the fit (HDShadowSampling.hlsl:303).
FIT_ATLAS = 4096.0
#: ``maxSoftness`` at 512 texels (HDShadowSampling.hlsl:307).
MAX_SOFTNESS = 0.04
#: The blocker search's ``+ 0.000001`` (HDShadowSampling.hlsl:312).
SEARCH_EPSILON = 1e-6
#: Blocker-distance fit, coefficients of d^0..d^4 (HDShadowSampling.hlsl:323), ``d`` clamped
#: to :data:`DIST_CLAMP` (:319).
DIST_FIT = (3.298300241, -2.001364639, 0.4967311427, -0.05464058455, 0.0021974)
DIST_CLAMP = 7.5
#: ``m_MinFilterSize * 0.001`` (HDAdditionalLightData.cs:1170, :2376).
MIN_FILTER_SIZE = 0.1 * 0.001


def _poly(coeffs, x):
    x = np.asarray(x, dtype=np.float64)
    return sum(c * x**k for k, c in enumerate(coeffs))


def softness(shape_radius: float, resolution: int) -> float:
    """``shadowSoftness`` of a punctual light: the fitted quartic of the shape radius / 100,
    times ``resolution / 512`` (HDAdditionalLightData.cs:2347-2354)."""
    return float(_poly(SOFTNESS_FIT, shape_radius)) / 100.0 * (resolution / SOFTNESS_BASE_RES)


def distance_scale(dist) -> np.ndarray:
    """The blocker-distance fit at ``min(dist, 7.5)`` (HDShadowSampling.hlsl:319-323)."""
    return _poly(DIST_FIT, np.minimum(np.asarray(dist, dtype=np.float64), DIST_CLAMP))


def _to_map_uv(size, resolution: int):
    """A shader size (atlas coordinates of the 4096 fit) in the map's own coordinates."""
    return np.asarray(size, dtype=np.float64) * (FIT_ATLAS / resolution)


def search_radius_uv(shape_radius: float, resolution: int) -> float:
    """Blocker-search radius in map coordinates (HDShadowSampling.hlsl:307, 312)."""
    cap = MAX_SOFTNESS * resolution / SOFTNESS_BASE_RES
    s = min(softness(shape_radius, resolution) + SEARCH_EPSILON, cap)
    return float(_to_map_uv(s, resolution))


def min_filter_uv(resolution: int) -> float:
    """The minimum filter radius in map coordinates (HDShadowSampling.hlsl:333-334)."""
    return float(_to_map_uv(MIN_FILTER_SIZE, resolution))


def device_ratio(t_receiver, t_blocker, far) -> np.ndarray:
    """``PenumbraSizePunctual`` (HDPCSS.hlsl:96-99) of linear light-view depths: ``|(d_r -
    d_b) / d_b|`` with the reversed-Z device depth ``d = n (f - t) / (t (f - n))`` of a map
    whose far plane is ``far`` (HDRP: the light's range; ``n`` cancels), i.e. ``f (t_r -
    t_b) / (t_r (f - t_b))``."""
    t_r = np.asarray(t_receiver, dtype=np.float64)
    t_b = np.asarray(t_blocker, dtype=np.float64)
    d_r, d_b = (far - t_r) / t_r, (far - t_b) / t_b
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(np.where(d_b != 0, (d_r - d_b) / d_b, np.inf))


def filter_radius_uv(shape_radius: float, resolution: int, t_receiver, t_blocker, far):
    """Filter radius in map coordinates (HDShadowSampling.hlsl:316-334) of receivers at
    linear light-view depth ``t_receiver`` whose mean blocker lies at ``t_blocker``
    (``LinearEyeDepth`` of the mean device depth, :318, the blocker's distance along the
    light's axis; ``pcss_filter.blocker_search`` with ``average="stored"``): the softness
    scaled by the blocker-distance fit and capped, times :func:`device_ratio` with far plane
    ``far``, at least the minimum filter size."""
    cap = MAX_SOFTNESS * resolution / SOFTNESS_BASE_RES
    soft = np.minimum(softness(shape_radius, resolution) * distance_scale(t_blocker), cap)
    size = np.maximum(soft * device_ratio(t_receiver, t_blocker, far), MIN_FILTER_SIZE)
    return _to_map_uv(size, resolution)
