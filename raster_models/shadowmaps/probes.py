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
from ..gbuffer import points_gbuffer, trace_gbuffer
from ..sensitivity import DEFAULT_OFFSET, probe_hits
from .engine import engine_conventions
from .render import render_maps
from .shade import shade
from .visibility import entry

__all__ = ["other_surface_verdicts"]


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
