"""Parameters of the ``smaa`` technique: the presets and defaults of ``SMAA.hlsl``, each value
overridable, and the sample positions and sub-sample indices of its modes."""

from __future__ import annotations

from dataclasses import dataclass

from ....scenes.base.display import TONE_MAPPERS
from ... import params as _params
from ...errors import ModelError

__all__ = ["INPUT_8BIT", "INPUTS", "MODES", "PRESETS", "SmaaParams", "resolved"]

#: The colour buffer of the published integration (the demo's ``sceneRT``,
#: ``DXGI_FORMAT_R8G8B8A8_UNORM_SRGB``): 8-bit sRGB bytes, read through the UNORM view
#: (gamma) by edge detection and through the sRGB view (linear) by the blending pass.
INPUT_8BIT = "rgba8-srgb"
#: Colour buffers SMAA can read: the 8-bit sRGB buffer, or the float gamma-encoded image.
INPUTS = (INPUT_8BIT, "float")

#: ``SMAA.hlsl``'s presets and its no-preset defaults ("none"): threshold, max search steps,
#: max diagonal search steps (0: ``SMAA_DISABLE_DIAG_DETECTION``), corner rounding (100:
#: ``SMAA_DISABLE_CORNER_DETECTION``; rounding 100 scales the corner factor by 0, the same).
PRESETS = {
    "low": {"threshold": 0.15, "max_search_steps": 4, "max_search_steps_diag": 0,
            "corner_rounding": 100},
    "medium": {"threshold": 0.1, "max_search_steps": 8, "max_search_steps_diag": 0,
               "corner_rounding": 100},
    "high": {"threshold": 0.1, "max_search_steps": 16, "max_search_steps_diag": 8,
             "corner_rounding": 25},
    "ultra": {"threshold": 0.05, "max_search_steps": 32, "max_search_steps_diag": 16,
              "corner_rounding": 25},
    "none": {"threshold": 0.1, "max_search_steps": 16, "max_search_steps_diag": 8,
             "corner_rounding": 25},
}  # fmt: skip

#: Frames of each mode; each frame a list of (sample position in the pixel, y down from the
#: upper-left corner; ``subsampleIndices``) (``SMAA.hlsl`` @SUBSAMPLE_INDICES; its jitters are
#: y up: (0.25, -0.25) is (0.75, 0.75) here, the D3D 2x standard sample 0).
MODES = {
    "1x": [[((0.5, 0.5), (0, 0, 0, 0))]],
    "t2x": [[((0.75, 0.75), (1, 1, 1, 0))], [((0.25, 0.25), (2, 2, 2, 0))]],
    "s2x": [[((0.75, 0.75), (1, 1, 1, 0)), ((0.25, 0.25), (2, 2, 2, 0))]],
    "4x": [
        [((0.875, 0.625), (5, 3, 1, 3)), ((0.375, 0.125), (4, 6, 2, 3))],
        [((0.625, 0.875), (3, 5, 1, 4)), ((0.125, 0.375), (6, 4, 2, 4))],
    ],
}

_FROM_PRESET = -1


