"""The technique registry and the one dispatch function, :func:`run`."""

from __future__ import annotations

from dataclasses import dataclass

from . import params
from .aa import fxaa as fxaa_model  # noqa: I001
from .aa import msaa, noaa, ssaa
from .aa.acaa import model as acaa
from .aa.agaa import model as agaa
from .aa.smaa import model as smaa_model
from .aa.taa import model as taa
from .alpha import technique as alpha
from .coherent import model as coherent
from .errors import ModelError
from .izb import model as izb
from .rtshadows import model as rtshadows
from .rtshadows.svgf import SvgfParams
from .shadowmaps import csm, msm, pcss, sdsm, shadow_map

__all__ = [
    "FAMILIES",
    "TECHNIQUES",
    "Family",
    "Technique",
    "family",
    "family_of",
    "front_group",
    "list_techniques",
    "parse_params",
    "run",
]


@dataclass(frozen=True)
class Family:
    """A technique family: everything the CLI, sweeps, scoring and reports need to know about
    its techniques, in one record (a new family is its technique folder plus one of these).

    Attributes
    ----------
    name : the family's key (``Technique.family``).
    title : the report's name of the group whose Pareto fronts compare its techniques (None:
        each technique is a group of its own, unless ``Technique.front`` names one).
    channels : candidate channels its models produce and are scored on (first: the primary).
    coverage_channel : the channel its ``coverage`` output is scored as (None: no coverage).
    metrics : metrics plotted on its fronts, headline first: keys of the metric catalogue
        (``metrics.catalog.CATALOG``; a test checks that every key is there).
    costs : cost keys plotted on its fronts, memory first.
    memory_cost : the cost ``tune`` minimises when none is given.
    per_pixel_memory : its ``framebuffer_bytes`` are per pixel: the report restates them at
        other resolutions.
    extremes_scene : base scene of the extreme-input study (None: the study skips the family).
    extremes_metric : the error the extreme-input study judges.
    temporal : its models keep state from frame to frame (scored over frame sequences).
    steady_against : what a temporal family's steady state is judged against: ``reference``
        (the steady error itself) or ``ssaa8`` (8x SSAA's error over the same frames beside it).
    group : the family whose report fronts its techniques join (None: its own).
    """

    name: str
    title: str | None
    channels: tuple[str, ...]
    metrics: tuple[str, ...]
    costs: tuple[str, ...]
    memory_cost: str
    coverage_channel: str | None = None
    per_pixel_memory: bool = False
    extremes_scene: str | None = None
    extremes_metric: str | None = None
    temporal: bool = False
    steady_against: str = "reference"
    group: str | None = None


#: The technique families by name.
FAMILIES: dict[str, Family] = {
    f.name: f
    for f in (
        Family(
            "shadow",
            None,
            ("visibility",),
            ("misclassified_fraction", "visibility_mae"),
            ("memory_bytes", "texels_rendered"),
            "shadow_map_bytes",
            extremes_scene="plate",
            extremes_metric="misclassified_fraction",
        ),
        Family(
            "aa",
            "anti-aliasing",
            ("color", "coverage"),
            ("flip_mean", "coverage_edge_rmse"),
            ("framebuffer_bytes", "shading_events_mean"),
            "framebuffer_bytes",
            coverage_channel="front_coverage",
            per_pixel_memory=True,
            extremes_scene="star",
            extremes_metric="coverage_rmse",
        ),
        Family(
            "taa",
            "temporal anti-aliasing",
            ("color",),
            ("flip_mean", "ghosting_error", "steady_error"),
            ("framebuffer_bytes", "bandwidth_bytes"),
            "framebuffer_bytes",
            per_pixel_memory=True,
            temporal=True,
            steady_against="ssaa8",
            group="aa",
        ),
        Family(
            "soft",
            "soft shadows",
            ("soft_visibility", "light_fraction"),
            ("visibility_mae", "edge_band_mae"),
            ("memory_bytes", "texture_lookups_per_pixel"),
            "shadow_map_bytes",
            extremes_scene="plate",
            extremes_metric="misclassified_fraction",
        ),
        Family(
            "rtshadows",
            "ray-traced shadows, denoised",
            ("soft_visibility", "light_fraction"),
            ("visibility_mae", "flicker"),
            ("memory_bytes", "taps_per_pixel"),
            "memory_bytes",
            per_pixel_memory=True,
            temporal=True,
            # judged at steady state against the area-light truth itself (its soft group)
            steady_against="reference",
        ),
        Family(
            "alpha",
            "alpha-tested foliage",
            ("coverage",),
            ("coverage_bias", "coverage_rmse", "coverage_edge_rmse"),
            ("framebuffer_bytes", "layers_mean"),
            "framebuffer_bytes",
            coverage_channel="coverage",
            per_pixel_memory=True,
        ),
    )
}


