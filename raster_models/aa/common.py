"""What every anti-aliasing model shares: resolve and shadow parameters, the optional shadow
technique, the fragment shading of the multisample models, and the packaged result (outputs,
cost record, diagnostics).

Cost record (the technique's own GPU budget, not the model's run time):

- ``framebuffer_bytes`` and ``framebuffer_bytes_by_buffer`` (``color``, ``depth``,
  ``normal``, ``aggregates``): the multisampled (or accumulation) buffers at this
  resolution, per-sample buffers ``N`` times; the 1x resolve/display target is not counted
  (``resolve_target_bytes``), as in the framebuffer figures of the NVIDIA slides;
- ``samples``, ``width``, ``height``;
- ``shading_events_mean`` and ``shading_events_histogram`` (pixels with 0, 1, 2, ...
  shading events: pixel-shader invocations, i.e. fragments, aggregates or samples shaded);
- ``geometry_passes`` (depth prepass, shading or accumulation passes), ``samples_tested``
  (sub-samples given an inside and depth test, all passes), ``shadow_rays``;
- ``bandwidth_bytes``: an estimate of framebuffer traffic: every sample test of a pass reads
  and (in a prepass) writes its depth, every shading event writes its colour to each sample
  it owns (MSAA) or blends once (ACAA, read + write), the resolve reads every colour sample
  and writes one pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import params as _params
from ..errors import ModelError
from ..result import ModelResult, model_result
from ..shadowmaps import SHADOW_TECHNIQUES, supported_lights, visibility_at
from . import resolve as _resolve
from .fragments import Fragments, sample_film_positions, shading_positions
from .trace import fragment_attributes, shade_points, trace_samples

__all__ = [
    "COLOR_FORMATS",
    "DEPTH_FORMATS",
    "ResolveParams",
    "ShadowParams",
    "check_shadows",
    "package",
    "shade_fragments",
]

#: Bytes per colour sample of each colour format.
COLOR_FORMATS = {"rgba8": 4, "rgba16f": 8, "rgba32f": 16}
#: Bytes per depth sample (D24 is stored as D24S8).
DEPTH_FORMATS = {"D24": 4, "D32F": 4}
#: Shadow techniques a colour model can take its visibility from instead of exact rays.
SHADOW_CHOICES = ("exact", *SHADOW_TECHNIQUES)


@dataclass(frozen=True)
class ShadowParams:
    shadows: str = _params.param(
        "exact",
        source="issue 9: exact shadow rays, so AA error is not mixed with shadow-map error",
        help="light visibility at each shading point: exact (the oracle's shadow ray) or a "
        "shadow technique with its default parameters (shadow-map, csm, sdsm)",
        choices=SHADOW_CHOICES,
    )


@dataclass(frozen=True)
class ResolveParams:
    resolve: str = _params.param(
        "box",
        source="D3D ResolveSubresource / glBlitFramebuffer: box average in linear",
        help="resolve filter: box (own samples) or a wide separable filter over the "
        "neighbours' samples (triangle r=1, gaussian sigma=0.5 r=2, blackman-harris, "
        "mitchell, catmull-rom r=2; MJP MSAAFilter)",
        choices=_resolve.FILTERS,
    )
    inverse_luminance: bool = _params.param(
        False,
        source="off: hardware resolve; on: Karis 2014 / MJP MSAAFilter option",
        help="divide each sample's resolve weight by 1 + its luminance",
    )


def check_shadows(scene, shadows: str) -> None:
    """Refuse a shadow technique the scene's light does not support (before any work)."""
    if shadows == "exact":
        return
    lights = supported_lights(shadows)
    if scene.light.kind not in lights:
        raise ModelError(
            f"shadows={shadows} needs a {' or '.join(lights)} light; the scene's light "
            f"is a {scene.light.kind} light"
        )


def shadow_visibility(scene, attrs: dict, shadows: str):
    """Visibility at shading points from a shadow technique (None for ``exact``)."""
    if shadows == "exact":
        return None
    return visibility_at(
        scene,
        shadows,
        position=attrs["position"],
        normal=attrs["normal"],
        geo_normal=attrs["geo_normal"],
        depth=attrs["depth"],
        valid=attrs["valid"],
    )