@dataclass(frozen=True)
class SmaaParams:
    """Parameters of :func:`.model.run`; -1 takes the value from ``preset``."""

    preset: str = _params.param(
        "none",
        source="SMAA.hlsl: no SMAA_PRESET_* defined (the configurable defines' defaults)",
        help="quality preset: none (the header's defaults), low, medium, high, ultra",
        choices=tuple(PRESETS),
    )
    mode: str = _params.param(
        "1x",
        source="SMAA.hlsl @SUBSAMPLE_INDICES: SMAA 1x, T2x, S2x, 4x",
        help="1x; t2x (two jittered frames, resolve); s2x (2x MSAA, SMAA per sample); 4x",
        choices=tuple(MODES),
    )
    input: str = _params.param(
        INPUT_8BIT,
        source="SMAA Demo/DX10/Code/Demo.cpp:512 (sceneRT_SRGB = R8G8B8A8_UNORM_SRGB view of "
        "sceneRT), :686 (edges read sceneRT, blending sceneRT_SRGB); SMAA.hlsl step 5",
        help="colour buffer SMAA reads: rgba8-srgb (8-bit sRGB render target, as engines feed "
        "it) or float (the tone-mapped image unquantized)",
        choices=INPUTS,
    )
    edge_detection: str = _params.param(
        "luma",
        source="SMAA.hlsl: 'For quickstarters: just use luma edge detection'",
        help="edge detection input: luma, color or depth",
        choices=("luma", "color", "depth"),
    )
    threshold: float = _params.param(
        -1.0,
        source="SMAA_THRESHOLD (preset; default 0.1)",
        help="edge contrast threshold in [0, 0.5]; -1: the preset's",
        lo=-1.0,
        hi=0.5,
    )
    max_search_steps: int = _params.param(
        -1,
        source="SMAA_MAX_SEARCH_STEPS (preset; default 16)",
        help="orthogonal search steps each side (2 pixels a step), [0, 112]; -1: preset's",
        lo=-1,
        hi=112,
    )
    max_search_steps_diag: int = _params.param(
        -1,
        source="SMAA_MAX_SEARCH_STEPS_DIAG (preset; default 8; LOW/MEDIUM: disabled)",
        help="diagonal search steps each side, [0, 20], 0: diagonal detection off; -1: preset's",
        lo=-1,
        hi=20,
    )
    corner_rounding: int = _params.param(
        -1,
        source="SMAA_CORNER_ROUNDING (preset; default 25; LOW/MEDIUM: disabled = 100)",
        help="corner rounding in [0, 100], 100: corner detection off; -1: preset's",
        lo=-1,
        hi=100,
    )
    local_contrast_factor: float = _params.param(
        2.0,
        source="SMAA_LOCAL_CONTRAST_ADAPTATION_FACTOR default",
        help="an edge is dropped where a neighbouring edge has this many times its contrast",
        lo=1.0,
        hi=100.0,
    )
    depth_threshold: float = _params.param(
        -1.0,
        source="SMAA_DEPTH_THRESHOLD default (0.1 * SMAA_THRESHOLD)",
        help="depth edge threshold in depth-buffer units; -1: 0.1 x threshold",
        lo=-1.0,
        hi=1.0,
    )
    predication: bool = _params.param(
        False,
        source="SMAA_PREDICATION default 0",
        help="lower the colour threshold where the depth buffer has an edge",
    )
    predication_threshold: float = _params.param(
        0.01, source="SMAA_PREDICATION_THRESHOLD default", help="depth edge threshold",
        lo=0.0, hi=1.0,
    )  # fmt: skip
    predication_scale: float = _params.param(
        2.0, source="SMAA_PREDICATION_SCALE default", help="global threshold scale, [1, 5]",
        lo=1.0, hi=5.0,
    )  # fmt: skip
    predication_strength: float = _params.param(
        0.4, source="SMAA_PREDICATION_STRENGTH default", help="local threshold decrease, [0, 1]",
        lo=0.0, hi=1.0,
    )  # fmt: skip
    reprojection_weight_scale: float = _params.param(
        30.0,
        source="SMAA_REPROJECTION_WEIGHT_SCALE default",
        help="velocity weighting of the T2x/4x resolve, [0, 80]",
        lo=0.0,
        hi=80.0,
    )
    srgb_blending: bool = _params.param(
        True,
        source="SMAA.hlsl step 5: sRGB reads and writes in the blending pass",
        help="blend in linear light (sRGB fetches); off: in gamma space",
    )
    exposure_key: float = _params.param(
        0.18,
        source="Reinhard et al. 2002 normal key (as fxaa)",
        help="middle grey the image's log-average luminance is mapped to before SMAA",
        lo=1e-3,
        hi=0.99,
    )
    tone_mapper: str = _params.param(
        "aces",
        source="scenes.base.display: the project's one pipeline (ACES, the scoring's curve)",
        help="tone-mapping curve before SMAA: aces, reinhard or clip",
        choices=TONE_MAPPERS,
    )

    def check(self, technique: str) -> None:
        for name in ("threshold", "depth_threshold"):
            v = getattr(self, name)
            if v != _FROM_PRESET and v < 0.0:
                raise ModelError(f"{technique}: parameter {name} must be -1 or >= 0, got {v}")


def resolved(p: SmaaParams) -> dict:
    """The effective settings: the preset's values where a parameter is -1."""
    out = dict(PRESETS[p.preset])
    for k in out:
        v = getattr(p, k)
        if v != _FROM_PRESET:
            out[k] = v
    out["threshold"] = float(out["threshold"])
    dt = p.depth_threshold
    out["depth_threshold"] = 0.1 * out["threshold"] if dt == _FROM_PRESET else float(dt)
    for k in (
        "input",
        "edge_detection",
        "local_contrast_factor",
        "predication",
        "predication_threshold",
        "predication_scale",
        "predication_strength",
        "reprojection_weight_scale",
        "srgb_blending",
    ):
        out[k] = getattr(p, k)
    return out
