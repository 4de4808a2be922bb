"""SMAA (issue 27): the three passes of ``SMAA.hlsl`` (:mod:`.edges`, :mod:`.weights`,
:mod:`.blending`), its area and search textures computed from the published construction
(:mod:`.textures`), and the 1x, T2x, S2x and 4x modes (:mod:`.model`)."""

from .params import MODES, PRESETS, SmaaParams

__all__ = ["MODES", "PRESETS", "SmaaParams"]