@dataclass(frozen=True)
class Technique:
    """A registered technique: its parameter dataclass and entry point.

    ``family``: a key of :data:`FAMILIES`: ``shadow`` (visibility outputs, scored on
    receivers), ``aa`` (colour and coverage outputs, scored against the reference image),
    ``taa`` (colour over a frame sequence, with the temporal metrics) or ``soft``
    (``soft_visibility`` and ``light_fraction`` under an area light, scored against the soft
    truth) or ``rtshadows`` (the same channels traced at one ray a pixel and denoised over
    frames, judged at steady state against the area-light truth) or ``alpha`` (a shipped
    alpha-test rule's ``coverage`` of alpha-tested cards against the cut-out truth)."""

    name: str
    description: str
    references: tuple[str, ...]
    params: type
    runner: object
    lights: tuple[str, ...]
    family: str = "shadow"
    #: the report group of its fronts when the family has no shared one (None: itself)
    front: str | None = None


#: Light kinds the anti-aliasing models accept (they shade with any light).
_ALL_LIGHTS = ("directional", "spot", "point")

TECHNIQUES: dict[str, Technique] = {
    t.name: t
    for t in (
        Technique(
            "shadow-map",
            "one shadow map (six cube faces for a point light) fit to the scene bounds or "
            "the view frustum; orthographic for directional, perspective for spot lights",
            (
                "L. Williams, Casting curved shadows on curved surfaces, SIGGRAPH 1978, "
                "doi:10.1145/965139.807402",
                "D. Scherzer, M. Wimmer, W. Purgathofer, A Survey of Real-Time Hard Shadow "
                "Mapping Methods, CGF 30(1) 2011, doi:10.1111/j.1467-8659.2010.01841.x",
            ),
            shadow_map.ShadowMapParams,
            shadow_map.run,
            shadow_map.LIGHTS,
            front="shadow maps",
        ),
        Technique(
            "csm",
            "cascaded shadow maps: uniform/log/practical/manual splits, frustum-slice or "
            "stable (sphere, texel-snapped) fits, selection by depth or projection, blend band",
            (
                "F. Zhang, H. Sun, L. Xu, L. K. Lun, Parallel-Split Shadow Maps for Large-scale "
                "Virtual Environments, VRCIA 2006, doi:10.1145/1128923.1128975",
                "W. Engel, Cascaded Shadow Maps, ShaderX5, 2006",
                "M. Pettineo, TheRealMJP/Shadows (A Sampling of Shadow Techniques), 2013",
                "NVIDIA Falcor, CSM render pass",
            ),
            csm.CsmParams,
            csm.run,
            csm.LIGHTS,
            front="shadow maps",
        ),
        Technique(
            "sdsm",
            "sample distribution shadow maps: min/max depth reduction, log/histogram/"
            "adaptive-log/K-means partitions, tight light-space bounds; current-frame depth "
            "or a CPU readback k frames late",
            (
                "A. Lauritzen, M. Salvi, A. Lefohn, Sample Distribution Shadow Maps, I3D 2011, "
                "doi:10.1145/1944745.1944761",
                "Intel Corporation, Sample Distribution Shadow Maps DX11 sample",
            ),
            sdsm.SdsmParams,
            sdsm.run,
            sdsm.LIGHTS,
            front="shadow maps",
        ),
        Technique(
            "pcss",
            "percentage-closer soft shadows on one shadow map: blocker search over a "
            "light-size-scaled disk, penumbra (z_r - z_b) L / z_b, PCF over it; presets "
            "nvidia (16/16 Poisson, the light's width as the disk radius) and hdrp (24/16 "
            "Fibonacci spiral, per-pixel rotation, HDRP's fitted softness mapping)",
            (
                "R. Fernando, Percentage-closer soft shadows, SIGGRAPH 2005 Sketches, "
                "doi:10.1145/1187112.1187153",
                "L. Bavoil, Integrating Realistic Soft Shadows into Your Game Engine, NVIDIA "
                "whitepaper, 2008",
                "Unity Technologies, HDRP 10.10.1 HDPCSS.hlsl / HDShadowSampling.hlsl / "
                "HDAdditionalLightData.cs",
            ),
            pcss.PcssParams,
            pcss.run,
            pcss.LIGHTS,
            "soft",
        ),
        Technique(
            "msm",
            "moment shadow map: four moments of depth (16-bit optimized quantization or "
            "float32), box blur, Hamburger 4MSM reconstruction with a moment bias",
            ("C. Peters, R. Klein, Moment Shadow Mapping, I3D 2015, doi:10.1145/2699276.2699277",),
            msm.MsmParams,
            msm.run,
            msm.LIGHTS,
            front="shadow maps",
        ),
        Technique(
            "izb",
            "irregular z-buffer: receivers listed in a light-space grid, occluders "
            "conservatively rasterized and tested against exact shadow volumes; samples=32 "
            "is FTIZB (32 tangent-plane points, 32-bit mask); cascades split the grid by depth",
            (
                "C. Wyman, R. Hoetzlein, A. Lefohn, Frustum-Traced Raster Shadows: Revisiting "
                "Irregular Z-Buffers, I3D 2015, doi:10.1145/2699276.2699282",
                "G. S. Johnson, J. Lee, C. A. Burns, W. R. Mark, The irregular Z-buffer, "
                "ACM TOG 24(4) 2005, doi:10.1145/1095878.1095889",
            ),
            izb.IzbParams,
            izb.run,
            ("directional", "spot"),
        ),
        Technique(
            "coherent-shadow-map",
            "coherent shadow maps: N precomputed orthographic depth maps over the bounding "
            "sphere, ids along a Hilbert curve over (phi, cos theta); lookup direction -> id "
            "texture -> matrix -> depth test; lossless run compression ratios per ordering",
            (
                "T. Ritschel, T. Grosch, J. Kautz, S. Mueller, Interactive Illumination with "
                "Coherent Shadow Maps, EGSR 2007, doi:10.2312/EGWR/EGSR07/061-072",
            ),
            coherent.CoherentParams,
            coherent.run,
            ("directional", "point"),
        ),
        # anti-aliasing family (issue 9): colour and coverage, scored against the reference
        Technique(
            "noaa",
            "no anti-aliasing: one sample at each pixel centre, shaded there",
            ("F. C. Crow, The aliasing problem in computer-generated shaded images, CACM 1977",),
            noaa.NoAAParams,
            noaa.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "ssaa",
            "supersampling: N standard or ordered-grid samples per pixel, every one shaded, "
            "box or wide resolve",
            ("T. Akenine-Moller et al., Real-Time Rendering, 4th ed., 2018, section 5.4",),
            ssaa.SsaaParams,
            ssaa.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "msaa",
            "multisampling: N standard sample positions (coverage + depth), one shade per "
            "primitive and pixel at the centre (or centroid), box or wide resolve",
            (
                "K. Akeley, Reality Engine graphics, SIGGRAPH 1993, doi:10.1145/166117.166131",
                "Khronos, Vulkan specification, standard sample locations",
            ),
            msaa.MsaaParams,
            msaa.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "acaa",
            "accumulative AA: N-sample depth prepass, shading pass with LEQUAL and additive "
            "blending weighted by post-depth coverage into one colour (float or RGBA8); "
            "coplanar surfaces tie and count twice",
            (
                "E. Enderton, E. Lum, C. Rouet, O. Kouznetsov, Accumulative anti-aliasing, "
                "NVIDIA (HPG 2015 poster; GameWorks BlendedAA sample)",
                "C. Wyman, High-quality rasterization (NVIDIA slides), 2015",
            ),
            acaa.AcaaParams,
            acaa.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "agaa",
            "aggregate G-buffer AA: N-sample depth+normal prepass, K <= 2 aggregates a pixel "
            "by clustering, coverage-weighted material accumulation, one shade per aggregate "
            "(Toksvig-filtered normal)",
            (
                "C. Crassin, M. McGuire, K. Fatahalian, A. Lefohn, Aggregate G-Buffer "
                "Anti-Aliasing, I3D 2015, doi:10.1145/2699276.2699285",
                "M. Toksvig, Mipmapping normal maps, JGT 10(3) 2005",
            ),
            agaa.AgaaParams,
            agaa.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "fxaa",
            "FXAA 3.11 quality path on the one-sample image (luma in gamma space)",
            ("T. Lottes, FXAA 3.11 (Fxaa3_11.h), NVIDIA, 2011",),
            fxaa_model.FxaaParams,
            fxaa_model.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "smaa",
            "SMAA 1x/T2x/S2x/4x (SMAA.hlsl): luma/colour/depth edges, orthogonal and diagonal "
            "pattern searches, area-texture weights, neighbourhood blending, in display space",
            (
                "J. Jimenez, J. I. Echevarria, T. Sousa, D. Gutierrez, SMAA: Enhanced Subpixel "
                "Morphological Antialiasing, CGF 31(2) 2012, doi:10.1111/j.1467-8659.2012.03014.x",
                "J. Jimenez et al., SMAA.hlsl, AreaTex.py, SearchTex.py (iryoku/smaa), 2013",
            ),
            smaa_model.SmaaParams,
            smaa_model.run,
            _ALL_LIGHTS,
            "aa",
        ),
        Technique(
            "taa",
            "temporal AA: one jittered sample a pixel a frame; history reprojected with the "
            "model's own motion vectors, rectified (clamp / AABB clip / variance clip) and "
            "blended; presets ue4, inside, hdrp, filament",
            (
                "B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014",
                "L. J. F. Pedersen, Temporal Reprojection Anti-Aliasing in INSIDE, GDC 2016",
                "M. Salvi, An Excursion in Temporal Supersampling, GDC 2016",
                "L. Yang, S. Liu, M. Salvi, A Survey of Temporal Antialiasing Techniques, "
                "CGF 39(2) 2020, doi:10.1111/cgf.14018",
            ),
            taa.TaaParams,
            taa.run,
            _ALL_LIGHTS,
            "taa",
        ),
        # ray-traced shadows at one ray a pixel, denoised over frames (issue 46)
        Technique(
            "rtshadows-none",
            "one shadow ray a pixel (AMD's cone rays for a sun, a point on a rectangle light), "
            "not denoised: what an integration that skips its denoiser shows",
            ("AMD FidelityFX-SDK v1.1.4, samples/hybridshadows (traceshadows.hlsl)",),
            rtshadows.NoParams,
            rtshadows.make_runner("rtshadows-none", "none"),
            rtshadows.LIGHTS,
            "rtshadows",
        ),
        Technique(
            "rtshadows-ffx",
            "one ray a pixel denoised by AMD's FidelityFX shadow denoiser: 8x4 ray masks, tile "
            "classification, 17x17 moments, temporal clamp, three a-trous passes, remap",
            ("AMD FidelityFX-SDK v1.1.4, sdk/include/FidelityFX/gpu/denoiser",),
            rtshadows.NoParams,
            rtshadows.make_runner("rtshadows-ffx", "ffx"),
            rtshadows.LIGHTS,
            "rtshadows",
        ),
        Technique(
            "rtshadows-svgf",
            "one ray a pixel denoised by SVGF as Falcor ships it (reprojection with history "
            "length, moments, 4 a-trous iterations, feedback tap 1)",
            (
                "C. Schied et al., Spatiotemporal Variance-Guided Filtering, HPG 2017, "
                "doi:10.1145/3105762.3105770",
                "NVIDIA Falcor eb540f6, Source/RenderPasses/SVGFPass",
            ),
            SvgfParams,
            rtshadows.make_runner("rtshadows-svgf", "svgf"),
            rtshadows.LIGHTS,
            "rtshadows",
        ),
        Technique(
            "rtshadows-asvgf",
            "SVGF with A-SVGF's gradient samples (one a 3x3 stratum re-tracing the previous "
            "frame's ray) and history rejection by the filtered temporal gradient",
            (
                "C. Schied, C. Peters, C. Dachsbacher, Gradient Estimation for Real-Time "
                "Adaptive Temporal Filtering, HPG 2018, doi:10.1145/3233301",
            ),
            SvgfParams,
            rtshadows.make_runner("rtshadows-asvgf", "asvgf"),
            rtshadows.LIGHTS,
            "rtshadows",
        ),
        Technique(
            "rtshadows-sigma",
            "one ray a pixel with NRD's penumbra input, denoised by a SIGMA-class model: 16x16 "
            "tiles, blur radius from hit distance, two blurs, short stabilisation",
            ("NVIDIA-RTX/NRD a822d87 (SIGMA settings and shader constants)",),
            rtshadows.NoParams,
            rtshadows.make_runner("rtshadows-sigma", "sigma"),
            rtshadows.LIGHTS,
            "rtshadows",
        ),
        # alpha-tested foliage (issue 44): the engines' cutout rules, scored on coverage
        # against the alpha-tested truth (glTF MASK)
        Technique(
            "alpha-test",
            "the plain alpha test (glTF MASK, three.js alphaTest): a fragment shaded at the "
            "pixel centre with trilinear mips keeps its MSAA samples where alpha >= cutoff",
            (
                "Khronos, glTF 2.0 specification, 3.9.6 Alpha Coverage",
                "mrdoob/three.js alphatest_fragment.glsl.js",
            ),
            alpha.AlphaParams,
            alpha.make_runner("alpha-test"),
            _ALL_LIGHTS,
            "alpha",
        ),
        Technique(
            "alpha-threejs-a2c",
            "three.js alpha-to-coverage: smoothstep(cutoff, cutoff + fwidth(a), a) of the "
            "samples, discarded at 0",
            ("mrdoob/three.js alphatest_fragment.glsl.js (alphaToCoverage)",),
            alpha.AlphaParams,
            alpha.make_runner("alpha-threejs-a2c"),
            _ALL_LIGHTS,
            "alpha",
        ),
        Technique(
            "alpha-filament-a2c",
            "Filament's masked alpha-to-coverage centred on maskThreshold 0.4: "
            "(a - t) / fwidth(a) + 1/2 of the samples, discarded at or under t",
            ("google/filament 24a7bc2 shaders/src/surface_main.fs (applyAlphaMask)",),
            alpha.FilamentAlphaParams,
            alpha.make_runner("alpha-filament-a2c"),
            _ALL_LIGHTS,
            "alpha",
        ),
        Technique(
            "alpha-hashed",
            "hashed alpha test as three.js ships it (alphaHash, ALPHA_HASH_SCALE 0.05): kept "
            "where alpha >= a hashed threshold stable in object space",
            (
                "C. Wyman, M. McGuire, Hashed Alpha Testing, I3D 2017, doi:10.1145/3023368.3023370",
                "mrdoob/three.js 80c40c4 alphahash_pars_fragment.glsl.js",
            ),
            alpha.AlphaParams,
            alpha.make_runner("alpha-hashed"),
            _ALL_LIGHTS,
            "alpha",
        ),
    )
}


