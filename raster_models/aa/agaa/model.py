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
   attributes at the shading position (pixel centre on its plane, as :mod:`.msaa`) to the
   aggregate of each sample it owns, weighted by those samples: albedo, shading normal,
   position. Each aggregate's average albedo and position, and its *unnormalized* average
   normal, are shaded once (:func:`._trace.shade_points` with ``filtered_normal``: diffuse
   with the normal's length as the Lambert average, Toksvig's factor on the specular
   exponent); the exact shadow ray starts at the aggregate's average position.
4. The pixel is the coverage-weighted sum of its aggregates (sky samples add 0).

With ``K`` at least the number of distinct surfaces in every pixel each aggregate holds one
surface and the result equals :mod:`.msaa`; with more surfaces (foliage) albedo/normal
correlation is lost and shadows are tested at a blended position.

With exact shadows the whole frame runs on the Dr.Jit side (:mod:`._agaa_dr`, per launch,
per-pixel results copied back); with a shadow technique the aggregates are copied to NumPy
for its visibility (:func:`_run_numpy`). Both compute the same bytes (tested).

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

import numpy as np

from ... import params as _params
from ...errors import ModelError
from .. import samples as _samples
from ..common import ShadowParams, check_shadows, package, shadow_visibility
from ..fragments import fragments_from_prepass, sample_film_positions, shading_positions
from ..trace import fragment_attributes, shade_points, trace_samples
from . import kernels as _agaa_dr

__all__ = ["AGGREGATE_BYTES", "NORMAL_FORMATS", "AgaaParams", "cluster", "quantize_normals", "run"]

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


def quantize_normals(n: np.ndarray, fmt: str) -> np.ndarray:
    """Unit normals ``(..., 3)`` as stored in ``fmt`` and read back (float32, as a shader
    reads them)."""
    f32 = np.float32
    n = np.asarray(n, f32)
    if fmt == "rgba16f":
        return n.astype(np.float16).astype(f32)
    if fmt == "rgb10a2":
        q = np.floor(np.clip(n * f32(0.5) + f32(0.5), f32(0), f32(1)) * f32(1023) + f32(0.5))
        return q * f32(2 / 1023) - f32(1)
    if fmt == "oct16":
        l1 = np.sum(np.abs(n), axis=-1, keepdims=True)
        p = n / np.where(l1 > 0, l1, 1.0)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
        u = np.where(z < 0, (1 - np.abs(y)) * sx, x)
        v = np.where(z < 0, (1 - np.abs(x)) * sy, y)
        u = np.round(np.clip(u, -1, 1) * 32767.0) / 32767.0
        v = np.round(np.clip(v, -1, 1) * 32767.0) / 32767.0
        zz = 1.0 - np.abs(u) - np.abs(v)
        t = np.maximum(-zz, 0.0)
        u = u - np.where(u >= 0, t, -t)
        v = v - np.where(v >= 0, t, -t)
        out = np.stack([u, v, zz], axis=-1)
        return (out / np.linalg.norm(out, axis=-1, keepdims=True)).astype(f32)
    raise ModelError(f"unknown normal format {fmt!r}")


def _distance(z_a, n_a, z_b, n_b, z_mean, weight):
    """Sample distances: ``z_a``, ``n_a`` are ``(P, N)``, ``(P, N, 3)``; ``z_b``, ``n_b`` one
    reference per pixel, ``(P, 1)``, ``(P, 3)``."""
    cos = np.einsum("pnc,pc->pn", n_a, n_b)
    return weight * np.abs(z_a - z_b) / z_mean + (1.0 - cos)


#: Pixels per clustering block (keeps the temporaries cache-sized).
CLUSTER_CHUNK = 1 << 15


def cluster(valid, depth, normal, k: int, threshold: float, depth_weight: float):
    """Aggregate index ``(P, N)`` of every sample (-1: sky) by the rule in the module doc.

    The NumPy reference of the rule: :func:`run` clusters on the Dr.Jit side
    (:func:`._pixel_dr.aggregate_of`, tested equal sample for sample). Distances are
    evaluated in float32, the precision of the G-buffer they are read from, in blocks of
    :data:`CLUSTER_CHUNK` pixels.
    """
    v = np.asarray(valid, bool)
    out = np.empty(v.shape, np.int8)
    for start in range(0, len(v), CLUSTER_CHUNK):
        sl = slice(start, start + CLUSTER_CHUNK)
        out[sl] = _cluster_block(v[sl], depth[sl], normal[sl], k, threshold, depth_weight)
    return out


def _cluster_block(v, depth, normal, k, threshold, depth_weight):
    f32 = np.float32
    vf = v.astype(f32)
    z = np.asarray(depth, f32) * vf
    nrm = np.asarray(normal, f32)
    cnt = np.maximum(vf.sum(axis=1), f32(1))
    z_mean = z.sum(axis=1) / cnt
    z_mean = np.where(z_mean > 0, z_mean, f32(1))[:, None]
    n_mean = np.einsum("pn,pnc->pc", vf, nrm) / cnt[:, None]
    w = f32(depth_weight)
    low = f32(-np.inf)
    d_mean = _distance(z, nrm, z_mean, n_mean, z_mean, w)
    seed1 = np.argmax(np.where(v, d_mean, low), axis=1)
    take = np.arange(len(v))
    d1 = _distance(z, nrm, z[take, seed1][:, None], nrm[take, seed1], z_mean, w)
    seed2 = np.argmax(np.where(v, d1, low), axis=1)
    d2 = _distance(z, nrm, z[take, seed2][:, None], nrm[take, seed2], z_mean, w)
    split = (k >= 2) & (d1[take, seed2] > threshold)
    agg = np.where(split[:, None] & (d2 < d1), 1, 0)
    return np.where(v, agg, -1)


