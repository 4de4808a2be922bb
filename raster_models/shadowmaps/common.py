"""Parameters every shadow-map technique shares: map format, bias, filter, precision.

Defaults name their source. Where the three reference implementations differ (Intel SDSM
sample, TheRealMJP/Shadows, Falcor's CSM pass) each technique module overrides the default
and says whose it is.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..depth import FORMATS
from ..errors import ModelError
from ..params import param
from .filters import FILTERS

__all__ = ["CommonParams"]


@dataclass(frozen=True)
class CommonParams:
    """Shared parameters (see :func:`raster_models.list_techniques` for the records)."""

    resolution: int = param(
        2048,
        source="TheRealMJP/Shadows default ShadowMapSize 2048",
        help="shadow-map texels per side (per partition / cube face)",
        lo=8,
        hi=16384,
    )
    format: str = param(
        "D32F",
        source="TheRealMJP/Shadows default DepthBufferFormat (32-bit float); Falcor D32Float",
        help="depth format: D16 / D24 UNORM (quantum 1/(2^n - 1)) or D32F (float32). The "
        "compare reference is clamped to [0, 1] for every format (hardware clamps it for UNORM "
        "only): for D32F this differs only for a receiver beyond a map's far plane (reference "
        "> 1: hardware shadows it, the model compares 1 and lights it), e.g. SDSM receivers "
        "outside a late partition (latency > 0)",
        choices=tuple(FORMATS),
    )
    depth_clamp: bool = param(
        True,
        source="Falcor CSM rasterizer state setDepthClamp(true); Intel SDSM "
        "DepthClipEnable = false",
        help="pancaking: casters nearer to the light than the map's near plane keep depth 0 "
        "instead of being clipped (off: their shadows vanish)",
    )
    bias: float = param(
        0.005,
        source="TheRealMJP/Shadows Bias 0.005; Falcor CsmData::depthBias 0.005",
        help="constant bias subtracted from the receiver's normalized depth before the "
        "compare (point/PCF filters; replaced by the receiver-plane bias when that is on)",
        lo=-1.0,
        hi=1.0,
    )
    depth_bias: int = param(
        0,
        source="D3D11 rasterizer default DepthBias 0",
        help="hardware DepthBias (integer units of r: 1/(2^n - 1) for UNORM, 2^(e-23) for "
        "D32F) added to every texel when the map is rendered, before the viewport clamp",
        lo=-(1 << 24),
        hi=1 << 24,
    )
    slope_scaled_bias: float = param(
        0.0,
        source="D3D11 rasterizer default SlopeScaledDepthBias 0",
        help="hardware SlopeScaledDepthBias: times the caster's MaxDepthSlope (normalized "
        "depth per texel, from the hit's geometric normal)",
        lo=-1e6,
        hi=1e6,
    )
    depth_bias_clamp: float = param(
        0.0,
        source="D3D11 rasterizer default DepthBiasClamp 0 (no clamp)",
        help="hardware DepthBiasClamp (0 = no clamp)",
        lo=-1.0,
        hi=1.0,
    )
    receiver_plane_bias: bool = param(
        False,
        source="Falcor CSM (none); TheRealMJP/Shadows UsePlaneDepthBias defaults to true",
        help="receiver-plane depth bias from the light-space derivatives of the receiver: "
        "per-tap depth slope plus min(texel . |dz/duv|, 0.01) (MJP); replaces 'bias'",
    )
    normal_offset: float = param(
        0.0,
        source="TheRealMJP/Shadows OffsetScale 0 (Falcor: commented out)",
        help="normal offset in texels of the selected map: the lookup position moves by "
        "normal_offset * texel * saturate(1 - N.L) * N (MJP's GetShadowPosOffset)",
        lo=0.0,
        hi=1e3,
    )
    normal_offset_units: str = param(
        "texels",
        source="TheRealMJP/Shadows GetShadowPosOffset (texels x (1 - N.L)); three.js r187 "
        "shadowmap_vertex.glsl.js:35 adds shadowNormalBias world units (LightShadow.js:74)",
        help="texels: normal_offset texels of the map times saturate(1 - N.L) (MJP); world: "
        "normal_offset world units along the normal, whatever N.L (three.js normalBias)",
        choices=("texels", "world"),
    )
    normal_offset_direction: str = param(
        "facing",
        source="TheRealMJP/Shadows offsets along the shaded (light-facing) normal; three.js "
        "r187 shadowmap_vertex.glsl.js:9 uses the vertex normal as wound",
        help="facing: the normal of the side the camera and light see (a receiver faces "
        "both); vertex: the normal as the triangle is wound, which points away from the "
        "light on the back of a double-sided surface (three.js)",
        choices=("facing", "vertex"),
    )
    bias_space: str = param(
        "hyperbolic",
        source="D3D/GL: the compare reference is the stored (normalized device) depth",
        help="hyperbolic: bias is subtracted from the normalized depth as stored (for a "
        "perspective map, hyperbolic in distance); linear: bias is a fraction of the map's "
        "depth range (far - near) of linear light-view depth, then converted; identical on "
        "orthographic maps, whose stored depth is linear",
        choices=("hyperbolic", "linear"),
    )
    caster_faces: str = param(
        "both",
        source="D3D11 CullMode NONE in the shadow pass (MJP, Falcor); three.js r187 "
        "WebGLShadowMap.js:51,490 renders the opposite side of single-sided materials",
        help="faces rendered into the map, as seen from the light: both, front (wound "
        "counter-clockwise towards the light: the geometric normal faces it) or back "
        "(three.js's default for single-sided glTF materials)",
        choices=("both", "front", "back"),
    )
    caster_alpha: str = param(
        "test",
        source="Filament surface_depth_main.fs:35-40 (google/filament 27de9fb) discards where "
        "alpha < maskThreshold in the depth pass; ignore: the opaque-quad shadows of three.js "
        "issues 24995 (map alpha, r146), 30462 (alphaToCoverage) and 31802 (WebGPURenderer)",
        help="alpha-tested casters (glTF MASK): test (the depth pass discards where the "
        "alpha test fails, at the texel centre, on the texture's base level) or ignore (the "
        "card casts its whole quad)",
        choices=("test", "ignore"),
    )
    lookup_offset: tuple = param(
        (0.0, 0.0),
        source="raster-oracle default (0: texel centres at (i + 0.5) / R; D3D9's texel-to-"
        "pixel convention reads half a texel over)",
        help="(du, dv) in texels added to every lookup's texture coordinates (an engine "
        "that samples its map off the texel-centre convention)",
        lo=-64.0,
        hi=64.0,
    )
    light_matrix: str = param(
        "",
        source="raster-oracle default (the model fits its own light box)",
        help='JSON file with the engine\'s world-to-shadow-texture matrix ({"matrix": 4x4 '
        'row-major, "texture_origin": top-left or bottom-left}) for a directional '
        "light's one orthographic map: the model renders and samples the engine's map",
    )
    filter: str = param(
        "hw_pcf",
        source="Falcor CsmData::filterMode HwPcf",
        help="point, hw_pcf (2x2 hardware PCF), pcf (NxN taps), poisson (disc PCF), vsm, "
        "evsm2, evsm4, three_pcf (three.js r187 PCFShadowMap: 5 hardware-PCF taps on a Vogel "
        "disk of shadow_radius texels rotated per pixel by interleaved gradient noise), "
        "three_vsm (three.js r187 VSMShadowMap: blur_samples taps over +-shadow_radius "
        "texels, (mean, std-dev) in RG16F, (p - 0.3) / 0.65 bleed remap)",
        choices=FILTERS,
    )
    pcf_size: int = param(
        3,
        source="raster-oracle default (MJP FixedFilterSize choices 2..9, Falcor width 5)",
        help="N of the NxN PCF filter: N^2 hardware-PCF taps one texel apart",
        lo=1,
        hi=15,
    )
    poisson_taps: int = param(
        16,
        source="TheRealMJP/Shadows NumDiscSamples 16",
        help="hardware-PCF taps of the Poisson-disc filter",
        lo=1,
        hi=64,
    )
    filter_size: float = param(
        3.0,
        source="raster-oracle default (MJP's FilterSize defaults to 0, which disables the disc)",
        help="diameter in texels of the Poisson disc",
        lo=0.0,
        hi=100.0,
    )
    poisson_rotate: bool = param(
        False,
        source="TheRealMJP/Shadows RandomizeDiscOffsets false",
        help="rotate the disc per pixel by a seeded random angle",
    )
    seed: int = param(
        0,
        source="raster-oracle default",
        help="seed of the Poisson pattern and its per-pixel rotations",
        lo=0,
        hi=2**31 - 1,
    )
    blur_size: int = param(
        1,
        source="TheRealMJP/Shadows FilterSize 0 / Intel edgeSoftening off (no blur)",
        help="box blur width in texels applied to VSM/EVSM moments (1 = none)",
        lo=1,
        hi=63,
    )
    vsm_bias: float = param(
        1e-4,
        source="TheRealMJP/Shadows VSMBias 0.01 (x100 units)",
        help="VSM minimum variance; EVSM minimum variance is (vsm_bias * c * warped depth)^2",
        lo=0.0,
        hi=1.0,
    )
    light_bleeding_reduction: float = param(
        0.0,
        source="TheRealMJP/Shadows LightBleedingReduction 0",
        help="VSM/EVSM light-bleeding reduction: linstep(amount, 1, p)",
        lo=0.0,
        hi=0.999,
    )
    evsm_positive: float = param(
        40.0,
        source="TheRealMJP/Shadows PositiveExponent 40",
        help="EVSM positive exponent (clamped to 42 for float32, 5.54 for float16 moments)",
        lo=0.0,
        hi=1e4,
    )
    evsm_negative: float = param(
        5.0,
        source="TheRealMJP/Shadows NegativeExponent 5",
        help="EVSM negative exponent (EVSM4)",
        lo=0.0,
        hi=1e4,
    )
    evsm_light_space: bool = param(
        False,
        source="TheRealMJP/Shadows applies the exponents to each cascade's own depth",
        help="exponents are per unit of a reference light-space depth and scaled by each "
        "map's depth extent: c * extent / reference (Intel: c / partition.scale.z with the "
        "global light box as reference; csm/shadow-map: one world unit, as MJP's global "
        "shadow matrix)",
    )
    moment_format: str = param(
        "float32",
        source="TheRealMJP/Shadows SMFormat 32-bit",
        help="VSM/EVSM moment texture format",
        choices=("float32", "float16"),
    )
    shadow_radius: float = param(
        1.0,
        source="three.js r187 src/lights/LightShadow.js:87 radius = 1",
        help="three_pcf: radius in texels of the Vogel disk; three_vsm: half-width in "
        "texels of the blur (taps at -radius..+radius)",
        lo=0.0,
        hi=100.0,
    )
    blur_samples: int = param(
        8,
        source="three.js r187 src/lights/LightShadow.js:95 blurSamples = 8 "
        "(WebGLShadowMap.js:55 VSM_SAMPLES: 8)",
        help="three_vsm: taps of each (vertical, horizontal) blur pass",
        lo=1,
        hi=64,
    )
    address_mode: str = param(
        "clamp",
        source="Intel SDSM and MJP samplers use ADDRESS_CLAMP (Falcor: border, colour 1)",
        help="lookups outside a map: clamp (edge texels) or border (lit)",
        choices=("clamp", "border"),
    )
    subtexel_bits: int = param(
        8,
        source="D3D11: 8 bits of sub-texel precision for filtering weights",
        help="bits of the bilinear PCF/moment weights (0 = exact)",
        lo=0,
        hi=24,
    )
    matrix_precision: str = param(
        "float64",
        source="raster-oracle default (engines use float32: set it to reproduce them)",
        help="precision of light matrices and shadow lookups (float32 = GPU/CPU floats)",
        choices=("float64", "float32"),
    )
    view_projection_inverse: str = param(
        "separate",
        source="TheRealMJP/Shadows CalculateInverseViewProj (fix of issue #6, Falcor PR #330)",
        help="frustum corners from inverse(view) * inverse(projection) (separate) or from "
        "inverse(projection * view) as one matrix (combined: shimmers at far >= 1000 in "
        "float32)",
        choices=("separate", "combined"),
    )

    def check(self, technique: str) -> None:
        """Cross-field validation (raises :class:`ModelError`)."""
        if len(self.lookup_offset) != 2:
            raise ModelError(
                f"{technique}: lookup_offset must be two numbers (du;dv texels), "
                f"got {len(self.lookup_offset)}"
            )
        if self.filter in ("vsm", "evsm2", "evsm4", "msm", "three_vsm") and (
            self.receiver_plane_bias
        ):
            raise ModelError(
                f"{technique}: receiver_plane_bias applies to compare filters "
                f"(point, hw_pcf, pcf, poisson), not to filter={self.filter}"
            )
