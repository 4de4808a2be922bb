"""PCSS: one shadow map (as ``shadow-map``) filtered with percentage-closer soft shadows.

Blocker search over a light-size-scaled region, penumbra ``(z_r - z_b) L / z_b``, PCF over
it (:mod:`.pcss_filter`). Two published configurations (``preset``):

- ``nvidia``: Fernando 2005 as in NVIDIA's sample (Bavoil 2008): 16 blocker-search and 16
  PCF samples on the 16-point Poisson disk, no rotation, no minimum filter.
- ``hdrp``: Unity HDRP 10.10.1's PCSS: Fibonacci spiral disk (``HDPCSS.hlsl`` 21-94), 24
  blocker-search and 16 filter samples (the light's defaults ``m_BlockerSampleCount = 24``
  and ``m_FilterSampleCount = 16``, ``HDAdditionalLightData.cs`` lines 1134 and 1152), the
  disk rotated per pixel by interleaved gradient noise (``HDShadowSampling.hlsl`` 297-298,
  frame 0), and on spot/point (perspective) maps HDRP's softness mapping
  (:mod:`.pcss_hdrp`): the shape radius through the quartic fitted at 512^2
  (``HDAdditionalLightData.cs`` 2347-2354), the blocker search over ``min(softness, 0.04 R /
  512)``, the blocker-distance fit (``HDShadowSampling.hlsl`` 316-327), the penumbra as the
  ratio of reversed-Z device depths (``HDPCSS.hlsl`` 96-99) and the minimum filter size
  ``m_MinFilterSize * 0.001`` = 1e-4 of the 4096 fit, i.e. ``0.4096 / R`` in map coordinates
  (lines 1170 and 2376; ``HDShadowSampling.hlsl`` 303, 333-334). Directional (orthographic)
  maps keep the angular-diameter model of ``nvidia``. Sources: the published package mirror
  needle-mirror/com.unity.render-pipelines.high-definition, tag 10.10.1 = commit
  6328cc84c83b4143a5939859d76f9ccdc7a5b08f.

The light's size: ``light_size`` (world units, perspective maps) or, when 0, the scene's
area light (its diameter: the larger side of a rectangle, a disk's or sphere's diameter),
else NVIDIA's ``LIGHT_WORLD_SIZE`` 0.5 (``nvidia``) or HDRP's default shape radius 0.025
(``hdrp``: a size of 0.05); ``hdrp`` takes half the size as HDRP's shape radius.
``nvidia`` reads ``LIGHT_WORLD_SIZE`` as the light's full width and uses it as the filter
disk's radius (see docs/models.md for the measured transition factors). Directional lights
use ``light_angle`` (degrees, HDRP's default angular diameter 0.5, HDRP 10.10.1
HDAdditionalLightData.cs line 716).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

from .. import params as _params
from ..gbuffer import trace_gbuffer
from ..params import param
from .engine import execute
from .pcss_filter import DISKS
from .pcss_hdrp import DEFAULT_SHAPE_RADIUS, min_filter_uv
from .shadow_map import LIGHTS, ShadowMapParams, build

__all__ = [
    "LIGHTS",
    "NAME",
    "PRESETS",
    "SOFT_OUTPUTS",
    "PcssParams",
    "light_size_of",
    "resolved",
    "run",
]

NAME = "pcss"

#: NVIDIA's sample: ``#define LIGHT_WORLD_SIZE .5`` (Bavoil 2008).
NVIDIA_LIGHT_WORLD_SIZE = 0.5

#: Per preset: blocker samples, filter samples, disk, minimum filter radius (map
#: coordinates; ``None``: HDRP's, which depends on the map's resolution), per-pixel rotation,
#: softness mapping (``physical``: the light's size through similar triangles; ``hdrp``:
#: HDRP 10.10.1's fitted mapping, :mod:`.pcss_hdrp`), light size without an area light.
PRESETS = {
    "nvidia": (16, 16, "poisson16", 0.0, "none", "physical", NVIDIA_LIGHT_WORLD_SIZE),
    "hdrp": (24, 16, "fibonacci", None, "ign", "hdrp", 2.0 * DEFAULT_SHAPE_RADIUS),
}

#: Softness mappings (``softness``).
SOFTNESS = ("physical", "hdrp")

#: Outputs scored against the area-light truth (the ``soft`` family's channels), each the
#: ``visibility`` image.
SOFT_OUTPUTS = ("soft_visibility", "light_fraction")


@dataclass(frozen=True)
class PcssParams(ShadowMapParams):
    """Parameters of ``pcss`` (map placement, bias and format as ``shadow-map``)."""

    filter: str = param(
        "pcss",
        source="this technique's filter",
        help="pcss (blocker search, penumbra estimate, PCF over it)",
        choices=("pcss",),
    )
    preset: str = param(
        "nvidia",
        source="Fernando 2005 / NVIDIA PCSS sample (Bavoil 2008); Unity HDRP HDPCSS.hlsl",
        help="published configuration: nvidia (16/16 Poisson) or hdrp (24/16 Fibonacci "
        "spiral, rotated per pixel, minimum radius 1e-4)",
        choices=tuple(PRESETS),
    )
    blocker_samples: int = param(
        0,
        source="NVIDIA BLOCKER_SEARCH_NUM_SAMPLES 16; HDRP 10.10.1 m_BlockerSampleCount 24 "
        "(HDAdditionalLightData.cs:1134)",
        help="blocker-search taps (0 = the preset's)",
        lo=0,
        hi=64,
    )
    filter_samples: int = param(
        0,
        source="NVIDIA PCF_NUM_SAMPLES 16; HDRP 10.10.1 m_FilterSampleCount 16 "
        "(HDAdditionalLightData.cs:1152)",
        help="PCF taps over the penumbra disk (0 = the preset's)",
        lo=0,
        hi=64,
    )
    disk: str = param(
        "preset",
        source="NVIDIA poissonDisk[16]; HDRP 10.10.1 fibonacciSpiralDirection[64] "
        "(HDPCSS.hlsl:21-87)",
        help="tap pattern: preset, poisson16 or fibonacci",
        choices=("preset", *DISKS),
    )
    rotation: str = param(
        "preset",
        source="NVIDIA: none; HDRP 10.10.1: InterleavedGradientNoise(posSS, frame) * 2 pi "
        "(HDShadowSampling.hlsl:297)",
        help="per-pixel disk rotation: preset, none or ign (interleaved gradient noise)",
        choices=("preset", "none", "ign"),
    )
    softness: str = param(
        "preset",
        source="NVIDIA: the light size (Fernando 2005); HDRP 10.10.1: the fitted mapping "
        "(HDAdditionalLightData.cs:2347-2354, HDShadowSampling.hlsl:303-334)",
        help="softness mapping: preset, physical (light size, similar triangles) or hdrp "
        "(HDRP's fitted shape-radius and blocker-distance curves; perspective maps)",
        choices=("preset", *SOFTNESS),
    )
    min_filter_uv: float = param(
        -1.0,
        source="HDRP 10.10.1 m_MinFilterSize 0.1 x 0.001 of the 4096 fit "
        "(HDAdditionalLightData.cs:1170, 2376; HDShadowSampling.hlsl:303, 333: 0.4096 / "
        "resolution in map coordinates); NVIDIA none",
        help="smallest PCF radius in map coordinates where a blocker was found (-1 = the preset's)",
        lo=-1.0,
        hi=1.0,
    )
    light_size: float = param(
        0.0,
        source="the scene's area light; without one NVIDIA LIGHT_WORLD_SIZE 0.5, HDRP "
        "10.10.1 m_ShapeRadius 0.025 (HDAdditionalLightData.cs:443)",
        help="light size (full width) in world units for spot/point maps (0 = the scene's "
        "area light, else the preset's: nvidia 0.5, hdrp 0.05 = shape radius 0.025)",
        lo=0.0,
        hi=1e6,
    )
    light_range: float = param(
        0.0,
        source="HDRP 10.10.1: the shadow's far plane is the light's range "
        "(HDAdditionalLightData.cs:2270-2272 f = legacyLight.range)",
        help="hdrp softness: the light's range in world units, the far plane of its "
        "device-depth penumbra ratio (0 = the map's far plane)",
        lo=0.0,
        hi=1e9,
    )
    light_angle: float = param(
        0.5,
        source="Unity HDRP 10.10.1 m_AngularDiameter 0.5 degrees (HDAdditionalLightData.cs:716)",
        help="angular diameter of a directional light in degrees",
        lo=0.0,
        hi=90.0,
    )
    radius_scale: float = param(
        1.0,
        source="the presets' own radii (1)",
        help="scale of the search and filter disk radii (nvidia at 0.5: the disk's radius is "
        "half the parallel-plane width)",
        lo=0.0,
        hi=10.0,
    )


def light_size_of(light) -> float | None:
    """The size of a scene's area light (``None`` for a punctual light): the larger of its
    full width and height (a disk's or sphere's diameter; :attr:`scenes.Light.extent`)."""
    if not getattr(light, "is_area", False):
        return None
    size = max(float(x) for x in light.extent)
    return size if size > 0 else None


def resolved(p: PcssParams, light) -> PcssParams:
    """``p`` with the preset's values in place of its ``0`` / ``preset`` / ``-1`` fields and
    the light size taken from the scene where it is 0."""
    blockers, taps, disk, min_uv, rotation, softness, default_size = PRESETS[p.preset]
    size = p.light_size or light_size_of(light) or default_size
    if min_uv is None:
        min_uv = min_filter_uv(p.resolution)
    return dataclasses.replace(
        p,
        blocker_samples=p.blocker_samples or blockers,
        filter_samples=p.filter_samples or taps,
        disk=disk if p.disk == "preset" else p.disk,
        rotation=rotation if p.rotation == "preset" else p.rotation,
        softness=softness if p.softness == "preset" else p.softness,
        min_filter_uv=min_uv if p.min_filter_uv < 0 else p.min_filter_uv,
        light_size=size,
    )


def run(scene, params: PcssParams | None = None, **kwargs):
    """Run ``pcss`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, PcssParams, kwargs)
    used = resolved(p, scene.light)
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, used)
    setup.diagnostics["pcss"] = {
        k: getattr(used, k)
        for k in (
            "blocker_samples",
            "filter_samples",
            "disk",
            "rotation",
            "softness",
            "min_filter_uv",
        )
    } | {
        "light_size": used.light_size,
        "light_angle": used.light_angle,
        "light_range": used.light_range,
    }
    if used.softness == "hdrp" and getattr(scene.light, "is_directional", False):
        # HDRP's directional softness is not transcribed: the sun keeps the angular model
        setup.diagnostics["pcss"]["softness_applied"] = "physical (directional light)"
    res = execute(NAME, scene, gbuf, setup, used, _params.as_dict(p), t0)
    # the soft family's channels: PCSS's one estimate is both the irradiance-weighted shadow
    # factor an engine multiplies and the unoccluded area fraction it approximates
    for channel in SOFT_OUTPUTS:
        res.outputs[channel] = res.outputs["visibility"]
    return res
