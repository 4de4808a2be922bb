"""PCSS: one shadow map (as ``shadow-map``) filtered with percentage-closer soft shadows.

Blocker search over a light-size-scaled region, penumbra ``(z_r - z_b) L / z_b``, PCF over
it (:mod:`.pcss_filter`). Two published configurations (``preset``):

- ``nvidia``: Fernando 2005 as in NVIDIA's sample (Bavoil 2008): 16 blocker-search and 16
  PCF samples on the 16-point Poisson disk, no rotation, no minimum filter.
- ``hdrp``: Unity HDRP 10.10.1's PCSS: Fibonacci spiral disk (``HDPCSS.hlsl`` 21-94), 24
  blocker-search and 16 filter samples (the light's defaults ``m_BlockerSampleCount = 24``
  and ``m_FilterSampleCount = 16``, ``HDAdditionalLightData.cs`` lines 1134 and 1152), a
  minimum filter radius of ``m_MinFilterSize * 0.001`` = 1e-4 in map coordinates (lines 1170
  and 2376), and the disk rotated per pixel by interleaved gradient noise
  (``HDShadowSampling.hlsl`` 297-298, frame 0). HDRP maps a light's shape radius to its
  "softness" through a quartic fitted at 512^2 (``HDAdditionalLightData.cs`` 2349) and
  scales it by a fitted curve of the blocker distance (``HDShadowSampling.hlsl`` 316-327);
  the model uses the physical light size for both presets instead, so that they differ only
  in their sampling. Sources: the published package mirror needle-mirror/
  com.unity.render-pipelines.high-definition at 6328cc84.

The light's size: ``light_size`` (world units, perspective maps) or, when 0, the scene's
area light (its diameter: the larger side of a rectangle, a disk's or sphere's diameter),
else NVIDIA's ``LIGHT_WORLD_SIZE`` 0.5; directional lights use ``light_angle`` (degrees,
HDRP's default angular diameter 0.5, HDRP 10.10.1 HDAdditionalLightData.cs line 716).
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

#: Per preset: blocker samples, filter samples, disk, minimum filter radius (map
#: coordinates), per-pixel rotation.
PRESETS = {
    "nvidia": (16, 16, "poisson16", 0.0, "none"),
    "hdrp": (24, 16, "fibonacci", 1e-4, "ign"),
}

#: Outputs scored against the area-light truth (the ``soft`` family's channels), each the
#: ``visibility`` image.
SOFT_OUTPUTS = ("soft_visibility", "light_fraction")

#: NVIDIA's sample: ``#define LIGHT_WORLD_SIZE .5`` (Bavoil 2008).
NVIDIA_LIGHT_WORLD_SIZE = 0.5


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
    min_filter_uv: float = param(
        -1.0,
        source="HDRP 10.10.1 m_MinFilterSize 0.1 x 0.001 (HDAdditionalLightData.cs:1170, "
        "2376; map coordinates); NVIDIA none",
        help="smallest PCF radius in map coordinates where a blocker was found (-1 = the preset's)",
        lo=-1.0,
        hi=1.0,
    )
    light_size: float = param(
        0.0,
        source="the scene's area light; NVIDIA LIGHT_WORLD_SIZE 0.5 without one",
        help="light size in world units for spot/point maps (0 = the scene's area light, else 0.5)",
        lo=0.0,
        hi=1e6,
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
        source="NVIDIA/HDRP use the light size as the disk radius (1); 0.5 = geometric",
        help="scale of the search and filter disk radii (0.5 makes the filtered transition "
        "as wide as the geometric penumbra)",
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
    blockers, taps, disk, min_uv, rotation = PRESETS[p.preset]
    size = p.light_size or light_size_of(light) or NVIDIA_LIGHT_WORLD_SIZE
    return dataclasses.replace(
        p,
        blocker_samples=p.blocker_samples or blockers,
        filter_samples=p.filter_samples or taps,
        disk=disk if p.disk == "preset" else p.disk,
        rotation=rotation if p.rotation == "preset" else p.rotation,
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
        for k in ("blocker_samples", "filter_samples", "disk", "rotation", "min_filter_uv")
    } | {"light_size": used.light_size, "light_angle": used.light_angle}
    res = execute(NAME, scene, gbuf, setup, used, _params.as_dict(p), t0)
    # the soft family's channels: PCSS's one estimate is both the irradiance-weighted shadow
    # factor an engine multiplies and the unoccluded area fraction it approximates
    for channel in SOFT_OUTPUTS:
        res.outputs[channel] = res.outputs["visibility"]
    return res