def _segment_sums(rows: np.ndarray, first: np.ndarray) -> np.ndarray:
    """``np.add.reduceat(rows, first, axis=0)`` for increasing ``first`` (``first[0] = 0``),
    computed by ``reduceat`` on the segments of more than one row only (most hold one: their
    sum is the row), so the additions are reduceat's own."""
    sums = rows[first]
    if len(rows) == len(first):
        return sums
    size = np.diff(np.append(first, len(rows)))
    multi = np.flatnonzero(size > 1)
    take = np.repeat(first[multi], size[multi]) + (
        np.arange(int(size[multi].sum()))
        - np.repeat(np.cumsum(size[multi]) - size[multi], size[multi])
    )
    start = np.cumsum(size[multi]) - size[multi]
    sums[multi] = np.add.reduceat(rows[take], start, axis=0)
    return sums


def _run_numpy(scene, p: AgaaParams, offsets):
    """The frame on the NumPy side (any shadow technique): per-pixel colour ``(P, 3)``,
    coverage, aggregates, fragments and shadow rays. :func:`._agaa_dr.render` computes the
    same bytes for exact shadows without the round trips."""
    n, k = p.samples, p.aggregates
    w, h = scene.width, scene.height
    n_pix = w * h
    clustering = (k, p.threshold, p.depth_weight, p.normal_format)
    buf = trace_samples(scene, offsets, group=True, cluster=clustering, keep=("valid",))
    valid = buf["valid"]
    agg = buf["aggregate"]
    frags = fragments_from_prepass(buf, n)
    sx, sy = sample_film_positions(frags, offsets, w)
    cx, cy = shading_positions(frags, offsets, w, False, n)
    attrs = fragment_attributes(scene, sx, sy, cx, cy)
    # material accumulation: one entry per (fragment, aggregate) pair, weighted by the
    # samples it owns (pairs found on the Dr.Jit side)
    pr = np.flatnonzero(buf["pair_rep"].ravel())
    e_slot = (pr // n) * k + agg.ravel()[pr]
    order = np.argsort(e_slot, kind="stable")
    pr, e_slot = pr[order], e_slot[order]
    e_f = buf["of"].ravel()[pr]
    e_w = buf["pair_count"].ravel()[pr].astype(np.float64)
    first = np.flatnonzero(np.r_[True, e_slot[1:] != e_slot[:-1]]) if len(e_slot) else e_slot
    slots = e_slot[first]
    weight = np.add.reduceat(e_w, first)

    keys = ("albedo", "normal", "position", "to_eye", "geo_normal")
    table = np.concatenate([np.asarray(attrs[key], np.float32) for key in keys], axis=1)
    # float32 sums of at most N samples, as a GPU's aggregate accumulation
    sums = _segment_sums(table[e_f] * e_w.astype(np.float32)[:, None], first)
    means = sums / weight.astype(np.float32)[:, None]
    agg_attrs = {key: means[:, 3 * i : 3 * i + 3] for i, key in enumerate(keys)}
    g = agg_attrs["geo_normal"]
    g_len = np.linalg.norm(g, axis=1, keepdims=True)
    agg_attrs["geo_normal"] = np.where(
        g_len > 1e-6, g / np.maximum(g_len, 1e-30), agg_attrs["normal"]
    )
    e = agg_attrs["to_eye"]
    agg_attrs["to_eye"] = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
    agg_attrs["offset"] = np.maximum.reduceat(np.asarray(attrs["offset"], np.float64)[e_f], first)
    agg_attrs["valid"] = np.ones(len(slots), bool)
    view = scene.camera
    agg_attrs["depth"] = (agg_attrs["position"] - view.position) @ view.forward
    vis = shadow_visibility(scene, agg_attrs, p.shadows)
    rgb, rays = shade_points(scene, agg_attrs, visibility=vis, filtered_normal=True)
    contrib = rgb.astype(np.float64) * (weight / n)[:, None]
    pix = slots // k
    color = np.empty((n_pix, 3), np.float32)  # the output's float32, cast per channel
    for c in range(3):
        color[:, c] = np.bincount(pix, weights=contrib[:, c], minlength=n_pix)
    n_agg = np.bincount(pix, minlength=n_pix)
    coverage = np.count_nonzero(valid, axis=1) / n
    return color, coverage, n_agg, frags.per_pixel(n_pix), rays


def run(scene, params: AgaaParams | None = None, **kwargs):
    """Run ``agaa`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, AgaaParams, kwargs)
    check_shadows(scene, p.shadows)
    offsets = _samples.positions(p.samples)
    n, k = p.samples, p.aggregates
    w, h = scene.width, scene.height
    n_pix = w * h
    if p.shadows == "exact":
        res = _agaa_dr.render(
            scene,
            offsets,
            k=k,
            threshold=p.threshold,
            depth_weight=p.depth_weight,
            fmt=p.normal_format,
        )
        color, n_agg, surfaces = res["color"], res["aggregates"], res["surfaces"]
        coverage = res["covered"] / n
        rays = res["shadow_rays"]
    else:
        color, coverage, n_agg, surfaces, rays = _run_numpy(scene, p, offsets)
    n_frag = int(surfaces.sum())
    nb = NORMAL_FORMATS[p.normal_format]
    return package(
        NAME,
        scene,
        p,
        color=color.reshape(h, w, 3),
        coverage=coverage,
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