def _technique(name: str) -> Technique:
    if name not in TECHNIQUES:
        raise ModelError(f"unknown technique {name!r}; choose one of {', '.join(TECHNIQUES)}")
    return TECHNIQUES[name]


def family(name: str) -> Family:
    """The :class:`Family` record of a family name or of a registered technique's name.

    Raises
    ------
    ModelError
        Neither a family nor a technique (lists the families).
    """
    if name in FAMILIES:
        return FAMILIES[name]
    if name in TECHNIQUES:
        return FAMILIES[TECHNIQUES[name].family]
    raise ModelError(f"unknown technique family {name!r}; choose one of {', '.join(FAMILIES)}")


def front_group(technique: str) -> str:
    """The report group whose fronts compare ``technique``: its family's shared group, else
    the technique's ``front`` (the three shadow maps), else the technique itself."""
    t = _technique(technique)
    return FAMILIES[t.family].title or t.front or t.name


def family_of(technique: str) -> str:
    """The family of a registered technique: a key of :data:`FAMILIES` (``shadow``, ``aa``,
    ``taa``, ``soft``, ``rtshadows`` or ``alpha``).

    Raises
    ------
    ModelError
        Unknown technique (lists the registered ones).
    """
    return _technique(technique).family


def list_techniques() -> list[dict]:
    """Every technique with its description, references, family (``family``, the channels
    it is ``scored_on``, whether it is ``temporal``) and parameter records.

    Each parameter record: ``name``, ``default``, ``type`` (bool, int, float, str, floats),
    ``choices`` (or None), ``range`` (``[lo, hi]`` or None), ``source`` and ``help``.
    """
    return [
        {
            "name": t.name,
            "description": t.description,
            "references": list(t.references),
            "lights": list(t.lights),
            "family": t.family,
            "scored_on": list(FAMILIES[t.family].channels),
            "temporal": FAMILIES[t.family].temporal,
            "params": params.describe(t.params),
        }
        for t in TECHNIQUES.values()
    ]


