"""Irregular z-buffer shadows (IZB) and frustum-traced IZB (FTIZB, 32 samples per pixel).

1. Build: every receiver of the G-buffer (valid, N.L > 0; sky and back-facing pixels are
   skipped) is inserted into a light-space grid of ``resolution``^2 texels fit tightly
   around the receivers (orthographic for a directional light, perspective from a spot
   light's position along its axis): one node per (texel, receiver),
   lists sorted by texel (:mod:`._izb_lists`). ``samples=1``: the pixel-centre point.
   ``samples=32``: the 32 fixed points ``P + a dP/dx + b dP/dy`` of the pixel's footprint on
   the tangent plane (:data:`scenes.tangent32.TANGENT_POINTS_32`); the receiver is inserted
   in each texel one of its points falls in (orthographic grids: :mod:`._izb_build`).
2. Traverse: every occluder triangle of the scene is conservatively rasterized over the grid
   (:mod:`._izb_geometry`); each fragment walks its texel's list and tests the node's
   sample(s) against the triangle's shadow volume (three edge planes through the light
   direction, the triangle plane pushed ``epsilon`` world units away from the light).
   Triangles go in the scene's order, ``ROUND_TRIANGLES`` at a time; after each round the
   fully shadowed receivers (mask full) are removed from the lists.
3. Visibility: 1 - shadowed (1 sample), or the lit fraction of the 32-bit mask.

Outputs (``(H, W)`` float32): ``visibility`` (1 = lit; sky 1, back-facing 0, as the
oracle), ``cascade`` (grid of the pixel, -1 for non-receivers), ``list_length`` (length of
the list of the texel holding the pixel centre), ``epsilon_band`` (1 where a sample lies
inside an occluder's edge planes, beyond its plane by more than float32 rounding but by at
most ``epsilon``: lit by the epsilon, though an exact shadow ray could still hit the
occluder; outside this band the model and the oracle's rays differ only where float32 ray
origins round across a shadow edge).

Cascaded IZB (``cascades > 1``): receivers are split by view depth with the SDSM sample's log
partitioning over ``[zmin, zmax]`` of the receivers (:func:`._splits.log_splits`), one grid
per partition fit tightly around its samples (SDSM's tight light-space bounds); every
triangle is rasterized into every grid.

Cost record (the technique's GPU budget, after the seed slides): ``f_ls`` (light-space
fragments), ``list_length_avg`` (``L_avg``: nodes tested per fragment, so that
``f_ls * L_avg`` is the number of tests, the seed's ``O(N)``; ``list_length_avg_nonempty``
over fragments whose list was not empty), ``list_length_max`` (``L_max``: the longest list a
fragment walked, "the pixels tested by the slowest thread"), the histogram of the
built list lengths, ``sample_triangle_tests`` (fragment-node tests; ``point_tests`` counts
the 32 points of each FTIZB test), both cost models ``f_ls * L_avg`` and ``f_ls * L_max``,
and ``memory_bytes`` (heads ``4 R^2`` per grid, nodes 8 bytes: next pointer and receiver
index, a visibility word per pixel: 1 byte, or 4 for the 32-bit mask).

Not modelled: the paper's approximate insertion for 32 samples (here exact: each texel a
point falls in), back-face and z culling of occluders, the second tighter light frustum of
the public code for lists over 1024 nodes, point lights (six grids). Spot lights: the
occluders crossing the light's plane are rasterized over the whole grid; with 32 samples
each point's N.L and cone test are its own (the oracle's reference does the same), so a
pixel whose centre is outside the cone may still be partly lit. Analytic shapes (spheres,
cylinders) are tessellated as :func:`scenes.export.shape_mesh` does, so their shadows
differ from the oracle's by the tessellation.

References
----------
.. [1] C. Wyman, R. Hoetzlein, A. Lefohn, "Frustum-Traced Raster Shadows: Revisiting
   Irregular Z-Buffers", I3D 2015. DOI: 10.1145/2699276.2699282
.. [2] G. S. Johnson, J. Lee, C. A. Burns, W. R. Mark, "The irregular Z-buffer: Hardware
   acceleration for irregular data structures", ACM TOG 24(4), 2005.
   DOI: 10.1145/1095878.1095889
.. [3] A. Lauritzen, M. Salvi, A. Lefohn, "Sample Distribution Shadow Maps", I3D 2011.
   DOI: 10.1145/1944745.1944761
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from scenes.records import jsonable, provenance
from scenes.tangent32 import tangent_offsets

from .. import params as _params
from .. import splits as _splits
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..light_frame import make_frame
from ..params import param
from ..result import ModelResult
from ..shadowmaps.fit import light_frame_for
from .build import BUILD_CHUNK, Ortho32Build, grid, texel
from .geometry import conservative_fragments, scene_triangles, shadow_volumes
from .lists import FULL_MASK, JoinStats, build_lists, join, list_nodes

__all__ = ["IzbParams", "run"]

NAME = "izb"

#: Triangles per traversal round; fully shadowed receivers leave the lists between rounds.
ROUND_TRIANGLES = 256

#: Pixels per chunk of the spot light's per-point N.L and cone tests (32 points, a few
#: (n, 32, 3) temporaries: small chunks stay in cache, about 1.5x faster than 2^16).
UNLIT_CHUNK = 1 << 10

#: A triangle (texel units / R) containing the whole grid ``[0, 1]^2``: what a spot light's
#: occluder crossing the light's plane is rasterized as.
WHOLE_GRID = np.array([[-0.5, -0.5], [3.5, -0.5], [-0.5, 3.5]])

#: Samples per pixel the technique supports: the pixel centre, or FTIZB's 32 points.
SAMPLE_COUNTS = (1, 32)


@dataclass(frozen=True)
class IzbParams:
    """Parameters of ``izb``."""

    resolution: int = param(
        512,
        source="dormon/Shadows src/FTS (public FTIZB code): 512^2 light-space grid",
        help="light-space grid texels per side (per cascade)",
        lo=1,
        hi=8192,
    )
    samples: int = param(
        1,
        source="Wyman et al. 2015: 1 sample (pixel centre) or 32 (FTIZB on the tangent plane)",
        help="samples per pixel: 1 (pixel centre, equals a shadow ray) or 32 (FTIZB mask)",
        lo=1,
        hi=32,
    )
    epsilon: float = param(
        0.001,
        source="dormon/Shadows src/FTS: epsilon 0.001 world units",
        help="the triangle plane of each shadow volume is pushed this far (world units) away "
        "from the light, against self-shadowing",
        lo=0.0,
        hi=1e3,
    )
    cascades: int = param(
        1,
        source="Wyman et al. 2015 use cascaded IZBs; 1 = a single grid",
        help="number of grids, one per view-depth partition (SDSM log partitioning)",
        lo=1,
        hi=8,
    )
    light_up: str = param(
        "camera_right",
        source="Intel SDSM sample alignLightToFrustum = 1 (the grids reuse SDSM's tight "
        "light-space bounds)",
        help="directional lights: light frame up, camera_right (camera Z -> light X) or world "
        "(+Y); a spot light's grid uses world +Y",
        choices=("world", "camera_right"),
    )

    def check(self, technique: str) -> None:
        """Cross-field validation (raises :class:`ModelError`)."""
        if self.samples not in SAMPLE_COUNTS:
            raise ModelError(
                f"{technique}: parameter samples must be 1 or 32, got {self.samples!r}"
            )


def _histogram(lengths: np.ndarray) -> dict:
    """Texels per list length, in power-of-two bins (``"1"``, ``"2-3"``, ``"4-7"``, ...)."""
    if len(lengths) == 0:
        return {}
    k = np.floor(np.log2(lengths)).astype(np.int64)
    counts = np.bincount(k)
    out = {}
    for b, c in enumerate(counts.tolist()):  # bins, not samples
        lo, hi = 1 << b, (1 << (b + 1)) - 1
        out[f"{lo}" if lo == hi else f"{lo}-{hi}"] = int(c)
    return out


def _unlit_bits(light, gbuf, cand: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Spot light, 32 samples: per pixel of ``cand``, the bits of the points that face away
    from the light (N.L <= 0 with the pixel's normal) or lie outside the cone: unlit before
    any occluder, as in the oracle's tangent-plane reference."""
    out = np.empty(len(cand), dtype=np.uint32)
    pos = np.asarray(light.position, dtype=np.float64)
    axis = np.asarray(light.direction, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    cos_cut = np.cos(np.radians(light.cutoff_angle))
    bits = np.left_shift(np.uint64(1), np.arange(32, dtype=np.uint64))
    for i0 in range(0, len(cand), UNLIT_CHUNK):  # chunks of pixels
        ch = cand[i0 : i0 + UNLIT_CHUNK]
        q = (
            gbuf.position[ch, None, :]
            + gbuf.dpdx[ch, None, :] * a[:, None]
            + gbuf.dpdy[ch, None, :] * b[:, None]
        )
        wl = pos - q
        wl /= np.linalg.norm(wl, axis=-1, keepdims=True)
        ok = (np.einsum("nkj,nj->nk", wl, gbuf.normal[ch]) > 0) & (-(wl @ axis) > cos_cut)
        out[i0 : i0 + len(ch)] = ((~ok).astype(np.uint64) @ bits).astype(np.uint32)
    return out


def run(scene, params: IzbParams | None = None, **kwargs) -> ModelResult:
    """Run ``izb`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, IzbParams, kwargs)
    light = scene.light
    if light.kind not in ("directional", "spot"):
        raise ModelError(
            f"{NAME} needs a directional or spot light; the scene's light is a {light.kind} light"
        )
    spot = light.kind == "spot"
    gbuf = trace_gbuffer(scene)
    r = p.resolution
    s = p.samples
    a, b = tangent_offsets()
    if spot:
        frame = make_frame(light.direction, [("world_y", (0.0, 1.0, 0.0))], light.position)
    else:
        frame = light_frame_for(light, scene.camera, p.light_up)
    if spot and s == 32:
        cand = np.flatnonzero(gbuf.valid)
        unlit = _unlit_bits(light, gbuf, cand, a, b)
        rec, init = cand[unlit != FULL_MASK], unlit[unlit != FULL_MASK]
    else:
        rec = np.flatnonzero(gbuf.receiver)
        init = np.zeros(len(rec), dtype=np.uint32)
    m = len(rec)
    rot = frame.rotation()
    # np.take: the same rows as fancy indexing, about twice as fast on (N, 3)
    pos = np.take(gbuf.position, rec, axis=0)
    # a directional light's frame has its origin at 0: p - 0 is p, no temporary needed
    lc = frame.to_light(pos) if frame.origin.any() else pos @ rot.T
    recv = {"p": pos}
    if s == 32:
        recv.update(dpdx=np.take(gbuf.dpdx, rec, axis=0), dpdy=np.take(gbuf.dpdy, rec, axis=0))
        recv.update(a=a, b=b)
        ldx, ldy = recv["dpdx"] @ rot.T, recv["dpdy"] @ rot.T

    # ---- partitions (SDSM log over the receivers' depth range) and one grid each
    depth = np.take(gbuf.depth, rec)
    k = p.cascades
    if m:
        splits = _splits.log_splits(float(depth.min()), float(depth.max()), k)
        if k > 1:
            part = np.searchsorted(splits[1:-1], depth, side="right")
        else:  # one grid: every receiver in partition 0
            part = np.zeros(m, dtype=np.intp)
    else:
        splits, part = np.zeros(k + 1), np.zeros(0, dtype=np.int64)

    def light_pts(sel):
        """Grid x, y and light depth z ``(n, S)`` of the samples of receivers ``sel``:
        light-frame x, y (orthographic) or x / z, y / z (perspective). A spot light's
        samples that no light reaches (set in ``init``: outside the cone, possibly behind
        the light) take the place of the receiver's first lit sample: never tested, they
        must not stretch the grid or reach a texel of their own."""
        if s == 1:
            x, y, z = lc[sel, 0, None], lc[sel, 1, None], lc[sel, 2, None]
        else:
            x, y, z = (
                lc[sel, q, None] + ldx[sel, q, None] * a + ldy[sel, q, None] * b for q in range(3)
            )
        if not spot:
            return x, y, z
        if s == 32:
            ok = ((init[sel, None] >> np.arange(32, dtype=np.uint32)) & 1) == 0
            first = np.argmax(ok, axis=1)[:, None]
            x, y, z = (np.where(ok, v, np.take_along_axis(v, first, axis=1)) for v in (x, y, z))
        return x / z, y / z, z

    # Orthographic, 32 samples: bounds, centre texels and nodes by :mod:`._izb_build` (the
    # grids and the depth cull only need boxes containing each receiver's points).
    ortho32 = s == 32 and not spot
    build = Ortho32Build(lc, ldx, ldy, a, b) if ortho32 else None

    boxes: list = []
    zmax = np.full(k, -np.inf)
    nodes = []
    centre_texel = np.empty(m, dtype=np.int64)
    for c in range(k):  # cascades
        sel = np.flatnonzero(part == c) if k > 1 else np.arange(m)
        if len(sel) == 0:
            boxes.append(None)
            continue
        whole = len(sel) == m  # one grid: no gathers
        if ortho32:
            lo, hi = build.bounds(None if whole else sel)
            box = grid(lo[:2], hi[:2])
            boxes.append(box)
            zmax[c] = hi[2]
            ctex, node_texel, node_recv = build.nodes(None if whole else sel, box, r)
            if whole:
                centre_texel[:] = c * r * r + ctex
            else:
                centre_texel[sel] = c * r * r + ctex
            nodes.append((c * r * r + node_texel if c else node_texel, node_recv))
            continue
        chunks = [sel[i : i + BUILD_CHUNK] for i in range(0, len(sel), BUILD_CHUNK)]
        lcs = lc if whole else lc[sel]
        if spot:
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for ch in chunks:  # chunks of receivers
                pts = light_pts(ch)
                lo = np.minimum(lo, [v.min() for v in pts])
                hi = np.maximum(hi, [v.max() for v in pts])
        else:
            # one sample: the pixel centres (per column: an axis-0 reduction over (n, 3) is
            # several times slower)
            lo = np.array([lcs[:, q].min() for q in range(3)])
            hi = np.array([lcs[:, q].max() for q in range(3)])
        box = grid(lo[:2], hi[:2])
        boxes.append(box)
        zmax[c] = hi[2]
        cx, cy, cz = lcs[:, 0], lcs[:, 1], lcs[:, 2]
        if spot:
            # the centre may lie outside the cone (32 samples): its texel is diagnostic only
            cz = np.maximum(cz, 1e-300)
            cx, cy = cx / cz, cy / cz
        ci, cj = texel(cx, cy, box, r)
        ctex = c * r * r + cj * r + ci
        centre_texel[sel] = ctex
        if not spot:
            nodes.append((ctex, sel))  # one sample: the pixel centre is the sample
            continue
        for ch in chunks:  # chunks of receivers
            gx, gy, _ = light_pts(ch)
            i, j = texel(gx, gy, box, r)
            nodes.append(list_nodes(c * r * r + j * r + i, ch))
    lists = build_lists(nodes)
    del nodes
    built = lists.lengths()
    centre_len = lists.length_at(centre_texel)

    # ---- traversal: rounds of triangles, each rasterized into every grid and joined
    tris = scene_triangles(scene)
    keep, planes = shadow_volumes(
        tris, light.direction, p.epsilon, position=light.position if spot else None
    )
    tris = tris[keep]
    tri_lc = frame.to_light(tris.reshape(-1, 3)).reshape(-1, 3, 3)
    if s == 32:
        state = {"mask": init.copy(), "band": np.zeros(m, dtype=np.uint32)}
    else:
        state = {"shadowed": np.zeros(m, dtype=bool), "band": np.zeros(m, dtype=bool)}
    stats = JoinStats()
    rounds = 0
    crossing_count = 0
    n_dead_before = 0
    for start in range(0, len(tris), ROUND_TRIANGLES):  # rounds of triangles
        stop = min(len(tris), start + ROUND_TRIANGLES)
        rounds += 1
        for c, box in enumerate(boxes):  # cascades
            if box is None:
                continue
            x0, x1, y0, y1 = box
            t_lc = tri_lc[start:stop]
            # A triangle wholly farther from the light than every sample shadows none.
            near = t_lc[:, :, 2].min(axis=1) <= zmax[c]
            idx = np.flatnonzero(near)
            if len(idx) == 0:
                continue
            gx, gy = t_lc[idx, :, 0], t_lc[idx, :, 1]
            crossing = np.zeros(len(idx), dtype=bool)
            if spot:
                # Behind the light entirely: no shadow in front of it. Crossing the light's
                # plane: no finite projection; rasterized over the whole grid (conservative).
                z = t_lc[idx, :, 2]
                front = (z > 0).any(axis=1)
                idx, gx, gy, z = idx[front], gx[front], gy[front], z[front]
                crossing = (z <= 0).any(axis=1)
                with np.errstate(divide="ignore", invalid="ignore"):
                    gx, gy = gx / z, gy / z
            uv = np.empty((len(idx), 3, 2))
            uv[..., 0] = (gx - x0) / ((x1 - x0) / r)
            uv[..., 1] = (y1 - gy) / ((y1 - y0) / r)
            uv[crossing] = WHOLE_GRID * r
            crossing_count += int(crossing.sum())
            for ft, fx in conservative_fragments(uv, r):  # chunks
                join(
                    lists,
                    start + idx[ft],
                    c * r * r + fx,
                    planes,
                    recv,
                    state,
                    stats,
                    epsilon=p.epsilon,
                )
        dead = state["shadowed"] if s == 1 else state["mask"] == FULL_MASK
        n_dead = int(np.count_nonzero(dead))
        if n_dead > n_dead_before:  # a receiver stays dead: no new one, no node to remove
            stats.nodes_removed += lists.compact(dead)
            n_dead_before = n_dead

    # ---- outputs (float32 images built directly: the values k / 32, 0/1, indices and list
    # lengths round to float32 once, as they did through float64)
    n_pix = gbuf.size
    f32 = np.float32
    vis = np.ones(n_pix, dtype=f32)
    vis[gbuf.valid & ~gbuf.receiver] = 0.0
    if s == 32:
        lit_bits = 32 - np.bitwise_count(state["mask"]).astype(f32)
        vis[rec] = lit_bits / f32(32.0)
        fully = int((state["mask"] == FULL_MASK).sum())
    else:
        vis[rec] = np.where(state["shadowed"], 0.0, 1.0)
        fully = int(state["shadowed"].sum())
    cascade = np.full(n_pix, -1.0, dtype=f32)
    cascade[rec] = part.astype(f32)  # converted first: a faster scatter, the same values
    if s == 32:
        band = (state["band"] & ~state["mask"]) != 0
    else:
        band = state["band"] & ~state["shadowed"]
    band_img = np.zeros(n_pix, dtype=f32)
    band_img[rec] = band.astype(f32)
    list_img = np.zeros(n_pix, dtype=f32)
    list_img[rec] = centre_len.astype(f32)
    outputs = {
        "visibility": gbuf.image(vis),
        "cascade": gbuf.image(cascade),
        "list_length": gbuf.image(list_img),
        "epsilon_band": gbuf.image(band_img),
    }

    # ---- cost record and diagnostics
    f_ls = stats.fragments
    l_avg = stats.tests / f_ls if f_ls else 0.0
    l_avg_nonempty = stats.tests / stats.fragments_with_list if stats.fragments_with_list else 0.0
    n_nodes = int(len(built) and built.sum())
    word = 4 if s == 32 else 1
    grids = sum(1 for box in boxes if box is not None)
    memory = {
        "list_heads": 4 * r * r * k,
        "list_nodes": 8 * n_nodes,
        "visibility_mask": word * n_pix,
    }
    cost = {
        "samples": s,
        "f_ls": int(f_ls),
        "fragments_with_list": int(stats.fragments_with_list),
        "list_length_avg": float(l_avg),
        "list_length_avg_nonempty": float(l_avg_nonempty),
        "list_length_max": int(stats.list_max),
        "sample_triangle_tests": int(stats.tests),
        "point_tests": int(stats.tests * s),
        "cost_model_avg": float(f_ls * l_avg),
        "cost_model_max": float(f_ls * stats.list_max),
        "nodes": n_nodes,
        "built_list_length_avg": float(built.mean()) if len(built) else 0.0,
        "built_list_length_max": int(built.max()) if len(built) else 0,
        "texels_by_list_length": _histogram(built),
        "memory_bytes": int(sum(memory.values())),
        "memory_bytes_by_buffer": memory,
        "grids": int(grids),
    }
    diagnostics = {
        "light": light.to_json(),
        "light_frame": frame.to_json(),
        "projection": "perspective" if spot else "orthographic",
        "receivers": int(m),
        "fully_shadowed_receivers": fully,
        "epsilon_band_receivers": int(band.sum()),
        "nodes_removed": int(stats.nodes_removed),
        "rounds": rounds,
        "triangle_grids_crossing_light_plane": crossing_count,
        "round_triangles": ROUND_TRIANGLES,
        "triangles": int(len(keep)),
        "triangles_culled_edge_on": int((~keep).sum()),
        "split_depths": [float(z) for z in splits],
        "partitions": [
            {
                "index": c,
                "receivers": int((part == c).sum()),
                "grid_bounds": None if box is None else [float(v) for v in box],
                "texel_size": None
                if box is None
                else [(box[1] - box[0]) / r, (box[3] - box[2]) / r],
            }
            for c, box in enumerate(boxes)
        ],
        "scene": scene.provenance(),
        "provenance": provenance(),
    }
    return ModelResult(
        technique=NAME,
        outputs=outputs,
        cost=cost,
        diagnostics=jsonable(diagnostics),
        params=_params.as_dict(p),
        wall_seconds=time.perf_counter() - t0,
    )
