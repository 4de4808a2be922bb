"""Supersampling (SSAA): every sample shaded where it lies.

``ssaa`` traces and shades each of ``N`` sub-samples per pixel (standard multisample
positions or an ordered grid) with the oracle's own per-sample path
(:func:`scenes.backend.raycast.trace_film_dr`: shading at the hit, exact shadow ray) and resolves
them; with many samples it converges to the oracle's box-filtered reference.
:func:`supersample` is also ``noaa``'s frame (:mod:`.noaa`: one sample at the pixel centre).

References
----------
F. C. Crow, The aliasing problem in computer-generated shaded images, CACM 20(11) 1977,
doi:10.1145/359863.359869.
T. Akenine-Moller et al., Real-Time Rendering, 4th ed., 2018, section 5.4 (supersampling,
ordered and rotated grids).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from . import resolve as _resolve
from . import samples as _samples
from .common import COLOR_FORMATS, DEPTH_FORMATS, ResolveParams, package
from .trace import sample_colors

__all__ = ["SsaaParams", "run", "supersample"]


@dataclass(frozen=True)
class SsaaParams(ResolveParams):
    """Parameters of :func:`run`."""

    samples: int = _params.param(
        4,
        source="4x: the common SSAA setting (Real-Time Rendering 4th ed., 5.4)",
        help="samples per pixel (standard: 1, 2, 4, 8, 16; ordered-grid: 1..64)",
        lo=1,
        hi=64,
    )
    pattern: str = _params.param(
        "standard",
        source="Vulkan/D3D standard sample locations",
        help="sample positions: standard (rotated, as MSAA) or ordered-grid (m x k cells)",
        choices=_samples.PATTERNS,
    )

    def check(self, technique: str) -> None:
        if self.pattern == "standard":
            _samples.check_standard_count(technique, self.samples, why="with pattern=standard")


def supersample(name: str, scene, p, offsets, *, t0: float):
    """Every sample at ``offsets`` ((N, 2), in the pixel, y down) traced, shaded with an
    exact shadow ray and resolved with ``p``'s filter (box without one); the packaged
    :class:`raster_models.result.ModelResult` of technique ``name``, timed from ``t0``."""
    w, h = scene.width, scene.height
    n = len(offsets)
    res, rays = sample_colors(scene, offsets)
    resolve = getattr(p, "resolve", "box")
    color = _resolve.resolve(
        res["color"],
        offsets,
        w,
        h,
        resolve,
        inverse_luminance=getattr(p, "inverse_luminance", False),
    )
    valid = res["valid"]
    n_pix = w * h
    events = np.count_nonzero(valid, axis=1)
    cb, db = COLOR_FORMATS["rgba8"], DEPTH_FORMATS["D32F"]
    return package(
        name,
        scene,
        p,
        color=color,
        coverage=events / n,
        offsets=offsets,
        events=events,
        extra_outputs={},
        samples=n,
        buffers={"color": n_pix * n * cb, "depth": n_pix * n * db},
        resolve_target_bytes=n_pix * cb,
        geometry_passes=1,
        samples_tested=n_pix * n,
        bandwidth_bytes=n_pix * n * 2 * db + int(valid.sum()) * cb + n_pix * n * cb + n_pix * cb,
        shadow_rays=rays,
        diagnostics={"sample_positions": np.asarray(offsets).tolist()},
        t0=t0,
    )


def run(scene, params: SsaaParams | None = None, **kwargs):
    """Run ``ssaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make("ssaa", SsaaParams, kwargs)
    return supersample("ssaa", scene, p, _samples.positions(p.samples, p.pattern), t0=t0)