def parse_params(technique: str, pairs: list[str]) -> dict:
    """Typed, validated values from ``"key=value"`` strings (for ``--set``).

    Raises
    ------
    ModelError
        Unknown technique (lists them), unknown parameter (lists the valid ones), or a value
        of the wrong type, range or choice (says what was expected).
    """
    t = _technique(technique)
    return params.parse_pairs(t.name, t.params, list(pairs))


def run(technique: str, scene, **values):
    """Run a technique on a loaded scene (its current camera frame and light).

    Parameters
    ----------
    technique : a name of :data:`TECHNIQUES`.
    scene : :class:`scenes.LoadedScene`.
    **values : parameter values (Python types; see :func:`list_techniques`).

    Returns
    -------
    ModelResult
        ``outputs`` (``visibility``, ``cascade``, ``texels_per_pixel``, ``resolution_error``,
        ``uncovered``: ``(H, W)`` float32), ``cost``, ``diagnostics``, ``params``,
        ``wall_seconds``.
    """
    t = _technique(technique)
    p = params.make(t.name, t.params, values)
    if scene.light.kind not in t.lights:
        raise ModelError(
            f"{t.name} needs a {' or '.join(t.lights)} light; the scene's light is a "
            f"{scene.light.kind} light (use shadow-map)"
        )
    return t.runner(scene, p)
