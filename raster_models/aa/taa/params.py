"""Parameters of the ``taa`` model and its presets.

A preset named after an engine (``ue4``, ``inside``, ``hdrp``, ``hdrp-high``, ``filament``)
with no part set runs that engine's transcribed resolve (:mod:`.ue4`, :mod:`.inside`,
:mod:`.hdrp`, :mod:`.filament`; sources in :data:`PRESET_SOURCES`). Every part can also be
set on its own: then the part-by-part pipeline runs, each part left at ``preset`` (strings) or
0 (numbers) taking the preset's value in :data:`PRESETS` (the nearest part of the generic
pipeline, not the engine's exact step). ``preset=custom`` takes the ``ue4`` part values.
"""

from __future__ import annotations

from dataclasses import dataclass

from ... import params as _params
from ...errors import ModelError
from .blend import BLENDS
from .filters import HISTORY_FILTERS, INPUT_FILTERS
from .jitter import JITTERS
from .rectify import COLOR_SPACES, NEIGHBOURHOODS, RECTIFIERS

__all__ = ["ENGINE_PRESETS", "PRESETS", "PRESET_SOURCES", "TaaParams", "resolve"]

#: Presets whose every step is a transcription of the engine's shipped shader
#: (:mod:`.inside`, :mod:`.filament`); setting any part runs the part-by-part pipeline.
ENGINE_PRESETS = (
    "ue4",
    "ue4-high",
    "ue4-18",
    "ue4-20",
    "inside",
    "filament",
    "hdrp",
    "hdrp-high",
)

DILATIONS = ("none", "nearest-depth-3x3")
REPROJECTIONS = ("motion", "off")
REJECTIONS = ("none", "offscreen", "depth")

#: The published TAAs, part by part.
PRESETS = {
    "ue4": dict(
        jitter="ue4-gaussian",
        samples=8,
        input_filter="ue4",
        history_filter="catmull-rom",
        dilation="nearest-depth-3x3",
        reprojection="motion",
        rectify="clamp",
        color_space="ycocg",
        neighbourhood="rounded",
        gamma=1.0,
        blend="ue4",
        alpha=0.04,
        reject="offscreen",
    ),
    "inside": dict(
        jitter="halton",
        samples=16,
        input_filter="box",
        history_filter="bilinear",
        dilation="nearest-depth-3x3",
        reprojection="motion",
        rectify="clip",
        color_space="rgb",
        neighbourhood="rounded",
        gamma=1.0,
        blend="inside",
        alpha=0.0,
        reject="offscreen",
    ),
    "hdrp": dict(
        jitter="halton",
        samples=8,
        input_filter="ue4",
        history_filter="catmull-rom",
        dilation="nearest-depth-3x3",
        reprojection="motion",
        rectify="variance",
        color_space="ycocg",
        neighbourhood="3x3",
        gamma=1.0,
        blend="constant",
        alpha=0.125,
        reject="offscreen",
    ),
    "filament": dict(
        jitter="halton",
        samples=16,
        input_filter="ue4",
        history_filter="catmull-rom",
        dilation="none",
        reprojection="motion",
        rectify="clip",
        color_space="rgb",
        neighbourhood="rounded",
        gamma=1.0,
        blend="constant",
        alpha=0.12,
        reject="offscreen",
    ),
}
PRESETS["hdrp-high"] = dict(PRESETS["hdrp"])
PRESETS["ue4-high"] = dict(PRESETS["ue4"])
PRESETS["ue4-18"] = dict(PRESETS["ue4"])
PRESETS["ue4-20"] = dict(PRESETS["ue4"])
PRESETS["custom"] = dict(PRESETS["ue4"])

