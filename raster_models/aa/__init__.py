"""Anti-aliasing models: no AA, SSAA, MSAA, ACAA, AGAA, FXAA (issue 9) and SMAA (issue 27).

Every model samples where the technique samples (sub-sample positions, pixel centres) with
the intersection engine the oracle uses, shades with the oracle's shading model and exact
shadow rays (or a shadow technique), and writes ``color`` (linear, (H, W, 3)), ``coverage``,
``shading_events`` and its diagnostics, with a cost record of framebuffer bytes, shading
events, passes, samples tested and bandwidth.
"""

from .acaa import AcaaParams
from .agaa import AgaaParams
from .fxaa import FxaaParams
from .msaa import MsaaParams
from .noaa import NoAAParams
from .smaa import SmaaParams
from .ssaa import SsaaParams

#: Output channels of the anti-aliasing models (``ties``: ACAA, ``aggregates``: AGAA).
AA_OUTPUT_CHANNELS = ("color", "coverage", "front_coverage", "shading_events")

__all__ = [
    "AA_OUTPUT_CHANNELS",
    "AcaaParams",
    "AgaaParams",
    "FxaaParams",
    "MsaaParams",
    "NoAAParams",
    "SmaaParams",
    "SsaaParams",
]
