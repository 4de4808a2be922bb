"""Aggregate G-buffer anti-aliasing (AGAA): N visibility samples, K <= 2 shades a pixel.

1. Depth + normal prepass at the ``N`` standard positions (the nearest surface per sample;
   its geometric normal stored in ``normal_format``).
2. Aggregates, per pixel, by the published clustering rule: the first seed is the covered
   sample farthest from the mean of the pixel's samples, the second the sample farthest from
   the first; if their distance exceeds the threshold ``t`` (and ``K = 2``) every covered
   sample joins the nearer seed, else all form one aggregate. The distance between samples
   ``a`` and ``b`` is ``depth_weight |z_a - z_b| / z_mean + (1 - n_a . n_b)`` (view depths
   relative to the pixel's mean depth; normals from the prepass; the mean normal is the
   unnormalized average).
3. Material accumulation (a second geometry pass): every fragment (primitive, pixel) adds its
   attributes at the shading position (pixel centre on its plane, as :mod:`..msaa`) to the
   aggregate of each sample it owns, weighted by those samples: albedo, shading normal,
   position. Each aggregate's average albedo and position, and its *unnormalized* average
   normal, are shaded once (:func:`..trace.shade_dr` with ``filtered_normal``: diffuse
   with the normal's length as the Lambert average, Toksvig's factor on the specular
   exponent) and the aggregate's *filtered visibility*: the mean over its samples of the
   light visibility at each sample's own surface point (the oracle's exact shadow ray from
   the sample's hit with the mesh offset, or the shadow technique's lookup there). AGAA
   pre-filters its shading inputs and, by its authors, the shadowing ("Shadowing must be
   filtered; account for aggregate depth extent", Crassin et al. 2015 and Wyman's 2015
   NVIDIA slides); a single ray from the aggregate's mean position would start on no
   surface (behind ``stripes``' zigzag: every K = 1 pixel black).
4. The pixel is the coverage-weighted sum of its aggregates (sky samples add 0).

With ``K`` at least the number of distinct surfaces in every pixel each aggregate holds one
surface and the result equals :mod:`..msaa`; with more surfaces (foliage) albedo/normal
correlation is lost (the visibility stays each sample's own, averaged).

The whole frame runs on the Dr.Jit side (:func:`.kernels.render`, per launch, per-pixel
results copied back); with a shadow technique the samples' surface points of a launch are
copied to NumPy once for its visibility (:func:`..common.shadow_visibility`), which is then
filtered per aggregate.

Memory per pixel: N x (depth + normal) + K x aggregate (albedo RGBA8, normal RGBA16F,
depth R32F, sample mask R32UI: 20 bytes) + the 1x colour target.

References
----------
C. Crassin, M. McGuire, K. Fatahalian, A. Lefohn, Aggregate G-Buffer Anti-Aliasing, I3D 2015,
doi:10.1145/2699276.2699285 (extended: IEEE TVCG 22(10) 2016).
M. Toksvig, Mipmapping normal maps, Journal of Graphics Tools 10(3), 2005.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ... import params as _params
from .. import samples as _samples
from ..common import ShadowParams, check_shadows, package, shadow_visibility
from . import kernels

__all__ = ["AGGREGATE_BYTES", "NORMAL_FORMATS", "AgaaParams", "run"]

NAME = "agaa"
#: Bytes per stored prepass normal of each format.
NORMAL_FORMATS = {"rgba16f": 8, "rgb10a2": 4, "oct16": 4}
#: Bytes of one aggregate record (albedo RGBA8 + normal RGBA16F + depth R32F + mask R32UI).
AGGREGATE_BYTES = 20


@dataclass(frozen=True)
class AgaaParams(ShadowParams):
    """Parameters of :func:`run`."""

    samples: int = _params.param(
        8,
        source="Crassin et al. 2015: AGAA at 8 visibility samples (vs 8x MSAA)",
        help="visibility samples per pixel at the standard positions: 1, 2, 4, 8 or 16",
        lo=1,
        hi=16,
    )
    aggregates: int = _params.param(
        2,
        source="Crassin et al. 2015: 2 aggregates comparable to 8x MSAA",
        help="aggregates per pixel K (1 or 2)",
        lo=1,
        hi=2,
    )
    threshold: float = _params.param(
        0.1,
        source="unverified (TECHNIQUES.md): chosen so one surface never splits "
        "(distance 0) and a 10 % depth gap or 25 deg crease does",
        help="seed distance above which a pixel gets a second aggregate",
        lo=0.0,
        hi=10.0,
    )
    depth_weight: float = _params.param(
        1.0,
        source="unverified (TECHNIQUES.md): relative depth and (1 - cos) of normals weigh equally",
        help="weight of the relative depth difference in the sample distance",
        lo=0.0,
        hi=1e6,
    )
    normal_format: str = _params.param(
        "rgb10a2",
        source="a common G-buffer normal format (10 bits a component)",
        help="prepass normal storage: rgba16f, rgb10a2 (UNORM 10 bits) or oct16 "
        "(octahedral, 2 x 16-bit SNORM)",
        choices=tuple(NORMAL_FORMATS),
    )

    def check(self, technique: str) -> None:
        _samples.check_standard_count(technique, self.samples)


def run(scene, params: AgaaParams | None = None, **kwargs):
    """Run ``agaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, AgaaParams, kwargs)
    check_shadows(scene, p.shadows)
    offsets = _samples.positions(p.samples)
    n, k = p.samples, p.aggregates
    w, h = scene.width, scene.height
    n_pix = w * h
    visibility = None
    if p.shadows != "exact":

        def visibility(attrs):
            return shadow_visibility(scene, attrs, p.shadows)

    res = kernels.render(
        scene,
        offsets,
        k=k,
        threshold=p.threshold,
        depth_weight=p.depth_weight,
        fmt=p.normal_format,
        visibility=visibility,
    )
    color, n_agg, surfaces = res["color"], res["aggregates"], res["surfaces"]
    coverage = res["covered"] / n
    rays = res["shadow_rays"]
    n_frag = int(surfaces.sum())
    nb = NORMAL_FORMATS[p.normal_format]
    return package(
        NAME,
        scene,
        p,
        color=color.reshape(h, w, 3),
        coverage=coverage,
        offsets=offsets,
        events=n_agg,
        extra_outputs={"aggregates": n_agg, "surfaces": surfaces},
        samples=n,
        buffers={
            "depth": n_pix * n * 4,
            "normal": n_pix * n * nb,
            "aggregates": n_pix * k * AGGREGATE_BYTES,
        },
        resolve_target_bytes=n_pix * 4,
        geometry_passes=2,
        samples_tested=2 * n_pix * n,
        bandwidth_bytes=n_pix * n * (2 * 4 + nb)
        + n_pix * n * 4
        + n_frag * 2 * AGGREGATE_BYTES
        + n_pix * k * AGGREGATE_BYTES
        + n_pix * 4,
        shadow_rays=rays,
        diagnostics={
            "sample_positions": offsets.tolist(),
            "fragments": int(n_frag),
            "aggregates_total": int(n_agg.sum()),
            "pixels_split": int((n_agg > 1).sum()),
        },
        t0=t0,
    )
