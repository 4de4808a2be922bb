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
``shading_events`` (fragments per pixel). Memory (``shading="forward"``) = N x (colour +
depth) per pixel, plus the 1x resolve target.

``shading="deferred"``: deferred MSAA, the AGAA slides' baseline ("Deferred 8x (reference)",
112 MB at 1280x736, shaded "Simple/Complex" [Lauritzen 2010]). The geometry pass writes a
per-sample G-buffer; a lighting pass shades a pixel once where all its samples hold one
primitive ("simple") and every covered sample where they differ ("complex"), and resolves
into the 1x target. The G-buffer holds per sample what an AGAA aggregate holds per aggregate
(seed 001, Wyman 2015 slides, "AGAA overview": aggregates store the normal distribution,
average albedo, specular coefficient, emissive and other material information; per-sample
visibility from a Z-prepass), in the formats the ``agaa`` model uses:

========================  ===========  ========  ===================================
target                    format       bytes     holds
========================  ===========  ========  ===================================
depth                     D32F         4         depth (position from depth)
normal                    RGB10A2      4         shading normal (``agaa`` default)
albedo / specular         RGBA8        4         albedo RGB, specular coefficient A
emissive / material       RGBA8        4         emissive RGB, other material info A
========================  ===========  ========  ===================================

16 bytes per sample (:data:`DEFERRED_GBUFFER`), so ``W x H x N x 16`` bytes of G-buffer plus
the 1x RGBA8 target: 8x at 1280x736 is 120.6 MB (115.0 MiB), 124.4 MB with the target,
against the slides' 112 MB (the slides give no layout; 112 MB is 14.9 bytes per sample in
MB, 15.6 in MiB). A per-sample lit buffer is not counted (the lighting pass resolves in the
shader). The image equals forward MSAA's: the G-buffer stores each primitive's attributes
as shaded at the pixel centre (or centroid) for every sample it owns, so per-sample lighting
of a complex pixel repeats the primitive's colour; only shading events, memory and bandwidth
differ.

References
----------
K. Akeley, Reality Engine graphics, SIGGRAPH 1993, doi:10.1145/166117.166131.
Khronos, Vulkan specification, "Multisampling" (standard sample locations, sample shading).
Microsoft, Direct3D 11 rasterization rules: multisample anti-aliasing, centroid sampling.
A. Lauritzen, Deferred rendering for current and future rendering pipelines, SIGGRAPH 2010
course "Beyond programmable shading" (per-sample shading of complex pixels only).
C. Wyman, High-quality rasterization (NVIDIA slides, 2015; seed 001): deferred 8x 112 MB.
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

__all__ = [
    "DEFERRED_GBUFFER",
    "NAME",
    "MsaaParams",
    "deferred_events",
    "multisample",
    "resolve_fragments",
    "run",
    "sample_colors",
]

NAME = "msaa"
#: Deferred MSAA's per-sample G-buffer: target -> (format, bytes per sample); module docstring.
DEFERRED_GBUFFER = {
    "depth": ("D32F", 4),
    "normal": ("RGB10A2", 4),
    "albedo_specular": ("RGBA8", 4),
    "emissive_material": ("RGBA8", 4),
}


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
        help="per-sample colour format (memory accounting only; colour stays float); "
        "deferred: the 1x lit target's",
        choices=tuple(COLOR_FORMATS),
    )
    depth_format: str = _params.param(
        "D32F",
        source="NVIDIA slides' framebuffer figures (D32 depth)",
        help="per-sample depth format (memory accounting)",
        choices=tuple(DEPTH_FORMATS),
    )
    shading: str = _params.param(
        "forward",
        source="forward: hardware MSAA; deferred: the AGAA slides' 'Deferred 8x' baseline "
        "(Wyman 2015, Simple/Complex shading, Lauritzen 2010)",
        help="forward (colour + depth per sample) or deferred (per-sample 16-byte G-buffer, "
        "complex pixels shaded per sample); the image is the same",
        choices=("forward", "deferred"),
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


def deferred_events(frags, valid: np.ndarray, n: int) -> np.ndarray:
    """Shading events per pixel of Simple/Complex deferred shading: 0 without geometry, 1
    where all ``n`` samples hold one primitive, else one per covered sample."""
    covered = np.count_nonzero(valid, axis=1)
    per_pixel = frags.per_pixel(len(covered))
    simple = (per_pixel == 1) & (covered == n)
    return np.where(per_pixel == 0, 0, np.where(simple, 1, covered))


def _forward_cost(p, n_pix: int, covered: int) -> dict:
    """Buffers and bandwidth of forward MSAA: N x (colour + depth), colour writes of the
    covered samples, a depth test per sample, the resolve's read and write."""
    n, cb, db = p.samples, COLOR_FORMATS[p.color_format], DEPTH_FORMATS[p.depth_format]
    return {
        "buffers": {"color": n_pix * n * cb, "depth": n_pix * n * db},
        "bandwidth_bytes": n_pix * n * 2 * db + covered * cb + n_pix * n * cb + n_pix * cb,
    }


def _deferred_cost(p, n_pix: int, covered: int) -> dict:
    """Buffers and bandwidth of deferred MSAA (:data:`DEFERRED_GBUFFER`, depth in
    ``depth_format``): a depth test per sample, G-buffer writes of the covered samples, the
    lighting pass reading every sample of the G-buffer once, the 1x write."""
    n, cb, db = p.samples, COLOR_FORMATS[p.color_format], DEPTH_FORMATS[p.depth_format]
    attrs = sum(b for k, (_, b) in DEFERRED_GBUFFER.items() if k != "depth")
    normal = DEFERRED_GBUFFER["normal"][1]
    return {
        # the framebuffer's colour slot holds the G-buffer's colour targets
        "buffers": {
            "color": n_pix * n * (attrs - normal),
            "normal": n_pix * n * normal,
            "depth": n_pix * n * db,
        },
        "bandwidth_bytes": n_pix * n * 2 * db
        + covered * attrs
        + n_pix * n * (attrs + db)
        + n_pix * cb,
    }


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
    covered = int(valid.sum())
    deferred = p.shading == "deferred"
    if deferred:
        events = deferred_events(ms["frags"], valid, n)
        cost = _deferred_cost(p, n_pix, covered)
    else:
        events = ms["frags"].per_pixel(n_pix)
        cost = _forward_cost(p, n_pix, covered)
    cb = COLOR_FORMATS[p.color_format]
    diag = {"shading": "centroid" if p.centroid else "pixel centre", "pipeline": p.shading}
    if deferred:
        diag["gbuffer"] = {
            k: {"format": f, "bytes_per_sample": b} for k, (f, b) in DEFERRED_GBUFFER.items()
        }
        diag["gbuffer"]["depth"]["format"] = p.depth_format
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
        buffers=cost["buffers"],
        resolve_target_bytes=n_pix * cb,
        geometry_passes=1,
        samples_tested=n_pix * n,
        bandwidth_bytes=cost["bandwidth_bytes"],
        shadow_rays=ms["shadow_rays"],
        diagnostics={
            "sample_positions": offsets.tolist(),
            "fragments": len(ms["frags"]),
            **diag,
        },
        t0=t0,
    )
