"""The ``fxaa`` technique: the FXAA 3.11 filter (:mod:`.fxaa_filter`) on the one-sample
image.

The 1x image is ``noaa``'s (:mod:`.noaa`: one sample at each pixel centre, the oracle's
shading and exact shadow rays). FXAA runs after tone mapping, on a display-referred image
where 1 is white: the image is scaled by the exposure that maps its log-average luminance
(over non-black pixels) to the key ``exposure_key`` (Reinhard's auto-exposure, the oracle's
tone-mapping exposure rule applied to the model's own image), FXAA is applied, and the
result is scaled back. FXAA's output is a blend of input colours, so the output stays linear
radiance.

References
----------
T. Lottes, FXAA 3.11 (``Fxaa3_11.h``), NVIDIA, 2011.
E. Reinhard et al., Photographic tone reproduction for digital images, SIGGRAPH 2002,
doi:10.1145/566654.566575.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from .common import package
from .fxaa_filter import FXAA_PRESETS, fxaa
from .trace import sample_colors

__all__ = ["FxaaParams", "run"]

NAME = "fxaa"
#: Rec. 709 luminance of linear RGB, for the exposure.
_LUMA = np.array([0.2126, 0.7152, 0.0722])


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

    def check(self, technique: str) -> None:
        from ..errors import ModelError

        if self.preset not in FXAA_PRESETS:
            raise ModelError(
                f"{technique}: parameter preset must be one of "
                f"{', '.join(map(str, FXAA_PRESETS))}, got {self.preset}"
            )


def exposure_scale(rgb: np.ndarray, key: float) -> float:
    """``key / L_avg`` with ``L_avg = exp(mean(log(1e-4 + Y)))`` over pixels with ``Y > 0``."""
    y = np.asarray(rgb, np.float64) @ _LUMA
    lit = y > 0
    if not lit.any():
        return 1.0
    return float(key / np.exp(np.mean(np.log(1e-4 + y[lit]))))


def run(scene, params: FxaaParams | None = None, **kwargs):
    """Run ``fxaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, FxaaParams, kwargs)
    w, h = scene.width, scene.height
    res, rays = sample_colors(scene, np.array([[0.5, 0.5]]))
    img = res["color"].reshape(h, w, 3).astype(np.float32)
    k = exposure_scale(img, p.exposure_key)
    out = fxaa(
        img * np.float32(k),
        subpix=p.subpix,
        edge_threshold=p.edge_threshold,
        edge_threshold_min=p.edge_threshold_min,
        preset=p.preset,
    ) / np.float32(k)
    changed = np.any(out != img, axis=2)
    valid = res["valid"].reshape(h, w)
    n_pix = w * h
    return package(
        NAME,
        scene,
        p,
        color=out,
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
        diagnostics={"exposure_scale": k, "pixels_changed": int(changed.sum())},
        t0=t0,
    )