def shade_fragments(scene, frags: Fragments, offsets, *, centroid: bool, shadows: str):
    """Attributes and colour of every fragment, shaded once at its shading position."""
    w = scene.width
    n = len(offsets)
    sx, sy = sample_film_positions(frags, offsets, w)
    cx, cy = shading_positions(frags, offsets, w, centroid, n)
    attrs = fragment_attributes(scene, sx, sy, cx, cy)
    vis = shadow_visibility(scene, attrs, shadows)
    rgb, rays = shade_points(scene, attrs, visibility=vis)
    return attrs, rgb, rays


def histogram(events: np.ndarray) -> list[int]:
    """Pixels with 0, 1, 2, ... shading events."""
    return [int(c) for c in np.bincount(np.asarray(events, np.int64).ravel())]


def front_coverage(scene, offsets) -> np.ndarray:
    """``(P,)`` fraction of each pixel's samples (``offsets``, as :func:`.trace.trace_samples`
    takes them) whose nearest surface is the shape seen through the pixel centre, the sky
    counting as one: the coverage of the pixel's front-most primitive.

    ``coverage`` (samples on any geometry) is 1 everywhere on a scene with a backdrop; this one
    measures every silhouette, against the sky or against another surface. The same rule as
    the reference's ``front_coverage`` (:mod:`oracle.reference.coverage`): the nearest hit of
    each sample is what a depth test keeps, so it is the sample-count coverage of that shape
    after the depth test, for every sample pattern. On a silhouette against the sky it is the
    geometry coverage where the centre sees geometry and one minus it where the centre sees
    sky: the same absolute errors.
    """
    centre = trace_samples(scene, np.array([[0.5, 0.5]]), keep=("shape",))["shape"][:, 0]
    shapes = trace_samples(scene, offsets, keep=("shape",))["shape"]
    return np.count_nonzero(shapes == centre[:, None], axis=1) / shapes.shape[1]


def package(
    name: str,
    scene,
    params,
    *,
    color: np.ndarray,
    coverage: np.ndarray,
    offsets: np.ndarray,
    events: np.ndarray,
    extra_outputs: dict,
    samples: int,
    buffers: dict,
    resolve_target_bytes: int,
    geometry_passes: int,
    samples_tested: int,
    bandwidth_bytes: int,
    shadow_rays: int,
    diagnostics: dict,
    t0: float,
) -> ModelResult:
    """A :class:`ModelResult` with the AA output channels and cost record; ``offsets``: the
    sample positions, for ``front_coverage`` (:func:`front_coverage`)."""
    h, w = scene.height, scene.width
    events = np.asarray(events).reshape(h, w)
    by_buffer = {k: int(buffers.get(k, 0)) for k in ("color", "depth", "normal", "aggregates")}
    outputs = {
        "color": np.asarray(color, np.float32).reshape(h, w, 3),
        "coverage": np.asarray(coverage, np.float32).reshape(h, w),
        "front_coverage": front_coverage(scene, offsets).astype(np.float32).reshape(h, w),
        "shading_events": events.astype(np.float32),
    }
    for k, v in extra_outputs.items():
        outputs[k] = np.asarray(v, np.float32).reshape(h, w)
    cost = {
        "framebuffer_bytes": int(sum(by_buffer.values())),
        "framebuffer_bytes_by_buffer": by_buffer,
        "resolve_target_bytes": int(resolve_target_bytes),
        "samples": int(samples),
        "width": int(w),
        "height": int(h),
        "shading_events_mean": float(events.mean()),
        "shading_events_histogram": histogram(events),
        "geometry_passes": int(geometry_passes),
        "samples_tested": int(samples_tested),
        "bandwidth_bytes": int(bandwidth_bytes),
        "shadow_rays": int(shadow_rays),
    }
    return model_result(
        name,
        scene,
        outputs=outputs,
        cost=cost,
        diagnostics=diagnostics,
        params=_params.as_dict(params),
        t0=t0,
    )
