"""Where a correct engine may answer otherwise than the model because its rasterizer saw
another surface: the technique's verdict at four sub-pixel probes around each pixel centre.

A pixel is *surface-defined by the engine* when a probe a quarter pixel away sees another
surface (:func:`..sensitivity.probe_hits`) **and** the technique, looked up on that surface
with the same maps, decides the other way (lit against shadowed at 0.5). Elsewhere a
surface swap would not change the engine's answer. Used by conformance scoring to name
those pixels implementation-defined instead of counting them as failures.
"""

from __future__ import annotations

import numpy as np

from .. import params as _params
from ..depth import FORMATS
from ..gbuffer import points_gbuffer, trace_gbuffer
from ..sensitivity import DEFAULT_OFFSET, probe_hits
from .engine import engine_conventions
from .render import render_maps
from .shade import shade
from .visibility import entry

__all__ = [
    "FLOAT32_REFERENCE_ULPS",
    "ROUNDING_QUANTA",
    "compare_tolerance",
    "implementation_defined",
    "other_surface_verdicts",
]

#: Quanta of the depth format within which a compare is implementation-defined: the stored
#: texel is rounded (half a quantum) and the engine's rasterizer interpolates its own depth.
ROUNDING_QUANTA = 2.0
#: float32 ulps of the reference an engine computes in 32-bit floats (matrix, divide, bias).
FLOAT32_REFERENCE_ULPS = 4.0


def other_surface_verdicts(
    scene, technique: str, values: dict, *, offset: float = DEFAULT_OFFSET
) -> dict:
    """``{"outputs", "visibility", "other_surface", "flipped"}``: the technique's output
    images and ``(H, W)`` visibility at pixel centres (as :func:`raster_models.run`), the
    pixels where a probe sees another surface, and those of them where the verdict on that
    surface differs."""
    module, cls, _ = entry(technique)
    p = _params.make(technique, cls, dict(values))
    gbuf = trace_gbuffer(scene)
    setup = module.build(scene, gbuf, p)
    gbuf, setup = engine_conventions(technique, scene, gbuf, setup, p)
    maps = render_maps(scene, setup, p)
    outputs = shade(gbuf, setup, maps, p)[0]
    centre = np.asarray(outputs["visibility"], np.float64).ravel()
    lit = centre >= 0.5
    other = np.zeros(centre.size, dtype=bool)
    flipped = np.zeros(centre.size, dtype=bool)
    for _, _, hit, differs in probe_hits(scene, gbuf, offset=offset):
        other |= differs
        idx = np.nonzero(differs)[0]
        if not len(idx):
            continue
        normal = np.asarray(hit["normal"], np.float64)[idx]
        points = points_gbuffer(
            scene,
            position=np.asarray(hit["position"], np.float64)[idx],
            normal=normal,
            geo_normal=normal,
            depth=np.asarray(hit["depth"], np.float64)[idx],
            valid=np.asarray(hit["valid"], bool)[idx],
        )
        vis = np.asarray(shade(points, setup, maps, p)[0]["visibility"], np.float64).ravel()
        flipped[idx] |= (vis >= 0.5) != lit[idx]
    h, w = scene.height, scene.width
    return {
        "outputs": outputs,
        "visibility": centre.reshape(h, w).astype(np.float32),
        "other_surface": other.reshape(h, w),
        "flipped": flipped.reshape(h, w),
    }


def compare_tolerance(fmt: str, reference) -> np.ndarray:
    """Normalized depth within which a compare of ``reference`` against a texel of ``fmt``
    is implementation-defined: :data:`ROUNDING_QUANTA` quanta of a UNORM format (one float32
    ulp of the texel for D32F) plus :data:`FLOAT32_REFERENCE_ULPS` ulps of the reference."""
    ref = np.abs(np.asarray(reference, dtype=np.float64))
    ulp = np.spacing(np.maximum(ref, 2.0**-126).astype(np.float32)).astype(np.float64)
    kind, bits = FORMATS[fmt]
    quantum = 1.0 / (2.0**bits - 1.0) if kind == "unorm" else ulp
    return ROUNDING_QUANTA * quantum + FLOAT32_REFERENCE_ULPS * ulp


def implementation_defined(
    scene, technique: str, values: dict, *, offset: float = DEFAULT_OFFSET, surfaces=True
) -> dict:
    """The technique's outputs and the receivers a correct engine may decide otherwise:
    ``{"outputs", "depth_rounding", "other_surface"}`` (``(H, W)`` bool each): compares
    decided within :func:`compare_tolerance` of a texel (from the model's
    ``compare_margin``), and pixels whose probes see another surface with another verdict
    (:func:`other_surface_verdicts`; all False with ``surfaces=False``)."""
    module, cls, _ = entry(technique)
    p = _params.make(technique, cls, dict(values))
    if surfaces:
        got = other_surface_verdicts(scene, technique, values, offset=offset)
        outputs, other = got["outputs"], got["flipped"]
    else:
        outputs = _run(scene, module, p, technique)
        other = np.zeros((scene.height, scene.width), dtype=bool)
    margin = outputs.get("compare_margin")
    if margin is None:
        rounding = np.zeros_like(other)
    else:
        # the margin is |reference - texel|: the reference is within it of the texel
        # at the largest reference (1): the widest float32 ulp of [0, 1]
        rounding = np.asarray(margin, np.float64) <= compare_tolerance(p.format, 1.0)
    return {"outputs": outputs, "depth_rounding": rounding, "other_surface": other}


def _run(scene, module, p, technique):
    gbuf = trace_gbuffer(scene)
    setup = module.build(scene, gbuf, p)
    gbuf, setup = engine_conventions(technique, scene, gbuf, setup, p)
    return shade(gbuf, setup, render_maps(scene, setup, p), p)[0]