#: Where each preset's values come from.
PRESET_SOURCES = {
    "ue4": "Unreal Engine 4.19 (Kryptexas/UE4-GameWorks-4.19.2@0341e5d5c1c2), main pass at "
    "r.PostProcessAAQuality 4: PostProcessTemporalAA.cpp (MainTemporalAAPS unless quality 3; "
    "r.TemporalAACatmullRom 1 plus weights; r.TemporalAACurrentFrameWeight 0.04; PF_FloatRGBA "
    "history), PostProcessTemporalAA.usf MainTemporalAACommon (AA_FILTERED, AA_BORDER, AA_CROSS "
    "2, AA_YCOCG, AA_BICUBIC, AA_DYNAMIC_ANTIGHOST, AA_TONE, AA_CLAMP, 5 samples), "
    "PostProcessTemporalCommon.ush (resolve), Common.ush Texture2DSampleBicubic (5-tap "
    "Catmull-Rom), SceneVisibility.cpp (8 samples: windowed Box-Muller of Halton(i+1), sigma "
    "0.47), SceneRendering.h OnFrameRenderingSetup (index incremented before use); "
    "raster_models/aa/taa/ue4.py",
    "ue4-high": "Unreal Engine 4.19 (Kryptexas/UE4-GameWorks-4.19.2@0341e5d5c1c2) at "
    "r.PostProcessAAQuality 3 (BaseScalability.ini@04475707d16b [AntiAliasingQuality@2], High): "
    "PostProcessTemporalAA.cpp bUseFast = Quality == 3 draws MainFastTemporalAAPS; "
    "PostProcessTemporalAA.usf MainFastTemporalAACommon (as MainTemporalAACommon without AA_TONE "
    "and AA_DYNAMIC_ANTIGHOST); otherwise as ue4; raster_models/aa/taa/ue4.py",
    "ue4-18": "Unreal Engine 4.18.3 (windystrife/UnrealEngine_NVIDIAGameWorks: Build.version "
    "@0bd1222b5959, PostProcessTemporalCommon.ush @0bd1222b5959 with the anti-flicker block "
    "under #if 0, PostProcessTemporalAA.cpp @0f9675ae7119 with r.TemporalAACatmullRom 0: "
    "Gaussian exp(-2.29 d^2) plus weights); otherwise as ue4; raster_models/aa/taa/ue4.py",
    "ue4-20": "Unreal Engine 4.20.3 main pass as a licensee's branch has it, not Epic's "
    "release (Epic's EpicGames/UnrealEngine is readable only by linked accounts; not read): "
    "blackix/blackix@03236bd0c684, a partner's fork (Build.version "
    "4.20.3, PostProcessTemporalAA.usf TAA_PASS_CONFIG 1, not TAA_FAST) with the 4.20-4.22 "
    "PostProcessTemporalAA.cpp of folgerwang/UnrealEngine@19747897ecf5 (r.TemporalAACatmullRom "
    "0, HistoryBufferUVMinMax, TAA_CAMERA_CUT without a history); raster_models/aa/taa/ue4.py",
    "inside": "playdeadgames/temporal@4795aa0007d4 (2017-03-31): TemporalReprojection.cs:34-45 "
    "(MinMax3x3Rounded, unjitterColorSamples, useClipping, useDilation, useOptimizations, "
    "feedback 0.88-0.97), :90-92 + EffectBase.cs:73 (ARGB32 Default: 8-bit sRGB history), "
    ":122-127 (frame 0 history = blit of the frame); TemporalReprojection.shader:216 (bilinear "
    "current at c - jitter), :220 (bilinear history), :229-258 (rounded min/max), :122-137 "
    "(clip towards the centre, FLT_EPS 1e-8 :37), :305-319 (Luminance feedback), :393-394 "
    "(saturate); IncDepth.cginc:37-68 (3x3 closest depth); FrustumJitter.cs:128-137, 243, "
    "301-319 (unjittered frame 0, then Halton_2_3_X16); UnityCG.cginc (TwoTailsGames/Unity-"
    "Built-in-Shaders@09db4ee6):29 (linear Luminance 0.0396819152, 0.458021790, 0.00609653955)",
    "hdrp": "Unity-Technologies/Graphics HDRP, TAAQuality Medium (the default): "
    "TemporalAntiAliasing.shader@003084f5d112 (MEDIUM_QUALITY defines, FragTAA), "
    "TemporalAntialiasing.hlsl (HistoryBicubic5Tap, VarianceNeighbourhood, DirectClipToAABB, "
    "SharpenColor, HistoryContrast), HDAdditionalCameraData.cs (sharpen 0.5, history "
    "sharpening 0.35, anti-flicker 0.5, base blend 0.875), HDRenderPipeline.PostProcess.cs "
    "PrepareTAAPassData, HDCamera.cs Update + GetJitteredProjectionMatrix (Halton (i+1), i = "
    "taaFrameIndex incremented before use: frame k has i = (k+1) mod 8), "
    "Color.hlsl RGBToYCoCg (chroma bias 128/255), RenderPipelineSettings (R11G11B10); the "
    "Medium path as in the released HDRP 12.1.0 (needle-mirror tag 12.1.0/Unity-2021.2.0b16, "
    "3178738b: shader :298, :325; hlsl :20-38, :278-301, :377, :565-613, :699-716, :776-801; "
    "HDAdditionalCameraData.cs :307-330; HDCamera.cs :949-952, :1731-1732); "
    "raster_models/aa/taa/hdrp.py",
    "hdrp-high": "as hdrp with TAAQuality High: HIGH_QUALITY defines (8 neighbours, "
    "Blackman-Harris central filter exp(-0.5/0.22 |o - jitter|^2) with the quad swizzle, "
    "motion-dependent anti-flicker); the weights as the released C# sends them (needle-mirror "
    "tag 12.1.0/Unity-2021.2.0b16, 3178738b: HDRenderPipeline.PostProcess.cs :1534-1545 "
    "TAASampleOffsets, diagonals (-1,1), (1,-1), (1,1), (-1,-1), :1578-1579 o - taaJitter; "
    "13.0.0/Unity-2022.1.0a12, a645acdd: :1526-1537, :1570-1571); "
    "raster_models/aa/taa/hdrp.py",
    "filament": "google/filament: Options.h@2fac13e154fb TemporalAntiAliasingOptions (feedback "
    "0.12, filterWidth 1, AABB box, ACCURATE clipping, HALTON_23_X16, useYCoCg false), "
    "PostProcessManager.cpp@003e5005713c (halton() i += 409; jitter frameId % 16 - 0.5; "
    "weights exp(-2.29 |o - jitter|^2); first frame history = the colour buffer), "
    "taa.mat@63ddbb267ac6 (depth + camera reprojection, 5-tap Catmull-Rom, rounded box, "
    "clipToBox, c/(1+max c) tone weighting), Options.h RenderQuality (RGB16F buffers); "
    "raster_models/aa/taa/filament.py",
    "custom": "the part-by-part pipeline with the part values listed under ue4 (Karis 2014's "
    "description: windowed-Gaussian jitter, 3x3 exp(-2.29 d^2) filter, Catmull-Rom history, "
    "rounded YCoCg clamp, the 0.04 -> 0.2 velocity blend) for every part not set",
}


