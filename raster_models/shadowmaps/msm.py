"""Moment shadow mapping: one shadow map (as ``shadow-map``) stored as four moments of depth,
box blurred, and reconstructed with the Hamburger 4MSM bound (:mod:`.msm_filter`).

Defaults: 16-bit UNORM moments with the paper's optimized quantization (64 bits a texel)
and the moment bias ``alpha = 3e-5`` given for that quantization; ``float32`` moments (128
bits) need far less (set ``moment_bias``). The bias value is the issue's transcription of
the paper (its body was not available here: unverified).

References
----------
.. [1] C. Peters, R. Klein, "Moment Shadow Mapping", I3D 2015. DOI: 10.1145/2699276.2699277
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from .. import params as _params
from ..gbuffer import trace_gbuffer
from ..params import param
from .engine import execute
from .msm_filter import DEPTHS, MSM_FORMATS
from .shadow_map import LIGHTS, ShadowMapParams, build

__all__ = ["LIGHTS", "NAME", "MsmParams", "run"]

NAME = "msm"


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
        3e-5,
        source="Peters and Klein 2015 bias for 16-bit moments (from the issue; unverified)",
        help="alpha of b' = (1 - alpha) b + alpha (0.5, 0.5, 0.5, 0.5)",
        lo=0.0,
        hi=0.5,
    )


def run(scene, params: MsmParams | None = None, **kwargs):
    """Run ``msm`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, MsmParams, kwargs)
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, p)
    return execute(NAME, scene, gbuf, setup, p, _params.as_dict(p), t0)
