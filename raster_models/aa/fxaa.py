"""The ``fxaa`` technique: the FXAA 3.11 filter (:mod:`.fxaa_filter`) on the tone-mapped,
gamma-encoded one-sample image, as engines run it.

The 1x image is ``noaa``'s (:mod:`.noaa`: one sample at each pixel centre, the oracle's
shading and exact shadow rays). FXAA runs after tone mapping on the display image, where its
thresholds are defined (fractions of a [0, 1] luma): the linear HDR image goes through the
project's one tone-mapping pipeline (:func:`scenes.base.display.tonemap`: exposure, ``tone_mapper``
(ACES by default, the scoring's), clip to [0, 1], sRGB encoding), with the exposure that maps
the image's own log-average luminance over lit pixels to ``exposure_key`` (Reinhard's
auto-exposure, :func:`scenes.base.display.exposure_from_reference` applied to the model's image:
an engine sees its own frame, not the reference). FXAA then filters the gamma-encoded LDR
image with its luma ``dot(rgb, (0.299, 0.587, 0.114))`` of the encoded values in alpha (FXAA
3.11's gamma-space set-up, ``encoding="gamma"``); every value it blends lies in [0, 1].

Outputs: ``color_display``, FXAA's output (display-encoded LDR sRGB, what reaches the screen),
``fxaa_input`` its input, and ``color``, the linear radiance that the tone-mapping pipeline
maps to ``color_display`` (:func:`scenes.base.display.tonemap_inverse` at the same exposure and
curve; pixels FXAA leaves alone keep their exact radiance). Scoring tone-maps ``color`` and
the reference with one pipeline, the reference's exposure and the ACES curve
(``tone_mapping`` in ``metrics.json``), so the scored candidate is FXAA's display output
exactly when the model's exposure equals the reference's (``diagnostics["tone_mapping"]``
records the model's). They differ by what separates a 1-sample image from a pixel-averaged
one: on ``hdr-edge`` (80x45, 16-spp reference) 2.563 against 2.420 stops, so the pixels FXAA
changed are scored 0.14 stops darker in exposed radiance than FXAA displayed them; pixels it
leaves alone are scored exactly as ``noaa``'s. Radiance above the clip level is lost where
FXAA blends (its output is LDR), as on a GPU.

References
----------
T. Lottes, FXAA 3.11 (``Fxaa3_11.h``), NVIDIA, 2011 (luma of gamma-space colour in alpha).
E. Reinhard et al., Photographic tone reproduction for digital images, SIGGRAPH 2002,
doi:10.1145/566654.566575.
K. Narkowicz, ACES filmic tone mapping curve, 2016 (the pipeline's default curve).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...scenes.base.display import TONE_MAPPERS, exposure_from_reference, tonemap, tonemap_inverse
from .. import params as _params
from .common import package
from .fxaa_filter import FXAA_PRESETS, fxaa
from .trace import sample_colors

__all__ = ["FxaaParams", "display_fxaa", "run"]

NAME = "fxaa"


@dataclass(frozen=True)
class FxaaParams:
    """Parameters of :func:`run`."""

    subpix: float = _params.param(
        0.75,
        source="FXAA 3.11 default fxaaQualitySubpix",
        help="sub-pixel AA amount",
        lo=0.0,
        hi=1.0,
    )
    edge_threshold: float = _params.param(
        0.166,
        source="FXAA 3.11 default fxaaQualityEdgeThreshold",
        help="minimum local contrast relative to the local maximum luma",
        lo=1e-6,
        hi=1.0,
    )
    edge_threshold_min: float = _params.param(
        0.0833,
        source="FXAA 3.11 default fxaaQualityEdgeThresholdMin",
        help="minimum absolute local contrast (skips dark areas)",
        lo=0.0,
        hi=1.0,
    )
    preset: int = _params.param(
        12,
        source="FXAA 3.11 default FXAA_QUALITY__PRESET",
        help="quality preset (edge-search steps): " + ", ".join(map(str, FXAA_PRESETS)),
        lo=10,
        hi=39,
    )
    exposure_key: float = _params.param(
        0.18,
        source="Reinhard et al. 2002 normal key (the oracle's tone-mapping exposure)",
        help="middle grey the image's log-average luminance is mapped to before FXAA",
        lo=1e-3,
        hi=0.99,
    )
    tone_mapper: str = _params.param(
        "aces",
        source="scenes.base.display: the project's one pipeline (ACES, the scoring's curve)",
        help="tone-mapping curve before FXAA: aces, reinhard or clip",
        choices=TONE_MAPPERS,
    )

    def check(self, technique: str) -> None:
        from ..errors import ModelError

        if self.preset not in FXAA_PRESETS:
            raise ModelError(
                f"{technique}: parameter preset must be one of "
                f"{', '.join(map(str, FXAA_PRESETS))}, got {self.preset}"
            )


def display_fxaa(rgb: np.ndarray, *, exposure: float, tone_mapper: str, **fxaa_kw) -> dict:
    """FXAA 3.11 in display space: tone map the linear image ``rgb`` (``exposure`` stops,
    ``tone_mapper``, clip, sRGB encode), filter the gamma-encoded result, and map it back.

    Returns a dict: ``input`` (display image FXAA reads, in [0, 1]), ``display`` (FXAA's
    output, LDR sRGB), ``changed`` ((H, W) bool) and ``linear`` (``rgb`` where unchanged,
    else the radiance the pipeline maps to ``display``).
    """
    rgb = np.asarray(rgb, np.float32)
    src = tonemap(rgb, exposure=exposure, method=tone_mapper)
    out = fxaa(src, encoding="gamma", **fxaa_kw)
    changed = np.any(out != src, axis=2)
    linear = rgb.copy()
    back = tonemap_inverse(out[changed], exposure=exposure, method=tone_mapper)
    linear[changed] = back.astype(np.float32)
    return {"input": src, "display": out, "changed": changed, "linear": linear}


def run(scene, params: FxaaParams | None = None, **kwargs):
    """Run ``fxaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, FxaaParams, kwargs)
    w, h = scene.width, scene.height
    res, rays = sample_colors(scene, np.array([[0.5, 0.5]]))
    img = res["color"].reshape(h, w, 3).astype(np.float32)
    exposure = exposure_from_reference(img, key=p.exposure_key)
    fx = display_fxaa(
        img,
        exposure=exposure,
        tone_mapper=p.tone_mapper,
        subpix=p.subpix,
        edge_threshold=p.edge_threshold,
        edge_threshold_min=p.edge_threshold_min,
        preset=p.preset,
    )
    changed = fx["changed"]
    valid = res["valid"].reshape(h, w)
    n_pix = w * h
    result = package(
        NAME,
        scene,
        p,
        color=fx["linear"],
        coverage=valid.astype(np.float32),
        offsets=np.array([[0.5, 0.5]]),
        events=valid.astype(np.int64),
        extra_outputs={"fxaa_changed": changed},
        samples=1,
        buffers={"color": n_pix * 4, "depth": n_pix * 4},
        resolve_target_bytes=n_pix * 4,
        geometry_passes=1,
        samples_tested=n_pix,
        # scene pass (depth r/w, colour write) + FXAA pass: 9 luma taps + up to 2 x steps
        # edge-end taps + 1 colour tap, bilinear (4 texels), one write
        bandwidth_bytes=n_pix * (2 * 4 + 4) + n_pix * 4 * (9 + 1) + n_pix * 4,
        shadow_rays=rays,
        diagnostics={
            "tone_mapping": {
                "exposure_stops": exposure,
                "tone_mapper": p.tone_mapper,
                "exposure_key": p.exposure_key,
                "encoding": "sRGB (IEC 61966-2-1), clipped to [0, 1]",
            },
            "pixels_changed": int(changed.sum()),
        },
        t0=t0,
    )
    result.outputs["color_display"] = fx["display"]
    result.outputs["fxaa_input"] = fx["input"]
    return result