def _choices(names) -> tuple[str, ...]:
    return ("preset", *names)


def _by_preset(key: str) -> str:
    """A part's ``source``: each published preset's value (their sources: PRESET_SOURCES)."""
    values = ", ".join(f"{name} {PRESETS[name][key]}" for name in PRESETS if name != "custom")
    return f"the preset's: {values} (raster_models/aa/taa/params.py PRESET_SOURCES)"


@dataclass(frozen=True)
class TaaParams:
    """Parameters of :func:`raster_models.aa.taa.run` (see the package docstring)."""

    preset: str = _params.param(
        "ue4",
        source="UE 4.19's main TAA pass (Karis 2014), the most copied TAA",
        help="engine TAA as shipped: ue4 (4.19, Epic AA quality), ue4-high (4.19, High), "
        "ue4-18 (4.18.3), ue4-20 (4.20), inside, hdrp "
        "(Unity, Medium), "
        "hdrp-high, filament; custom (= ue4's part values); setting any part runs the "
        "part-by-part pipeline with the preset's part values",
        choices=tuple(PRESETS),
    )
    jitter: str = _params.param(
        "preset",
        source=_by_preset("jitter"),
        help="sub-pixel jitter: halton (2,3), ue4-gaussian (UE4's windowed Gaussian), none",
        choices=_choices(JITTERS),
    )
    samples: int = _params.param(
        0,
        source=_by_preset("samples"),
        help="jitter sequence length (0: the preset's; 8 or 16)",
        lo=0,
        hi=64,
    )
    input_filter: str = _params.param(
        "preset",
        source=_by_preset("input_filter"),
        help="current-frame filter: ue4 (3x3 exp(-2.29 d^2)) or box (own sample)",
        choices=_choices(INPUT_FILTERS),
    )
    history_filter: str = _params.param(
        "preset",
        source=_by_preset("history_filter"),
        help="history sampling: bilinear or catmull-rom",
        choices=_choices(HISTORY_FILTERS),
    )
    dilation: str = _params.param(
        "preset",
        source=_by_preset("dilation"),
        help="velocity of the pixel (none) or of its nearest-depth 3x3 neighbour",
        choices=_choices(DILATIONS),
    )
    reprojection: str = _params.param(
        "preset",
        source=_by_preset("reprojection"),
        help="history read where the model's own motion vectors point (motion) or at the same "
        "pixel (off)",
        choices=_choices(REPROJECTIONS),
    )
    rectify: str = _params.param(
        "preset",
        source=_by_preset("rectify"),
        help="history rectification: none, clamp (min/max), clip (AABB clip), variance",
        choices=_choices(RECTIFIERS),
    )
    color_space: str = _params.param(
        "preset",
        source=_by_preset("color_space"),
        help="rectification space: rgb, ycocg",
        choices=_choices(COLOR_SPACES),
    )
    neighbourhood: str = _params.param(
        "preset",
        source=_by_preset("neighbourhood"),
        help="rectification neighbourhood: 3x3, plus (5 taps), rounded (their average)",
        choices=_choices(NEIGHBOURHOODS),
    )
    gamma: float = _params.param(
        0.0,
        source=_by_preset("gamma"),
        help="variance clip gamma (0: the preset's)",
        lo=0.0,
        hi=4.0,
    )
    blend: str = _params.param(
        "preset",
        source=_by_preset("blend"),
        help="history blend: constant alpha, ue4 (luma-contrast feedback), inside (0.88-0.97)",
        choices=_choices(BLENDS),
    )
    alpha: float = _params.param(
        0.0,
        source=_by_preset("alpha"),
        help="current-frame weight of constant and ue4 blends (0: the preset's)",
        lo=0.0,
        hi=1.0,
    )
    reject: str = _params.param(
        "preset",
        source=_by_preset("reject"),
        help="history rejected where its position is off screen (offscreen), also where the "
        "previous depth there disagrees with the reprojected point's by > 1% (depth), or never",
        choices=_choices(REJECTIONS),
    )

    def check(self, technique: str) -> None:
        r = resolve(self)
        if r["jitter"] != "none" and r["samples"] < 1:
            raise ModelError(f"{technique}: samples must be >= 1 with jitter {r['jitter']}")
        if r["blend"] != "inside" and not r["alpha"] > 0.0:
            raise ModelError(f"{technique}: alpha must be > 0 with blend {r['blend']}")


def resolve(p: TaaParams) -> dict:
    """Every part's value: the parameter where set, else the preset's; ``engine`` names the
    transcribed resolve (:data:`ENGINE_PRESETS`) that runs when no part is set, else
    ``none`` (the part-by-part pipeline with the preset's part values)."""
    base = PRESETS[p.preset]
    out = {}
    overridden = False
    for key, default in base.items():
        v = getattr(p, key)
        overridden |= v not in ("preset", 0, 0.0)
        out[key] = default if v in ("preset", 0, 0.0) else v
    out["engine"] = p.preset if p.preset in ENGINE_PRESETS and not overridden else "none"
    return out
