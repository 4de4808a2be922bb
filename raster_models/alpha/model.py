"""A rasterizer's alpha-tested coverage under a shipped rule, sampled where the hardware
samples.

Per pixel, a ray through each of the ``N`` standard sample positions (MSAA; ``N = 1``: the
pixel centre) finds the nearest triangle (the rasterizer's inside and depth tests). Its
fragment is shaded once, at the pixel centre on the triangle's plane (attributes
extrapolated, :mod:`.fragments`): the texture coordinates there and at the two neighbouring
pixel centres of the quad give the level of detail (OpenGL 4.6 8.14.1) and ``fwidth`` of the
alpha; the alpha is ``baseColorFactor.a`` times the trilinear lookup of the mask's mip chain
(``mips="box"`` or ``"coverage"``, :mod:`scenes.shading.alpha_mips`). The rule
(:mod:`.rules`) discards the fragment or gives its alpha-to-coverage value, which keeps the
first ``floor(value N + 1/2)`` samples. A sample whose fragment does not keep it looks
further along its ray (the next fragment behind it in depth order), up to ``max_layers``
fragments. A mask that reads vertex colour alpha (glTF ``COLOR_0``) multiplies it in, as
interpolated at the pixel centre and its neighbours.

Returns per pixel ``coverage`` (fraction of the ``N`` samples on a kept fragment) and
``layers`` (the most fragments a sample of the pixel passed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scenes.backend.alpha_hit import MAX_ALPHA_LAYERS, PASS_OFFSET_MESH
from ...scenes.shading.alpha import AlphaTable
from ...scenes.shading.alpha_mips import box_mips, coverage_mips, mip_level, sample_mips
from ..aa.samples import STANDARD_POSITIONS
from ..errors import ModelError
from .fragments import MeshTable, plane_attributes
from .rules import ALPHA_HASH_SCALE, RULES, a2c_samples, apply_rule

__all__ = ["AlphaRasterParams", "alpha_raster"]

MIPS = ("box", "coverage")


@dataclass(frozen=True)
class AlphaRasterParams:
    """``rule`` (a key of :data:`.rules.RULES`), ``samples`` (MSAA count, a standard pattern),
    ``mips`` (``box`` or ``coverage``), ``cutoff`` (None: each material's own),
    ``hash_scale`` (three.js ALPHA_HASH_SCALE 0.05), ``max_layers``."""

    rule: str = "test"
    samples: int = 4
    mips: str = "box"
    cutoff: float | None = None
    hash_scale: float = ALPHA_HASH_SCALE
    max_layers: int = MAX_ALPHA_LAYERS

    def __post_init__(self):
        if self.rule not in RULES:
            raise ModelError(f"rule must be one of {', '.join(RULES)}; got {self.rule!r}")
        if self.samples not in STANDARD_POSITIONS:
            raise ModelError(
                f"samples must be one of {sorted(STANDARD_POSITIONS)}; got {self.samples!r}"
            )
        if self.mips not in MIPS:
            raise ModelError(f"mips must be one of {', '.join(MIPS)}; got {self.mips!r}")


class _Chains:
    """Per mask: its mip chain, texture size, factor and cutoff."""

    def __init__(self, table: AlphaTable, params: AlphaRasterParams):
        self.items = []
        for m in table.masks:  # materials, not pixels
            cut = m.cutoff if params.cutoff is None else params.cutoff
            t = m.texture
            va = m.vertex_alpha
            if t is None:
                self.items.append((None, 1, 1, m.factor, cut, "repeat", "repeat", False, va))
                continue
            levels = box_mips(t.alpha) if params.mips == "box" else coverage_mips(t.alpha, cut)
            h, w = t.alpha.shape
            self.items.append((levels, w, h, m.factor, cut, t.wrap_s, t.wrap_t, t.nearest, va))

    def alpha(self, k, uv_c, uv_x, uv_y):
        """Alpha of mask ``k`` at the pixel centre and its two neighbours (one level of
        detail for the quad), and the mask's cutoff; ``uv_*`` (N, 3): texture coordinates
        and the interpolated vertex alpha (multiplied in where the mask reads it)."""
        levels, w, h, factor, cut, ws, wt, near, va = self.items[k]
        out = [np.full(len(uv_c), float(factor)) for _ in range(3)]
        if levels is not None:
            du_x, dv_x = (uv_x[:, :2] - uv_c[:, :2]).T
            du_y, dv_y = (uv_y[:, :2] - uv_c[:, :2]).T
            lam = mip_level(du_x, dv_x, du_y, dv_y, width=w, height=h)
            out = [
                o
                * sample_mips(
                    levels, uv[:, 0], uv[:, 1], lam, wrap_s=ws, wrap_t=wt, mag_nearest=near
                )
                for o, uv in zip(out, (uv_c, uv_x, uv_y), strict=True)
            ]
        if va:
            out = [o * uv[:, 2] for o, uv in zip(out, (uv_c, uv_x, uv_y), strict=True)]
        return out[0], out[1], out[2], cut


def _trace(mi, dr, scene, registry, o, d, tmax):
    """Closest hits of NumPy rays on ``scene``: valid, t, position, normal, shape, prim."""
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(np.ascontiguousarray(o[:, i], np.float32)) for i in range(3))),
        mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, i], np.float32)) for i in range(3))),
    )
    ray.maxt = mi.Float(np.ascontiguousarray(tmax, np.float32))
    si = scene.ray_intersect(ray, mi.RayFlags.Minimal, False)
    valid = np.array(si.is_valid())
    reg = np.array(dr.reinterpret_array(mi.UInt32, si.shape)).astype(np.int64)
    shape = np.where(valid, registry[np.minimum(reg, len(registry) - 1)], -1)
    return (
        valid,
        np.array(si.t, np.float64),
        np.array(si.p, np.float64).T,
        np.array(si.n, np.float64).T,
        shape,
        np.array(si.prim_index).astype(np.int64),
    )


def _fragment_keeps(chains, table, meshes, camera, params, where, shape, prim):
    """Whether the fragments of triangles ``prim`` of ``shape`` keep their samples (bool),
    for alpha-tested hits at ``where = (px, py, sample)`` (pixel and sample indices)."""
    px, py, sample = where
    mask = table.shape_mask[shape]
    tri_p, tri_uv = meshes.triangles(shape, prim)
    centre = [camera.rays(px + dx, py + dy) for dx, dy in ((0.5, 0.5), (1.5, 0.5), (0.5, 1.5))]
    att = [plane_attributes(tri_p, tri_uv, o, d) for o, d, _ in centre]
    keeps = np.zeros(len(shape), bool)
    for k in np.unique(mask):  # materials, not fragments
        sel = mask == k
        a_c, a_x, a_y, cut = chains.alpha(k, *(uv[sel] for _, uv in att))
        value, discarded = apply_rule(
            params.rule,
            a_c,
            cutoff=cut,
            fwidth_a=np.abs(a_x - a_c) + np.abs(a_y - a_c),
            position=att[0][0][sel],
            dpdx=att[1][0][sel] - att[0][0][sel],
            dpdy=att[2][0][sel] - att[0][0][sel],
            hash_scale=params.hash_scale,
        )
        keeps[sel] = ~discarded & (sample[sel] < a2c_samples(value, params.samples))
    return keeps


def alpha_raster(mi_scene, table: AlphaTable, camera, params: AlphaRasterParams) -> dict:
    """Per-pixel ``coverage`` ((H, W) float32) and ``layers`` ((H, W) int32) of the scene's
    alpha-tested rasterization under ``params`` (see the module text); ``camera`` a
    :class:`scenes.camera.Camera` (``rays(x, y)``)."""
    import drjit as dr
    import mitsuba as mi

    shapes = mi_scene.shapes()
    reg = [int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in shapes]
    registry = np.full(max(reg) + 2, -1, np.int64)
    registry[reg] = np.arange(len(shapes))
    meshes = MeshTable(mi, shapes)
    chains = _Chains(table, params)
    h, w = camera.height, camera.width
    pos = np.asarray(STANDARD_POSITIONS[params.samples])
    n = params.samples
    grid = np.meshgrid(np.arange(h), np.arange(w), np.arange(n), indexing="ij")
    py, px, s = (a.ravel() for a in grid)
    o, d, tmax = camera.rays(px + pos[s, 0], py + pos[s, 1])
    o, d, tmax = np.asarray(o, np.float64), np.asarray(d, np.float64), np.asarray(tmax, np.float64)
    kept = np.zeros(len(px), bool)
    layers = np.zeros(len(px), np.int32)
    pending = np.arange(len(px))
    for _ in range(params.max_layers + 1):  # layers of fragments, not pixels
        if not len(pending):
            break
        hit = _trace(mi, dr, mi_scene, registry, o[pending], d[pending], tmax[pending])
        valid, t, p, ng, shape, prim = hit
        idx, shape, prim = pending[valid], shape[valid], prim[valid]
        p, ng, t = p[valid], ng[valid], t[valid]
        tested = table.shape_mask[shape] >= 0
        keep = ~tested
        if np.any(tested):
            j = idx[tested]
            where = (px[j], py[j], s[j])
            keep[tested] = _fragment_keeps(
                chains, table, meshes, camera, params, where, shape[tested], prim[tested]
            )
        kept[idx[keep]] = True
        go = ~keep & (layers[idx] < params.max_layers)
        nxt = idx[go]
        side = np.where(np.einsum("ij,ij->i", ng[go], d[nxt]) >= 0, 1.0, -1.0)
        scale = 1.0 + np.einsum("ij,ij->i", np.abs(ng[go]), np.abs(p[go]))
        o[nxt] = p[go] + ng[go] * (side * scale * PASS_OFFSET_MESH)[:, None]
        tmax[nxt] = np.maximum(tmax[nxt] - t[go], 0.0)
        layers[nxt] += 1
        pending = nxt
    coverage = kept.reshape(h, w, n).mean(axis=2).astype(np.float32)
    return {"coverage": coverage, "layers": layers.reshape(h, w, n).max(axis=2)}
