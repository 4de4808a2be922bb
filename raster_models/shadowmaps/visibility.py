"""Shadow-map visibility at arbitrary shading points, for models of other families (the
anti-aliasing models' ``shadows=shadow-map|csm|sdsm`` option).

The technique runs with its default parameters: its maps are placed for the scene's own
camera (SDSM reduces the camera's G-buffer, as it would in that frame), rendered, and
looked up at the given points exactly as at pixel centres (filters, biases, cascade
selection and blending), with the points' own screen derivatives.
"""

from __future__ import annotations

import numpy as np

from .. import params
from ..errors import ModelError
from ..gbuffer import points_gbuffer, trace_gbuffer
from . import csm, sdsm, shadow_map
from .render import render_maps
from .shade import shade

__all__ = ["SHADOW_TECHNIQUES", "entry", "supported_lights", "visibility_at"]

#: Technique name -> (module with ``build``, parameter dataclass, light kinds).
_MODULES = {
    shadow_map.NAME: (shadow_map, shadow_map.ShadowMapParams, shadow_map.LIGHTS),
    csm.NAME: (csm, csm.CsmParams, csm.LIGHTS),
    sdsm.NAME: (sdsm, sdsm.SdsmParams, sdsm.LIGHTS),
}

#: The shadow-map techniques :func:`visibility_at` runs.
SHADOW_TECHNIQUES = tuple(_MODULES)


def entry(technique: str):
    """``(module with build, parameter dataclass, light kinds)`` of a technique."""
    if technique not in _MODULES:
        raise ModelError(
            f"unknown shadow-map technique {technique!r}; choose one of "
            f"{', '.join(SHADOW_TECHNIQUES)}"
        )
    return _MODULES[technique]


def supported_lights(technique: str) -> tuple[str, ...]:
    """Light kinds (``directional``, ``spot``, ``point``) a shadow-map technique supports."""
    return entry(technique)[2]


def visibility_at(
    scene, technique: str, *, position, normal, geo_normal, depth, valid
) -> np.ndarray:
    """Visibility (1 = lit) of ``technique`` with default parameters at shading points.

    Parameters
    ----------
    scene : scenes.LoadedScene (current camera frame and light).
    technique : one of :data:`SHADOW_TECHNIQUES`.
    position, normal, geo_normal : ``(N, 3)`` world points, shading and geometric normals.
    depth : ``(N,)`` view depth of the points (camera units along its forward axis).
    valid : ``(N,)`` bool, False where no surface was hit.

    Returns
    -------
    ``(N,)`` float64 in [0, 1]: 1 on invalid points, 0 on points facing away from the light
    or outside a spot light's cone.

    Raises
    ------
    ModelError
        Unknown technique, or a light kind the technique does not support.
    """
    module, cls, lights = entry(technique)
    if scene.light.kind not in lights:
        raise ModelError(
            f"{technique} needs a {' or '.join(lights)} light; the scene's light is a "
            f"{scene.light.kind} light"
        )
    p = params.make(technique, cls, {})
    setup = module.build(scene, trace_gbuffer(scene), p)
    maps = render_maps(scene, setup, p)
    points = points_gbuffer(
        scene, position=position, normal=normal, geo_normal=geo_normal, depth=depth, valid=valid
    )
    outputs, _ = shade(points, setup, maps, p)
    return np.asarray(outputs["visibility"], np.float64).ravel()
