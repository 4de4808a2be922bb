"""Shadow-map techniques (shadow-map, csm, sdsm) and the pipeline they share: render the maps,
shade a G-buffer with them (filters, depth formats, biases), fit light boxes; and
:func:`visibility_at`, their visibility at other models' shading points."""

from .csm import CsmParams
from .records import MapData, Partition, Setup
from .sdsm import SdsmParams
from .shadow_map import ShadowMapParams
from .visibility import SHADOW_TECHNIQUES, supported_lights, visibility_at

__all__ = [
    "SHADOW_TECHNIQUES",
    "CsmParams",
    "MapData",
    "Partition",
    "SdsmParams",
    "Setup",
    "ShadowMapParams",
    "supported_lights",
    "visibility_at",
]
