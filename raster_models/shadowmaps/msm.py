"""Moment shadow mapping: one shadow map (as ``shadow-map``) stored as four moments of depth,
box blurred, and reconstructed with the Hamburger 4MSM bound (:mod:`.msm_filter`).

Defaults: 16-bit UNORM moments with the paper's optimized quantization (64 bits a texel)
and a moment bias ``alpha`` of 6e-5, the paper's value for 16-bit moments as implementations
report it (its body was not available here: unverified; 3e-5 is the value of Peters et al.
2017, with a different bias target); ``float32`` moments (128 bits) take TheRealMJP/Shadows'
3e-6.

References
----------
.. [1] C. Peters, R. Klein, "Moment Shadow Mapping", I3D 2015. DOI: 10.1145/2699276.2699277
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

from .. import params as _params
from ..gbuffer import trace_gbuffer
from ..params import param
from .engine import execute
from .msm_filter import DEPTHS, MSM_FORMATS
from .shadow_map import LIGHTS, ShadowMapParams, build

__all__ = ["FORMAT_BIAS", "LIGHTS", "NAME", "MsmParams", "run"]

NAME = "msm"

#: Moment bias per storage format when ``moment_bias`` is -1.
FORMAT_BIAS = {"unorm16": 6e-5, "float32": 3e-6}


@dataclass(frozen=True)
class MsmParams(ShadowMapParams):
    """Parameters of ``msm`` (map placement and depth format as ``shadow-map``)."""

    filter: str = param(
        "msm",
        source="this technique's filter",
        help="msm (four moments, Hamburger 4MSM)",
        choices=("msm",),
    )
    msm_format: str = param(
        "unorm16",
        source="Peters and Klein 2015: 64 bits a texel, 16-bit optimized quantization",
        help="moment storage: unorm16 (optimized quantization) or float32",
        choices=MSM_FORMATS,
    )
    moment_depth: str = param(
        "stored",
        source="Peters and Klein 2015 (the map's depth in [0, 1])",
        help="depth the moments are taken of: stored (the map's; hyperbolic for spot and "
        "point maps) or linear (light-view distance between near and far)",
        choices=DEPTHS,
    )
    moment_bias: float = param(
        -1.0,
        source="unorm16: 6e-5, Peters and Klein 2015's 16-bit value as implementations report "
        "it (paper body unavailable here: unverified; 3e-5 goes with Peters et al. 2017's "
        "other bias target); float32: 3e-6, TheRealMJP/Shadows@338290a AppSettings.cs:381 "
        "(MSMMomentBias 0.003 x 0.001, Mesh.hlsl:499)",
        help="alpha of b' = (1 - alpha) b + alpha (0.5, 0.5, 0.5, 0.5) (-1 = the format's: "
        "6e-5 for unorm16, 3e-6 for float32)",
        lo=-1.0,
        hi=0.5,
    )


def run(scene, params: MsmParams | None = None, **kwargs):
    """Run ``msm`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, MsmParams, kwargs)
    used = p
    if p.moment_bias < 0:
        used = dataclasses.replace(p, moment_bias=FORMAT_BIAS[p.msm_format])
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, used)
    setup.diagnostics["moment_bias"] = used.moment_bias
    return execute(NAME, scene, gbuf, setup, used, _params.as_dict(p), t0)
