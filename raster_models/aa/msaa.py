"""Multisample anti-aliasing (MSAA): N coverage/depth samples, one shade per primitive.

Per pixel, a primary ray through each of the ``N`` standard sample positions (y down, see
:mod:`.samples`) finds the nearest surface: the inside test and depth test of a rasterizer
at those points (ARCHITECTURE.md). Each (primitive, pixel) pair owning at least one visible
sample is shaded once, at the pixel centre on the primitive's plane with its attributes
extrapolated (hardware's default, even where the centre lies outside the triangle) or, with
``centroid``, at the centroid of the samples it owns (the centre when it owns them all);
its colour is written to every sample it owns. The resolve averages the samples in linear
(``box``) or applies a wide filter (:mod:`.resolve`). Shading is the oracle's, with an
exact shadow ray from each shading point unless a shadow technique is chosen.

Outputs: ``color`` (linear, (H, W, 3)), ``coverage`` (fraction of samples on geometry),
``shading_events`` (fragments per pixel). Memory = N x (colour + depth) per pixel, plus the
1x resolve target.

References
----------
K. Akeley, Reality Engine graphics, SIGGRAPH 1993, doi:10.1145/166117.166131.
Khronos, Vulkan specification, "Multisampling" (standard sample locations, sample shading).
Microsoft, Direct3D 11 rasterization rules: multisample anti-aliasing, centroid sampling.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from . import owners as _owners
from . import resolve as _resolve
from . import samples as _samples
from .common import (
    COLOR_FORMATS,
    DEPTH_FORMATS,
    ResolveParams,
    ShadowParams,
    check_shadows,
    package,
)
from .fragments import fragments_from_prepass
from .trace import trace_samples

__all__ = ["NAME", "MsaaParams", "multisample", "resolve_fragments", "run", "sample_colors"]

NAME = "msaa"


@dataclass(frozen=True)
class MsaaParams(ShadowParams, ResolveParams):
    """Parameters of :func:`run` (every field: default, source, help)."""

    samples: int = _params.param(
        8,
        source="NVIDIA HQ rasterization slides (Wyman 2015): 8x, the quality baseline",
        help="samples per pixel at the standard positions: 1, 2, 4, 8 or 16",
        lo=1,
        hi=16,
    )
    centroid: bool = _params.param(
        False,
        source="hardware default: attributes at the pixel centre (D3D/Vulkan)",
        help="shade at the centroid of the samples a primitive owns instead of the centre",
    )
    color_format: str = _params.param(
        "rgba8",
        source="NVIDIA slides' framebuffer figures (RGBA8 colour)",
        help="per-sample colour format (memory accounting only; colour stays float)",
        choices=tuple(COLOR_FORMATS),
    )
    depth_format: str = _params.param(
        "D32F",
        source="NVIDIA slides' framebuffer figures (D32 depth)",
        help="per-sample depth format (memory accounting)",
        choices=tuple(DEPTH_FORMATS),
    )

    def check(self, technique: str) -> None:
        _samples.check_standard_count(technique, self.samples)


def multisample(
    scene, offsets, *, centroid: bool, shadows: str, depth_format: str = "D32F"
) -> dict:
    """Depth prepass, fragments and their shading at ``offsets`` (shared with ACAA/AGAA).

    Samples where surfaces of several shapes store the same depth in ``depth_format`` go to
    the first drawn, as a LESS depth test keeps them (:mod:`.owners`).
    Returns a dict: ``buffer`` (:func:`trace_samples`), ``frags``, ``attrs``, ``rgb``
    (per fragment), ``shadow_rays``.
    """
    buf = trace_samples(scene, offsets, group=True, keep=("valid", "shape", "prim"))
    frags = fragments_from_prepass(buf, len(offsets))
    drawn = _owners.draw_order_owners(scene, offsets, depth_format)
    regroup, groups, subs = None, (), ()
    if drawn is not None:
        owners, groups, subs = drawn
        frags, regroup = _owners.reassign_samples(
            frags, buf["valid"], buf["shape"], buf["prim"], owners
        )
    attrs, rgb, rays = _owners.shade_owned(
        scene,
        frags,
        offsets,
        centroid=centroid,
        shadows=shadows,
        regroup=regroup,
        groups=groups,
        subs=subs,
    )
    return {"buffer": buf, "frags": frags, "attrs": attrs, "rgb": rgb, "shadow_rays": rays}


def sample_colors(frags, rgb) -> np.ndarray:
    """``(P, N, 3)`` float32 colour of every sample: its fragment's, 0 for sky."""
    # row 0: sky (0); fragment f is row f + 1 (one float32 gather)
    table = np.concatenate([np.zeros((1, 3), np.float32), np.asarray(rgb, np.float32)])
    return table[frags.of_sample + 1]


def resolve_fragments(frags, rgb, offsets, width, height, name, inverse_luminance):
    """Resolve a multisampled image held as fragments (box: per fragment, no sample array)."""
    n = len(offsets)
    if name == "box":
        color = _resolve.box_from_fragments(
            frags.pixel,
            frags.count,
            rgb,
            n,
            width * height,
            inverse_luminance=inverse_luminance,
        )
        return color.reshape(height, width, 3)
    return _resolve.resolve(
        sample_colors(frags, rgb),
        offsets,
        width,
        height,
        name,
        inverse_luminance=inverse_luminance,
    )


def run(scene, params: MsaaParams | None = None, **kwargs):
    """Run ``msaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, MsaaParams, kwargs)
    check_shadows(scene, p.shadows)
    offsets = _samples.positions(p.samples)
    ms = multisample(
        scene, offsets, centroid=p.centroid, shadows=p.shadows, depth_format=p.depth_format
    )
    w, h = scene.width, scene.height
    n = p.samples
    color = resolve_fragments(ms["frags"], ms["rgb"], offsets, w, h, p.resolve, p.inverse_luminance)
    valid = ms["buffer"]["valid"]
    n_pix = w * h
    events = ms["frags"].per_pixel(n_pix)
    cb, db = COLOR_FORMATS[p.color_format], DEPTH_FORMATS[p.depth_format]
    covered = int(valid.sum())
    return package(
        NAME,
        scene,
        p,
        color=color,
        coverage=np.count_nonzero(valid, axis=1) / n,
        offsets=offsets,
        events=events,
        extra_outputs={},
        samples=n,
        buffers={"color": n_pix * n * cb, "depth": n_pix * n * db},
        resolve_target_bytes=n_pix * cb,
        geometry_passes=1,
        samples_tested=n_pix * n,
        bandwidth_bytes=n_pix * n * 2 * db + covered * cb + n_pix * n * cb + n_pix * cb,
        shadow_rays=ms["shadow_rays"],
        diagnostics={
            "sample_positions": offsets.tolist(),
            "fragments": len(ms["frags"]),
            "shading": "centroid" if p.centroid else "pixel centre",
        },
        t0=t0,
    )
