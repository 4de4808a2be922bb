"""Shadow-map techniques (shadow-map, csm, sdsm) and the pipeline they share: render the maps,
shade a G-buffer with them (filters, depth formats, biases), fit light boxes."""

from .csm import CsmParams
from .sdsm import SdsmParams
from .shadow_map import ShadowMapParams

__all__ = ["CsmParams", "SdsmParams", "ShadowMapParams"]
