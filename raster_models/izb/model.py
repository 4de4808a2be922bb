"""Irregular z-buffer shadows (IZB) and frustum-traced IZB (FTIZB, 32 samples per pixel).

1. Build: every receiver of the G-buffer (valid, N.L > 0; sky and back-facing pixels are
   skipped) is inserted into a light-space grid of ``resolution``^2 texels fit tightly
   around the receivers (orthographic for a directional light, perspective from a spot
   light's position along its axis): one node per (texel, receiver),
   lists sorted by texel (:mod:`.lists`). ``samples=1``: the pixel-centre point.
   ``samples=32``: the 32 fixed points ``P + a dP/dx + b dP/dy`` of the pixel's footprint on
   the tangent plane (:data:`scenes.geometry.tangent32.TANGENT_POINTS_32`); the receiver is inserted
   in each texel one of its points falls in (orthographic grids: :mod:`.build`).
2. Traverse: every occluder triangle of the scene is conservatively rasterized over the grid
   (:mod:`.geometry`); each fragment walks its texel's list and tests the node's
   sample(s) against the triangle's shadow volume (three edge planes through the light
   direction, the triangle plane pushed ``epsilon`` world units away from the light).
   Triangles go in the scene's order, ``ROUND_TRIANGLES`` at a time; after each round the
   fully shadowed receivers (mask full) are removed from the lists.
3. Visibility: 1 - shadowed (1 sample), or the lit fraction of the 32-bit mask.

Outputs (``(H, W)`` float32): ``visibility`` (1 = lit; sky 1, back-facing 0, as the
oracle), ``cascade`` (grid of the pixel, -1 for non-receivers), ``list_length`` (length of
the list of the texel holding the pixel centre), ``epsilon_band`` (1 where the model lights a
sample whose exact shadow ray, from the same sample of the pixel's exact float64 hit, may
meet an occluder: inside its edge planes up to float64 rounding and beyond its plane by more
than that rounding. Lit by the epsilon (a gap below it), or by the float32 G-buffer position
lying outside an occluder's edge that the exact hit is inside (a grazing light makes that a
strip); the triangles are rasterized grown by the distance between the two, so that such a
receiver's list is tested. Outside this band the model and an exact ray differ only where
the model shadows a sample by the float32 rounding of its position at a shadow edge).

Cascaded IZB (``cascades > 1``): receivers are split by view depth with the SDSM sample's log
partitioning over ``[zmin, zmax]`` of the receivers (:func:`raster_models.splits.log_splits`),
one grid per partition fit tightly around its samples (SDSM's tight light-space bounds);
every triangle is rasterized into every grid (:mod:`.samples`, :mod:`.grids`).

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
cylinders) are tessellated as :func:`scenes.formats.export.shape_mesh` does, so their shadows
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

from .. import params as _params
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..light_frame import make_frame
from ..params import param
from ..result import ModelResult, model_result
from ..shadowmaps.fit import light_frame_for
from .geometry import (
    grown_fragments,
    onto_own_planes,
    ray_hits,
    scene_triangles,
    shadow_volumes,
    surface_triangles,
)
from .grids import Grids, build_grids
from .kernel import BAND_FLOOR, BAND_FLOOR_ON_PLANE, PairTester, vectorized
from .lists import FULL_MASK, Joins, JoinStats
from .samples import Samples, frame_samples, partitions

__all__ = ["IzbParams", "run"]

NAME = "izb"

#: Triangles per traversal round; fully shadowed receivers leave the lists between rounds.
ROUND_TRIANGLES = 256

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


def run(scene, params: IzbParams | None = None, **kwargs) -> ModelResult:
    """Run ``izb`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, IzbParams, kwargs)
    light = scene.light
    _check_light(light)
    spot = light.kind == "spot"
    gbuf = trace_gbuffer(scene)
    if spot:
        frame = make_frame(light.direction, [("world_y", (0.0, 1.0, 0.0))], light.position)
    else:
        frame = light_frame_for(light, scene.camera, p.light_up)
    position, floor_scale, hit = _receiver_positions(scene, gbuf)
    smp = frame_samples(
        gbuf,
        light,
        frame,
        samples=p.samples,
        position=position,
        floor_scale=floor_scale,
        hit=hit,
    )
    splits, part = partitions(np.take(gbuf.depth, smp.rec), p.cascades)
    grids = build_grids(smp, part, cascades=p.cascades, resolution=p.resolution)
    built = grids.lists.lengths()
    centre_len = grids.lists.length_at(grids.centre_texel)
    reach = _hit_reach(smp, frame.to_light(np.take(hit, smp.rec, axis=0)), part, grids, p)
    trav = _traverse(scene, light, frame, smp, grids, p, reach)
    outputs, fully, band = _outputs(gbuf, smp, part, trav.state, centre_len)
    cost = _cost(trav.stats, built, grids, p, n_pix=gbuf.size)
    diagnostics = {
        "light": light.to_json(),
        "light_frame": frame.to_json(),
        "projection": "perspective" if spot else "orthographic",
        "receivers": len(smp.rec),
        "fully_shadowed_receivers": fully,
        "epsilon_band_receivers": int(band.sum()),
        "nodes_removed": int(trav.stats.nodes_removed),
        "rounds": trav.rounds,
        "triangle_grids_crossing_light_plane": trav.crossing,
        "round_triangles": ROUND_TRIANGLES,
        "triangles": trav.triangles,
        "triangles_culled_edge_on": trav.culled,
        "split_depths": [float(z) for z in splits],
        "partitions": _partitions_record(grids.boxes, part, p.resolution),
    }
    return model_result(
        NAME,
        scene,
        outputs=outputs,
        cost=cost,
        diagnostics=diagnostics,
        params=_params.as_dict(p),
        t0=t0,
    )


def _receiver_positions(scene, gbuf):
    """The pixels' positions put on their own triangles' planes in float64, the epsilon
    band's floor scale of each (exact on a plane, float32 rounding elsewhere) and the exact
    hit of each receiver's pixel-centre ray on that plane (the position elsewhere), where the
    band is judged: see :func:`raster_models.izb.geometry.onto_own_planes` and
    :func:`raster_models.izb.geometry.ray_hits`."""
    tris = scene_triangles(scene)
    own = surface_triangles(scene, gbuf.shape, gbuf.prim)
    position, moved = onto_own_planes(tris, own, gbuf.position)
    hit = position.copy()
    pix = np.flatnonzero(moved & gbuf.receiver)  # the pixels the band is judged for
    o, d, _ = scene.camera.rays(pix % gbuf.width + 0.5, pix // gbuf.width + 0.5)
    hit[pix] = ray_hits(tris, own[pix], position[pix], o, d)
    return position, np.where(moved, BAND_FLOOR_ON_PLANE, BAND_FLOOR), hit


def _check_light(light) -> None:
    """Directional and spot lights only; the joins (and the orthographic 32-sample build)
    run in Dr.Jit kernels: a vectorized variant."""
    if light.kind not in ("directional", "spot"):
        raise ModelError(
            f"{NAME} needs a directional or spot light; the scene's light is a {light.kind} light"
        )
    if not vectorized():
        raise ModelError(
            f"{NAME} tests its samples against the occluders in Dr.Jit kernels and needs a "
            "vectorized Mitsuba variant (llvm_ad_rgb or cuda_ad_rgb), not scalar_rgb"
        )


@dataclass
class _Traversal:
    """What the traversal leaves: the receivers' visibility state (``shadowed`` or
    ``mask``, and ``band``), the join counters, rounds, triangle-grid pairs crossing a spot
    light's plane, and the occluder triangles kept and culled edge-on."""

    state: dict
    stats: JoinStats
    rounds: int
    crossing: int
    triangles: int
    culled: int


def _hit_reach(smp: Samples, hit_lc: np.ndarray, part: np.ndarray, grids: Grids, p: IzbParams):
    """Per grid, how far the receivers' exact hits (light frame ``hit_lc``, :func:`_receiver_
    positions`) lie from their tested positions: in texels (max-norm, doubled for the 32
    points under a spot light's perspective), and in light depth. Each triangle is
    rasterized that much larger and reaches that much deeper, so that the list of a receiver
    whose exact hit is inside a triangle it is not inside is tested for the band (0 and 0
    where every hit is its position: nothing changes)."""
    out = []
    r = p.resolution
    for c, box in enumerate(grids.boxes):  # cascades
        sel = part == c
        if box is None or not sel.any():
            out.append((0.0, 0.0))
            continue
        q, h = smp.lc[sel], hit_lc[sel]
        if smp.spot:
            q = np.column_stack([q[:, :2] / q[:, 2:], q[:, 2]])
            h = np.column_stack([h[:, :2] / h[:, 2:], h[:, 2]])
        texel = np.array([(box[1] - box[0]) / r, (box[3] - box[2]) / r])
        far = float(np.max(np.abs(h[:, :2] - q[:, :2]) / texel))
        out.append((2.0 * far if np.isfinite(far) else 0.0, float(np.abs(h[:, 2] - q[:, 2]).max())))
    return out


def _traverse(
    scene, light, frame, smp: Samples, grids: Grids, p: IzbParams, reach: list
) -> _Traversal:
    """Rounds of :data:`ROUND_TRIANGLES` occluder triangles (scene order), each rasterized
    into every grid, grown by the grid's ``reach`` (:func:`_hit_reach`), and joined with its
    lists; after a round the fully shadowed receivers leave the lists (the joins batched over
    rounds: :class:`raster_models.izb.lists.Joins`)."""
    spot = smp.spot
    tris = scene_triangles(scene)
    keep, planes = shadow_volumes(
        tris, light.direction, p.epsilon, position=light.position if spot else None
    )
    tris = tris[keep]
    tri_lc = frame.to_light(tris.reshape(-1, 3)).reshape(-1, 3, 3)
    m = len(smp.rec)
    if smp.samples == 32:
        state = {"mask": smp.init.copy(), "band": np.zeros(m, dtype=np.uint32)}
    else:
        state = {"shadowed": np.zeros(m, dtype=bool), "band": np.zeros(m, dtype=bool)}
    tester = PairTester(planes, smp.recv, node_recv=grids.lists.node_recv, epsilon=p.epsilon)
    joins = Joins(grids.lists, tester, state)
    r = p.resolution
    rounds = crossing_count = 0
    for start in range(0, len(tris), ROUND_TRIANGLES):  # rounds of triangles
        rounds += 1
        t_lc = tri_lc[start : start + ROUND_TRIANGLES]
        for c, box in enumerate(grids.boxes):  # cascades
            if box is None:
                continue
            grow, deeper = reach[c]
            idx, uv, tight = _grid_triangles(t_lc, box, (grids.zmax[c], deeper), r, spot=spot)
            crossing_count += tight[1]
            for ft, fx, exact in grown_fragments(uv, r, margin=grow):  # chunks
                joins.add(start + idx[ft], c * r * r + fx, exact & tight[0][ft])
        joins.end_round()
    joins.flush()
    stats = joins.stats
    return _Traversal(state, stats, rounds, crossing_count, int(len(keep)), int((~keep).sum()))


def _grid_triangles(t_lc: np.ndarray, box, depth: tuple, r: int, *, spot: bool):
    """Light-frame triangles ``t_lc`` ``(T, 3, 3)`` of a round in one grid: the indices of
    those that can shadow a sample or, ``depth[1]`` deeper than the samples' ``depth[0]``,
    put an exact hit in the band, their vertices in texel units ``(n, 3, 2)``, and
    ``(tight, crossing)``: whether each is of the first kind (its fragments count), and how
    many of those cross a spot light's plane (rasterized over the whole grid)."""
    x0, x1, y0, y1 = box
    zmax, deeper = depth
    # A triangle wholly farther from the light than every sample shadows none.
    zmin = t_lc[:, :, 2].min(axis=1)
    idx = np.flatnonzero(zmin <= zmax + deeper)
    if len(idx) == 0:
        return idx, np.empty((0, 3, 2)), (np.zeros(0, dtype=bool), 0)
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
    tight = zmin[idx] <= zmax
    return idx, uv, (tight, int((crossing & tight).sum()))


def _outputs(gbuf, smp: Samples, part: np.ndarray, state: dict, centre_len: np.ndarray):
    """The output images, the number of fully shadowed receivers and the receivers' epsilon
    band flags. Float32 images built directly: the values k / 32, 0/1, indices and list
    lengths round to float32 once, as they did through float64."""
    rec = smp.rec
    n_pix = gbuf.size
    f32 = np.float32
    vis = np.ones(n_pix, dtype=f32)
    vis[gbuf.valid & ~gbuf.receiver] = 0.0
    if smp.samples == 32:
        lit_bits = 32 - np.bitwise_count(state["mask"]).astype(f32)
        vis[rec] = lit_bits / f32(32.0)
        fully = int((state["mask"] == FULL_MASK).sum())
        band = (state["band"] & ~state["mask"]) != 0
    else:
        vis[rec] = np.where(state["shadowed"], 0.0, 1.0)
        fully = int(state["shadowed"].sum())
        band = state["band"] & ~state["shadowed"]
    cascade = np.full(n_pix, -1.0, dtype=f32)
    cascade[rec] = part.astype(f32)  # converted first: a faster scatter, the same values
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
    return outputs, fully, band


def _cost(stats: JoinStats, built: np.ndarray, grids: Grids, p: IzbParams, *, n_pix: int):
    """The cost record (see the module docstring): fragments, list lengths, tests, both
    cost models and the memory of the heads, nodes and visibility words."""
    r, s = p.resolution, p.samples
    f_ls = stats.fragments
    l_avg = stats.tests / f_ls if f_ls else 0.0
    l_avg_nonempty = stats.tests / stats.fragments_with_list if stats.fragments_with_list else 0.0
    n_nodes = int(len(built) and built.sum())
    word = 4 if s == 32 else 1
    memory = {
        "list_heads": 4 * r * r * p.cascades,
        "list_nodes": 8 * n_nodes,
        "visibility_mask": word * n_pix,
    }
    return {
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
        "grids": sum(1 for box in grids.boxes if box is not None),
    }


def _partitions_record(boxes: list, part: np.ndarray, r: int) -> list:
    """Per partition: its index, receivers, grid bounds and texel size (light-frame units)."""
    return [
        {
            "index": c,
            "receivers": int((part == c).sum()),
            "grid_bounds": None if box is None else [float(v) for v in box],
            "texel_size": None if box is None else [(box[1] - box[0]) / r, (box[3] - box[2]) / r],
        }
        for c, box in enumerate(boxes)
    ]


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
