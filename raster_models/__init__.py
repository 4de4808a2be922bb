"""raster-oracle's technique models: real-time shadow, soft-shadow, anti-aliasing and temporal
anti-aliasing techniques reproduced in NumPy and Dr.Jit, one folder or file per technique,
each registered in :mod:`.registry` (``TECHNIQUES``; its family record in ``FAMILIES``:
``shadow``, ``soft``, ``rtshadows``, ``aa``, ``taa``).

Each model samples the scene where the real technique samples (shadow-map texel centres from
the light, MSAA sample positions, pixel centres from the camera) with the same intersection
engine as the oracle, and reconstructs the way the technique does: depth formats and their
quantization, depth clamp, bias, shadow-map filters (PCF, Poisson, VSM/EVSM, PCSS, moment
shadow maps), cascade selection and blending; coverage, resolve and post-process filters for
anti-aliasing (MSAA, SSAA, FXAA, SMAA, ACAA, AGAA), history and rectification for TAA;
ray-traced shadows at one ray a pixel denoised over frames (SVGF, A-SVGF, FidelityFX, SIGMA-class).

>>> from raster_oracle import raster_models, scenes
>>> s = scenes.load("city")                                            # doctest: +SKIP
>>> r = raster_models.run("sdsm", s, partitions=4, resolution=2048,
...                       filter="pcf", pcf_size=3)                    # doctest: +SKIP
>>> r.outputs["visibility"].shape, r.cost["shadow_map_bytes"]          # doctest: +SKIP

Here: the registry's names and each family's parameter classes of the first families
(``raster_models.registry.TECHNIQUES[name].params`` has every technique's). Layering:
depends on :mod:`scenes` only.
"""

from .aa import (
    AA_OUTPUT_CHANNELS,
    AcaaParams,
    AgaaParams,
    FxaaParams,
    MsaaParams,
    NoAAParams,
    SsaaParams,
)
from .coherent import CoherentParams
from .errors import ModelError
from .izb import IzbParams
from .registry import (
    FAMILIES,
    TECHNIQUES,
    Family,
    Technique,
    family,
    family_of,
    front_group,
    list_techniques,
    parse_params,
    run,
)
from .result import ModelResult
from .shadowmaps import CsmParams, SdsmParams, ShadowMapParams

#: Names of the output channels every hard-shadow model writes (``output.exr``); AA models'
#: are :data:`AA_OUTPUT_CHANNELS`.
OUTPUT_CHANNELS = ("visibility", "cascade", "texels_per_pixel", "resolution_error", "uncovered")
#: Written besides by the shadow models' compare filters (point, hw_pcf, pcf, poisson,
#: three_pcf): each receiver's compare margin (:mod:`.shadowmaps.margins`).
COMPARE_OUTPUT_CHANNELS = ("compare_margin",)

__all__ = [
    "AA_OUTPUT_CHANNELS",
    "COMPARE_OUTPUT_CHANNELS",
    "FAMILIES",
    "OUTPUT_CHANNELS",
    "TECHNIQUES",
    "AcaaParams",
    "AgaaParams",
    "CoherentParams",
    "CsmParams",
    "Family",
    "FxaaParams",
    "IzbParams",
    "ModelError",
    "ModelResult",
    "MsaaParams",
    "NoAAParams",
    "SdsmParams",
    "ShadowMapParams",
    "SsaaParams",
    "Technique",
    "family",
    "family_of",
    "front_group",
    "list_techniques",
    "parse_params",
    "run",
]
