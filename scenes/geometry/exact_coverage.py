"""Analytic (zero-noise) pixel coverage of triangle scenes: ``coverage_exact`` and
``front_coverage_exact``.

Every triangle of the scene (float64 from Mitsuba's float32 vertices) is clipped against the
camera's near and far planes (Mitsuba's rays run from the near to the far plane) and
projected to film pixels. Where the projections of two triangles overlap and the two do not
interpenetrate, one of them is in front over the whole overlap: for a perspective camera the
inverse ray distance ``1/s`` to a plane is an affine function of the film position, so its
sign of difference over the convex overlap is decided by the overlap's vertices (an
orthographic camera: ``s`` itself). Each triangle's visible region is its projection less the
union of the triangles in front of it (shapely 2, vectorised over all triangles and pairs);
visible regions are disjoint, and their exact areas inside each pixel
(:mod:`scenes.geometry.pixel_area`) give

- ``coverage_exact``: the area fraction of the pixel covered by any geometry;
- ``front_coverage_exact``: the area fraction whose nearest surface belongs to the shape seen
  through the pixel centre (a Mitsuba shape: a whole mesh, rectangle, sphere, ...), the sky
  counting as one: the quantity the Monte Carlo ``front_coverage`` estimates;
- ``coverage_exact_valid``: 1 where both are exact, 0 where they are not known exactly.

Not exact, hence ``valid = 0``: pixels touched by the visible part of an overlap where two
triangles interpenetrate or are coplanar (a depth tie: which one a ray tracer keeps is
rounding), and pixels within the tessellation bound of the visible silhouette of a curved
shape (sphere, cylinder, disk: tessellated here with a stated chord error, never passed off
as exact). The channels are float64 geometry rounded to float32 at the end; the area of a
triangle summed over the pixels matches its projected area to about 1e-13 relative.

References
----------
Auzinger, Wimmer, Jeschke, "Analytic Visibility on the GPU", Computer Graphics Forum 32(2),
2013. doi:10.1111/cgf.12046
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass

import numpy as np
import shapely

from .. import backend
from . import meshes as _meshes
from .coverage_edges import convex_arrays, convex_overlaps, visible_segments
from .pixel_area import (
    edge_pieces,
    pixel_area,
    segment_pieces,
    tagged_pixel_area,
    touched_pixels,
)

__all__ = [
    "ExactCoverage",
    "NotExact",
    "OverBudget",
    "estimate_cost",
    "TriangleSet",
    "exact_coverage",
    "exact_coverage_of",
    "scene_triangle_set",
]

#: Projected triangles or overlaps below this area (px^2) are dropped: slivers of rounding
#: (an edge shared by two triangles) whose area cannot move a pixel's coverage by 1e-12.
AREA_MIN = 1e-12
#: Relative tolerance of the depth comparison of two planes at an overlap vertex: float64
#: rounding of planes from float32 vertices is about 1e-16; contact lines (a box on the
#: ground) meet at zero and must not read as interpenetration.
DEPTH_REL_TOL = 1e-9
#: Overlap area (px^2) above which the layered path takes an overlap's vertices from compiled
#: convex clipping instead of the polygon boolean (below: touching edges, where rounding
#: could leave a sliver the boolean does not have).
OVERLAP_SURE = 1e-6
#: A pixel is invalid where a not-exact region covers more than this area of it (px^2).
INVALID_AREA = 1e-12
#: Tessellation of curved shapes: segments around (spheres: and half as many from pole to
#: pole), chosen per shape so that the chord error is about :data:`CURVED_ERROR_PX` pixels
#: where the shape is nearest the camera, within these bounds. The chord error is a stated
#: bound (``slack``), turned into invalid pixels.
CURVED_SEGMENTS = (12, 192)
#: Chord error (pixels) the tessellation of a curved shape aims at.
CURVED_ERROR_PX = 0.25
#: Film margin (pixels) kept around the film when clipping projected triangles.
FILM_MARGIN = 1.0
#: Tiles across the film: each projected triangle is cut into the tiles it covers before the
#: depth resolution, so every union and difference is local (the union of 3,600 crossing
#: blades over a backdrop cost seconds per tile instead of minutes for the whole film).
TILES_ACROSS = 16
#: Polygons covering more than this many tiles' area are cut into tiles (see ``_tile``).
BIG_TILES = 4.0
#: Polygons per chunk of a bounding-box query (a long C call is cut so that a signal
#: handler runs between chunks).
QUERY_CHUNK = 8192
#: Above this many shapes the cross-shape pairs come from one tree over every polygon
#: instead of one tree per shape.
SHAPE_TREES = 64
#: The cost model of :func:`estimate_cost` (seconds on one core of the 2-core development
#: machine, measured in CPU time on the built-in scenes and meadow:n=10k-100k; see
#: docs/research.md): per projected triangle, per candidate pair sharing a grid cell on the
#: layered path, and per pair on the polygon path (shapely intersections and unions).
COST_PER_TRIANGLE = 3e-5
COST_PER_PAIR_LAYERED = 1.5e-6
COST_PER_PAIR_POLYGONS = 6e-6
#: The layered path is tried when the polygon path's estimate exceeds this many seconds
#: (below it the polygon path runs: small scenes keep their channels bit for bit).
LAYERED_ABOVE_S = 5.0
#: Cells across the film of the grid :func:`estimate_cost` counts candidate pairs on (a
#: fixed number, so that the estimate does not grow with the resolution); polygons covering
#: more than ``BIG_CELLS`` cells are counted against every other polygon.
COST_CELLS_ACROSS = 80
BIG_CELLS = 4096
#: Key of the triangle sets in ``LoadedScene.memo`` (one per camera and film: the
#: tessellation of curved shapes follows their size on the film).
MEMO_KEY = "exact_coverage_triangles"
#: Key of the last view's exact coverage in ``LoadedScene.memo``: it depends on the geometry
#: and the camera only, so the noise-floor reference (seed + 1) of the same view reuses it.
RESULT_MEMO_KEY = "exact_coverage_result"


@dataclass(frozen=True)
class TriangleSet:
    """World-space triangles of a scene for exact coverage.

    tris : ``(T, 3, 3)`` float64; shape : ``(T,)`` Mitsuba shape index; slack : ``(T,)``
    largest distance (world units) between the triangle and the true surface it stands
    for (0 for mesh faces and rectangles; the chord error of a tessellated curved shape).
    """

    tris: np.ndarray
    shape: np.ndarray
    slack: np.ndarray


def _curved_mesh(mi, shape, n: int):
    """Inscribed tessellation ``(verts, faces, chord_error)`` of a sphere, cylinder or disk."""
    from .tessellation import tessellate_sphere as _tessellate_sphere

    kind = shape.class_name()
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    radius = float(np.linalg.norm(m[:3, 0]))
    if kind == "Sphere":
        v, f = _tessellate_sphere(m[:3, 3], radius, n_phi=n, n_theta=n // 2)
        half = 0.5 * math.hypot(2 * math.pi / n, math.pi / (n // 2))
        return v, f, radius * (1.0 - math.cos(half))
    if kind == "Cylinder":
        v, f = _meshes.tube(m[:3, 3], m[:3, 3] + m[:3, 2], radius, sides=n)
        return v, f, radius * (1.0 - math.cos(math.pi / n))
    if kind == "Disk":
        ang = 2 * math.pi * np.arange(n) / n
        ring = np.stack([np.cos(ang), np.sin(ang), 0 * ang, 1 + 0 * ang], -1) @ m.T
        k = np.arange(n)
        f = np.stack([np.zeros(n), 1 + k, 1 + (k + 1) % n], -1).astype(np.uint32)
        return (
            np.concatenate([m[None, :3, 3], ring[:, :3]]),
            f,
            radius * (1 - math.cos(math.pi / n)),
        )
    raise ValueError(f"shape {shape.id()!r} of type {kind} has no exact-coverage geometry")


def _is_curved(mi, shape) -> bool:
    """Whether ``shape`` is tessellated here (sphere, cylinder, disk), not exact (a mesh or
    a rectangle)."""
    return not (shape.is_mesh() or shape.class_name() == "Rectangle")


def _pixels_per_unit(camera, lo, hi) -> float:
    """Film pixels per world unit at the nearest point of the box ``[lo, hi]`` (at least the
    near plane): a bound on how large a world distance there appears on the film."""
    if camera.kind != "perspective":
        return camera.width / (2.0 * camera.half_extent()[0])
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    inside = np.all((camera.position >= lo) & (camera.position <= hi))
    depth = (
        camera.near
        if inside
        else max(camera.near, float(((corners - camera.position) @ camera.forward).min()))
    )
    return camera.width / (2.0 * camera.tan_half_x) / depth


def _segments(mi, shape, camera) -> int:
    """Tessellation segments of a curved shape: chord error about :data:`CURVED_ERROR_PX`."""
    bb = shape.bbox()
    lo = np.array(bb.min, dtype=np.float64).ravel()[:3]
    hi = np.array(bb.max, dtype=np.float64).ravel()[:3]
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    r_px = float(np.linalg.norm(m[:3, 0])) * _pixels_per_unit(camera, lo, hi)
    # chord error r (1 - cos a) ~ r a^2 / 2 for a half-angle a = sqrt(2) pi / n (spheres)
    n = math.sqrt(2.0) * math.pi / math.sqrt(2.0 * CURVED_ERROR_PX / max(r_px, 1e-9))
    lo_n, hi_n = CURVED_SEGMENTS
    return int(min(max(2 * math.ceil(n / 2), lo_n), hi_n))


def scene_triangle_set(loaded) -> TriangleSet:
    """The :class:`TriangleSet` of ``loaded`` for its camera (memoised in ``loaded.memo``)."""
    cam = loaded.camera
    mi = backend.mitsuba()
    curved = any(_is_curved(mi, sh) for sh in loaded.mi_scene.shapes())
    # only a curved shape's tessellation depends on the camera
    key = (cam.to_world.tobytes(), cam.width, cam.height, cam.fov_x) if curved else "planar"
    memo = loaded.memo.setdefault(MEMO_KEY, {})
    cached = memo.get(key)
    if cached is not None:
        return cached
    from .tessellation import shape_mesh

    parts, shape_of, slack = [], [], []
    for i, sh in enumerate(loaded.mi_scene.shapes()):  # a loop over shapes, not triangles
        if not _is_curved(mi, sh):
            v, f = shape_mesh(mi, sh)
            err = 0.0
        else:
            v, f, err = _curved_mesh(mi, sh, _segments(mi, sh, cam))
        tris = np.asarray(v, dtype=np.float64)[np.asarray(f, dtype=np.int64)]
        parts.append(tris)
        shape_of.append(np.full(len(tris), i, dtype=np.int64))
        slack.append(np.full(len(tris), err))
    out = TriangleSet(
        np.concatenate(parts) if parts else np.zeros((0, 3, 3)),
        np.concatenate(shape_of) if parts else np.zeros(0, np.int64),
        np.concatenate(slack) if parts else np.zeros(0),
    )
    memo[key] = out
    return out


def _clip_plane(v, count, dist):
    """Sutherland-Hodgman clip of padded polygons ``v (N, K, 3)`` (``count`` vertices each)
    against ``dist >= 0`` (``dist (N, K)``), vectorised: ``(N, K + 1, 3)`` and new counts."""
    n, k = dist.shape
    idx = np.arange(k)[None, :]
    valid = idx < count[:, None]
    nxt = (idx + 1) % np.maximum(count[:, None], 1)
    d1 = np.take_along_axis(dist, nxt, 1)
    v1 = np.take_along_axis(v, nxt[..., None], 1)
    inside = dist >= 0
    cross = valid & (inside != (d1 >= 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cross, dist / (dist - d1), 0.0)
    p = v + t[..., None] * (v1 - v)
    cand = np.stack([v, p], axis=2).reshape(n, 2 * k, 3)
    keep = np.stack([valid & inside, cross], axis=2).reshape(n, 2 * k)
    order = np.argsort(~keep, axis=1, kind="stable")[:, : k + 1]
    return np.take_along_axis(cand, order[..., None], 1), keep.sum(axis=1)


def _project(camera, tris):
    """Film polygons (shapely, clipped to the film) of the triangles, and each one's index;
    in chunks (a signal handler runs between them)."""
    polys, idx = [np.empty(0, dtype=object)], [np.zeros(0, np.int64)]
    for start in range(0, len(tris), QUERY_CHUNK):
        p, i = _project_chunk(camera, tris[start : start + QUERY_CHUNK])
        polys.append(p)
        idx.append(i + start)
    return np.concatenate(polys), np.concatenate(idx)


def _project_chunk(camera, tris):
    """:func:`_project` of one chunk."""
    v, count = tris, np.full(len(tris), 3)
    for sign, plane in ((1.0, camera.near), (-1.0, camera.far)):  # near, then far
        depth = (v - camera.position) @ camera.forward
        v, count = _clip_plane(v, count, sign * (depth - plane))
    film = camera.project(v)
    ok = count >= 3
    idx = np.flatnonzero(ok)
    if not len(idx):  # everything behind the camera, nearer than near or beyond far
        return np.empty(0, dtype=object), idx
    kmax = film.shape[1]
    ring_idx = np.repeat(idx, count[ok])
    sel = np.arange(kmax)[None, :] < count[ok][:, None]
    coords = film[ok][sel]
    rings = shapely.linearrings(coords, indices=np.searchsorted(idx, ring_idx))
    polys = shapely.polygons(rings)
    # the film and a pixel around it (a grid offset by under a pixel reads that margin)
    w, h = float(camera.width), float(camera.height)
    polys = shapely.clip_by_rect(
        polys, -FILM_MARGIN, -FILM_MARGIN, w + FILM_MARGIN, h + FILM_MARGIN
    )
    area = shapely.area(polys)
    keep = area > AREA_MIN
    return polys[keep], idx[keep]


def _tile(polys, tri_idx, width: int, height: int):
    """Cut the film polygons at a grid of square tiles (integer pixel borders, about
    :data:`TILES_ACROSS` across the film and its margin): ``(pieces, their triangle)``.
    Pieces of one triangle meet along tile borders, where their boundary terms cancel."""
    size = max(1, math.ceil((width + 2 * FILM_MARGIN) / TILES_ACROSS))
    b = shapely.bounds(polys)
    t0 = np.floor((b[:, :2] + FILM_MARGIN) / size).astype(np.int64)
    t1 = np.floor((b[:, 2:] + FILM_MARGIN) / size).astype(np.int64)
    # only polygons larger than BIG_TILES tiles are cut (a backdrop behind thousands of
    # blades); cutting every small one multiplies the overlapping pairs for nothing
    big = shapely.area(polys) > BIG_TILES * size * size
    nx = np.where(big, t1[:, 0] - t0[:, 0] + 1, 1)
    ny = np.where(big, t1[:, 1] - t0[:, 1] + 1, 1)
    count = nx * ny
    owner = np.repeat(np.arange(len(polys)), count)
    k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    tx = t0[owner, 0] + k % nx[owner]
    ty = t0[owner, 1] + k // nx[owner]
    x0, y0 = tx * size - FILM_MARGIN, ty * size - FILM_MARGIN
    pieces = polys[owner].copy()
    cut = count[owner] > 1
    pieces[cut] = shapely.intersection(
        polys[owner[cut]], shapely.box(x0[cut], y0[cut], x0[cut] + size, y0[cut] + size)
    )
    keep = shapely.area(pieces) > AREA_MIN
    return pieces[keep], tri_idx[owner[keep]]


def _planes(tris):
    """World planes ``n . p = c`` of the triangles: ``(T, 3)`` normals and ``(T,)`` offsets."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return n, np.einsum("ij,ij->i", n, tris[:, 0])


def _nearness(camera, x, y, n, c):
    """Per point a quantity that grows towards the camera along the ray through film
    ``(x, y)`` to the plane ``(n, c)``: ``1/s`` (perspective) or ``-s`` (orthographic),
    ``s`` the ray parameter; affine in ``(x, y)`` for both."""
    (ox, oy, oz), (dx, dy, dz) = camera.local_ray(x, y)
    m = np.asarray(camera.to_world, dtype=np.float64)
    o = np.stack([ox, oy, oz], -1) @ m[:3, :3].T + m[:3, 3]
    d = np.stack([dx, dy, dz], -1) @ m[:3, :3].T
    nd = np.einsum("ij,ij->i", n, d)
    num = c - np.einsum("ij,ij->i", n, o)
    with np.errstate(divide="ignore", invalid="ignore"):
        return nd / num if camera.kind == "perspective" else -num / nd


def _classify_pairs(camera, polys, tri_idx, tset):
    """Overlapping projected pairs: ``(front, back)`` index pairs (into ``polys``) where one
    is in front over the whole overlap, and ``(a, b, overlap)`` where they interpenetrate,
    tie (coplanar, of two shapes) or come within a curved shape's tessellation bound of each
    other."""
    tree = shapely.STRtree(polys)
    a, b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for start in range(0, len(polys), QUERY_CHUNK):  # chunks: a signal handler runs between
        i, j = tree.query(polys[start : start + QUERY_CHUNK], predicate="intersects")
        a.append(i + start)
        b.append(j)
    a, b = np.concatenate(a), np.concatenate(b)
    keep = a < b
    o = _pair_order(camera, polys, tri_idx, tset, a[keep], b[keep])
    a, b, over, a_front, b_front, cross, bad = o
    n, c = _planes(tset.tris[tri_idx])
    a_near, b_near = _split_overlap(
        camera, over[cross], n[a[cross]], c[a[cross]], n[b[cross]], c[b[cross]]
    )
    back = np.concatenate([b[a_front], a[b_front], b[cross], a[cross]])
    # what hides the back one: the overlap (inside the back polygon: unions stay local), or
    # the front one's side of the intersection line
    occluder = np.concatenate([over[a_front], over[b_front], a_near, b_near])
    return back, occluder, (a[bad], b[bad], over[bad])


def _pair_order(camera, polys, tri_idx, tset, a, b, convex=None):
    """Depth order of the candidate pairs ``(a, b)`` whose overlap has an area:
    ``(a, b, overlap, a_front, b_front, cross, bad)`` (``cross``: planar triangles that
    interpenetrate; ``bad``: not exact, see :func:`_classify_pairs`).

    ``convex``: :func:`convex_arrays` of ``polys``; given, the vertices of overlaps of more
    than :data:`OVERLAP_SURE` px^2 come from :func:`convex_overlaps` (compiled, no polygon
    boolean; the same points up to rounding) and ``overlap`` is None."""
    if convex is None:
        over = _chunked(shapely.intersection, polys[a], polys[b])
        big = shapely.area(over) > AREA_MIN
        a, b, over = a[big], b[big], over[big]
        xy, owner = shapely.get_coordinates(over, return_index=True)
    else:
        xy, owner, big = _overlap_vertices(convex, polys, a, b)
        a, b, over = a[big], b[big], None
    n, c = _planes(tset.tris[tri_idx])
    ta, tb = a[owner], b[owner]
    qa = _nearness(camera, xy[:, 0], xy[:, 1], n[ta], c[ta])
    qb = _nearness(camera, xy[:, 0], xy[:, 1], n[tb], c[tb])
    # a curved shape's tessellation may lie `slack` from its surface: widen the tie band
    slack = tset.slack[tri_idx]
    if camera.kind == "perspective":
        band = slack[ta] * qa * qa + slack[tb] * qb * qb
    else:
        band = slack[ta] + slack[tb]
    tol = DEPTH_REL_TOL * (np.abs(qa) + np.abs(qb)) + band
    diff = qa - qb
    hi = np.full(len(a), -np.inf)
    lo = np.full(len(a), np.inf)
    np.maximum.at(hi, owner, diff - tol)  # > 0: a clearly nearer at some vertex
    np.minimum.at(lo, owner, diff + tol)  # < 0: b clearly nearer at some vertex
    a_front = (hi > 0) & (lo >= 0)
    b_front = (lo < 0) & (hi <= 0)
    # a tie between coplanar triangles: either in front gives the same coverage (a consistent
    # order, as there is one depth at each point), and the same front coverage within one
    # shape; between two shapes which one a ray tracer keeps is rounding: not exact
    shape = tset.shape[tri_idx]
    tie = (hi <= 0) & (lo >= 0)
    bad = ~(a_front | b_front | tie) | (tie & (shape[a] != shape[b]))
    a_front |= tie
    # planar triangles crossing each other: split the overlap along their intersection
    cross = (hi > 0) & (lo < 0) & (slack[a] == 0) & (slack[b] == 0)
    bad &= ~cross
    return a, b, over, a_front, b_front, cross, bad


def _overlap_vertices(convex, polys, a, b):
    """The vertices ``(M, 2)`` of the overlaps of the pairs ``(a, b)`` that have an area,
    the pair each belongs to (numbered among those) and which pairs have one: compiled
    convex clipping where the overlap is sure (over :data:`OVERLAP_SURE`); the polygon
    boolean, as :func:`_pair_order` has it, for the touching, thin or disjoint rest."""
    xy, owner, area = convex_overlaps(*convex, a, b)
    sure = area > OVERLAP_SURE
    doubt = np.flatnonzero(~sure)
    over = _chunked(shapely.intersection, polys[a[doubt]], polys[b[doubt]])
    big = sure.copy()
    big[doubt] = shapely.area(over) > AREA_MIN
    xy_d, own_d = shapely.get_coordinates(over, return_index=True)
    keep = sure[owner]
    xy = np.concatenate([xy[keep], xy_d])
    owner = np.concatenate([owner[keep], doubt[own_d]])
    keep = big[owner]
    return xy[keep], (np.cumsum(big) - 1)[owner[keep]], big


def _chunked(fn, *arrays):
    """``fn(*arrays)`` (an element-wise shapely function) in chunks of
    :data:`QUERY_CHUNK`: one long C call is cut so that a signal handler runs between."""
    n = len(arrays[0])
    if n <= QUERY_CHUNK:
        return fn(*arrays)
    parts = [fn(*(x[s : s + QUERY_CHUNK] for x in arrays)) for s in range(0, n, QUERY_CHUNK)]
    return np.concatenate(parts)


def _split_overlap(camera, over, na, ca, nb, cb):
    """The parts of overlaps ``over`` where plane ``a`` / plane ``b`` is nearer: the
    overlap clipped by the half-plane ``q_a - q_b >= 0`` / ``<= 0`` of the film, the
    nearness difference being affine in the film position (:func:`_nearness`)."""
    if len(over) == 0:
        return over, over
    k = len(over)
    probe = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    g = np.stack(
        [
            _nearness(camera, np.full(k, px), np.full(k, py), na, ca)
            - _nearness(camera, np.full(k, px), np.full(k, py), nb, cb)
            for px, py in probe
        ],
        axis=1,
    )
    gx, gy, g0 = g[:, 1] - g[:, 0], g[:, 2] - g[:, 0], g[:, 0]
    lo, hi = -FILM_MARGIN - 1.0, FILM_MARGIN + 1.0
    rect = np.array(
        [
            [lo, lo],
            [camera.width + hi, lo],
            [camera.width + hi, camera.height + hi],
            [lo, camera.height + hi],
        ]
    )
    pts = np.zeros((k, 4, 3))
    pts[:, :, :2] = rect
    sides = []
    for sign in (1.0, -1.0):
        dist = sign * (
            g0[:, None] + gx[:, None] * rect[None, :, 0] + gy[:, None] * rect[None, :, 1]
        )
        v, count = _clip_plane(pts, np.full(k, 4), dist)
        sides.append(shapely.intersection(over, _polygons(v[..., :2], count)))
    return sides[0], sides[1]


def _polygons(v, count):
    """Shapely polygons from padded vertices ``v (N, K, 2)`` with ``count`` each (fewer than
    3: an empty polygon)."""
    out = np.empty(len(v), dtype=object)
    out[:] = shapely.Polygon()
    ok = count >= 3
    if ok.any():
        idx = np.flatnonzero(ok)
        sel = np.arange(v.shape[1])[None, :] < count[ok][:, None]
        rings = shapely.linearrings(v[ok][sel], indices=np.repeat(np.arange(len(idx)), count[ok]))
        out[idx] = shapely.polygons(rings)
    return out


def _visible(polys, back, occluder):
    """Each polygon less the union of what is in front of it (``occluder[i]`` in front of
    ``polys[back[i]]``; vectorised per polygon)."""
    order = np.argsort(back, kind="stable")
    occluder, back = occluder[order], back[order]
    groups = np.empty(len(polys), dtype=object)
    groups[:] = None
    if len(back):
        shapely.geometrycollections(occluder, indices=back, out=groups)
    has = np.zeros(len(polys), bool)
    has[back] = True
    vis = polys.copy()
    if has.any():
        occ = _chunked(lambda g: shapely.union_all(g[:, None], axis=1), groups[has])
        vis[has] = _chunked(shapely.difference, polys[has], occ)
    return vis


#: Largest rounding error (px) of clipped and projected vertices that still counts as exact:
#: float64 rounding of world coordinates of magnitude ``M`` seen at the near plane is about
#: ``M * 2^-52 * pixels per unit there``; a ground of +-1e30 gives 1e16 px.
ROUNDING_PX_MAX = 1e-6


class NotExact(Exception):
    """The scene's geometry cannot be clipped and projected exactly in float64 (coordinates
    so large that rounding moves vertices by more than :data:`ROUNDING_PX_MAX` pixels)."""


class OverBudget(Exception):
    """The estimated cost of the exact coverage exceeds the budget; ``estimate`` says by how
    much (:func:`estimate_cost`)."""

    def __init__(self, estimate: dict, budget: float):
        super().__init__(
            f"estimated {estimate['seconds']:.3g} s > budget {budget:g} s "
            f"({estimate['triangles']} projected triangles, {estimate['pairs']} overlapping "
            f"pairs, {estimate['path']} path)"
        )
        self.estimate, self.budget = estimate, budget


def estimate_cost(camera, tset: TriangleSet, path: str = "layered", pairs=None) -> dict:
    """Deterministic cost estimate of :func:`exact_coverage_of` from the projected
    triangles and their overlaps, made before any polygon work: the triangles are clipped
    and projected with NumPy (in chunks), their bounding boxes binned on a grid of
    :data:`COST_CELLS_ACROSS` cells across, and the pairs sharing a cell counted (``pairs``
    given: that count). ``{"seconds", "triangles", "pairs", "path"}``; seconds by the cost
    model above (``path``: ``"layered"`` or ``"polygons"``)."""
    w, h = camera.width, camera.height
    cell = w / COST_CELLS_ACROSS
    nx, ny = int(w / cell) + 3, int(h / cell) + 3
    counts = np.zeros(nx * ny, np.int64)
    n_tri = n_big = 0
    reach = 0.0
    for start in range(0, len(tset.tris), 1 << 15):
        box, far = _film_boxes(camera, tset.tris[start : start + (1 << 15)])
        reach = max(reach, far)
        if box is None:
            continue
        c0 = np.floor((box[:, :2] + FILM_MARGIN) / cell).astype(np.int64) + 1
        c1 = np.floor((box[:, 2:] + FILM_MARGIN) / cell).astype(np.int64) + 1
        c0, c1 = np.clip(c0, 0, [nx - 1, ny - 1]), np.clip(c1, 0, [nx - 1, ny - 1])
        span = (c1 - c0 + 1).prod(axis=1)
        big = span > BIG_CELLS
        n_tri += len(box)
        n_big += int(big.sum())
        c0, c1, span = c0[~big], c1[~big], span[~big]
        own = np.repeat(np.arange(len(span)), span)
        k = np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span)
        wx = (c1 - c0 + 1)[own, 0]
        at = (c0[own, 1] + k // wx) * nx + c0[own, 0] + k % wx
        counts += np.bincount(at, minlength=nx * ny)
    if pairs is None:
        pairs = int((counts * (counts - 1) // 2).sum()) + n_big * n_tri
    rate = COST_PER_PAIR_LAYERED if path == "layered" else COST_PER_PAIR_POLYGONS
    seconds = COST_PER_TRIANGLE * n_tri + rate * pairs
    return {
        "seconds": float(seconds),
        "triangles": int(n_tri),
        "pairs": int(pairs),
        "path": path,
        "rounding_px": float(reach * 2.0**-52 * _pixels_per_unit_near(camera)),
    }


def _pixels_per_unit_near(camera) -> float:
    """Film pixels per world unit at the near plane (the largest scale a world distance in
    view is seen at)."""
    if camera.kind != "perspective":
        return camera.width / (2.0 * camera.half_extent()[0])
    return camera.width / (2.0 * camera.tan_half_x) / camera.near


def _film_boxes(camera, tris):
    """Film bounding boxes ``(N, 4)`` (x0, y0, x1, y1) of the triangles' parts between the
    near and far planes that meet the film and its margin (None when none does), and the
    largest distance from the camera of a vertex of a triangle that reaches that range."""
    v, count = tris, np.full(len(tris), 3)
    with np.errstate(all="ignore"):
        for sign, plane in ((1.0, camera.near), (-1.0, camera.far)):
            depth = (v - camera.position) @ camera.forward
            v, count = _clip_plane(v, count, sign * (depth - plane))
    ok = count >= 3
    if not ok.any():
        return None, 0.0
    with np.errstate(all="ignore"):
        far = float(np.abs(tris[ok] - camera.position).max())
    if not np.isfinite(far):
        far = np.inf
    v, count = v[ok], count[ok]
    with np.errstate(all="ignore"):
        film = camera.project(v)
    used = np.arange(film.shape[1])[None, :] < count[:, None]
    lo = np.where(used[..., None], film, np.inf).min(axis=1)
    hi = np.where(used[..., None], film, -np.inf).max(axis=1)
    box = np.concatenate([lo, hi], axis=1)
    w, h = camera.width + FILM_MARGIN, camera.height + FILM_MARGIN
    box = np.clip(box, -FILM_MARGIN, [w, h, w, h])
    keep = np.isfinite(box).all(axis=1) & (box[:, 2] > box[:, 0]) & (box[:, 3] > box[:, 1])
    return (box[keep] if keep.any() else None), far


@dataclass
class ExactCoverage:
    """The exact channels (``(H, W)`` float64) and a record of how they were made."""

    coverage: np.ndarray
    front_coverage: np.ndarray
    valid: np.ndarray
    stats: dict


def _curved_invalid(vis, curved, tset, tri_idx, camera, w, h):
    """Pixels within the tessellation bound of a curved shape's visible silhouette: the
    pixels the boundary of each curved shape's visible region (the union of its triangles'
    visible parts: against the sky, another shape or itself) meets, dilated by the chord
    error in pixels plus one."""
    if not curved.any():
        return np.zeros((h, w), bool)
    shape = tset.shape[tri_idx[curved]]
    order = np.argsort(shape, kind="stable")
    ids, first = np.unique(shape[order], return_index=True)
    groups = shapely.geometrycollections(
        vis[curved][order], indices=np.searchsorted(ids, shape[order])
    )
    regions = shapely.union_all(groups[:, None], axis=1)
    partial = touched_pixels(regions, w, h)
    tris = tset.tris[tri_idx[curved]]
    slack = tset.slack[tri_idx[curved]]
    if camera.kind == "perspective":
        depth = np.maximum((tris - camera.position) @ camera.forward, camera.near).min(axis=1)
        px = float((slack * (camera.width / (2.0 * camera.tan_half_x)) / depth).max())
    else:
        px = float(slack.max()) * camera.width / (2.0 * camera.half_extent()[0])
    radius = int(math.ceil(px)) + 1
    from scipy.ndimage import binary_dilation

    return binary_dilation(partial, iterations=radius)


def exact_coverage(loaded, centre: np.ndarray, *, budget=None, check=None) -> ExactCoverage:
    """Exact ``coverage``, ``front_coverage`` and validity of ``loaded``'s current view.

    Parameters
    ----------
    loaded : a :class:`scenes.loader.LoadedScene` (its camera and film size are used).
    centre : ``(H*W,)`` or ``(H, W)`` int shape index seen through each pixel centre
        (-1: sky), as the Monte Carlo ``front_coverage`` uses it.
    """
    centre = np.ascontiguousarray(centre, dtype=np.int64)
    view = json.dumps(loaded.camera.to_json(), sort_keys=True)
    key = (view, hashlib.sha256(centre.tobytes()).hexdigest())
    slot = loaded.memo.get(RESULT_MEMO_KEY)
    if slot is not None and slot[0] == key:
        done = slot[1]
        over = isinstance(done, OverBudget) and budget is not None
        if isinstance(done, NotExact) or (over and done.estimate["seconds"] > budget):
            raise done  # the same view refused again (the noise floor's reference)
        if not isinstance(done, Exception):
            return done
    try:
        out = exact_coverage_of(
            loaded.camera, scene_triangle_set(loaded), centre, budget=budget, check=check
        )
    except (OverBudget, NotExact) as exc:
        exc.view = key  # said once per view by the caller
        loaded.memo[RESULT_MEMO_KEY] = (key, exc)
        raise exc.with_traceback(None) from None  # the memo keeps no frames alive
    loaded.memo[RESULT_MEMO_KEY] = (key, out)
    return out


def exact_coverage_of(
    camera,
    tset: TriangleSet,
    centre: np.ndarray,
    *,
    grid_offset=(0.0, 0.0),
    check=None,
    budget: float | None = None,
) -> ExactCoverage:
    """:func:`exact_coverage` of the triangles ``tset`` seen by ``camera`` (a
    :class:`scenes.camera.Camera`; its film size is the output's).

    ``grid_offset`` ``(ox, oy)`` in ``[-1, 1]`` pixels moves the pixel grid: pixel ``(x, y)``
    then covers ``[x + ox, x + ox + 1) x [y + oy, y + oy + 1)`` (the expected coverage of a
    sample under random sub-pixel translations of the scene is the coverage of such a box).
    ``check``: called between chunks of the long loops (a signal handler runs there).
    ``budget``: seconds of estimated work (:func:`estimate_cost`) allowed; over it,
    :class:`OverBudget` is raised before the work (before each path's own work).

    Where the polygon path would cost more than :data:`LAYERED_ABOVE_S` by the estimate and
    the shapes have one depth order wherever they overlap (no interpenetration or tie
    between shapes, no curved shape) the visible boundaries come from
    :mod:`scenes.geometry.coverage_edges` (``stats["method"] == "layered"``: work in
    proportion to the overlapping pairs, no polygon booleans); otherwise each triangle's
    visible polygon is its projection less the union of what is in front of it
    (``"polygons"``).
    """
    t0 = time.perf_counter()
    cam = camera
    w, h = cam.width, cam.height
    off = np.asarray(grid_offset, dtype=np.float64)
    if off.shape != (2,) or not np.all(np.abs(off) <= FILM_MARGIN):
        raise ValueError(f"grid_offset must be two values in [-1, 1] pixels, got {grid_offset!r}")
    est = estimate_cost(cam, tset)
    if not est["rounding_px"] <= ROUNDING_PX_MAX:
        raise NotExact(
            f"coordinates too large for exact clipping in float64: rounding up to "
            f"{est['rounding_px']:.3g} px (more than {ROUNDING_PX_MAX:g})"
        )
    if budget is not None and est["seconds"] > budget:
        raise OverBudget(est, budget)
    if est["triangles"] == 0:  # nothing between the near and far planes in view
        return _empty_view(cam, centre, est, t0)
    polys, tri_idx = _project(cam, tset.tris)
    polys, tri_idx = _tile(polys, tri_idx, w, h)
    poly_s = COST_PER_TRIANGLE * est["triangles"] + COST_PER_PAIR_POLYGONS * est["pairs"]
    # the layered path where it pays; below, the polygon path (the bytes of before)
    fast = None
    if poly_s > LAYERED_ABOVE_S:
        fast = _layered(cam, polys, tri_idx, tset, centre, off, check)
    if fast is not None:
        fast.stats.update(estimate=est, seconds=time.perf_counter() - t0)
        return fast
    est = dict(est, path="polygons", seconds=poly_s)
    if budget is not None and est["seconds"] > budget:
        raise OverBudget(est, budget)
    back, occluder, (bad_a, bad_b, bad_over) = _classify_pairs(cam, polys, tri_idx, tset)
    vis = _visible(polys, back, occluder)
    if np.any(off != 0.0):
        vis = shapely.transform(vis, lambda xy: xy - off)
        bad_over = shapely.transform(bad_over, lambda xy: xy - off)
    shape_of = tset.shape[tri_idx]
    pieces = edge_pieces(vis, w, h, tags=shape_of)
    cov = pixel_area(None, w, h, pieces=pieces)
    centre = np.asarray(centre, dtype=np.int64).reshape(h, w)
    front_cov = tagged_pixel_area(pieces, centre)
    front_cov = np.where(centre < 0, 1.0 - cov, front_cov)
    # not exact: visible parts of interpenetrating / tied overlaps, curved silhouettes
    bad_regions = np.concatenate(
        [shapely.intersection(vis[bad_a], bad_over), shapely.intersection(vis[bad_b], bad_over)]
    )
    invalid = (
        pixel_area(bad_regions, w, h) > INVALID_AREA if len(bad_regions) else np.zeros((h, w), bool)
    )
    curved = tset.slack[tri_idx] > 0
    invalid |= _curved_invalid(vis, curved, tset, tri_idx, cam, w, h)
    stats = {
        "triangles_projected": int(len(np.unique(tri_idx))),
        "tile_pieces": int(len(polys)),
        "occlusion_pairs": int(len(back)),
        "unresolved_pairs": int(len(bad_a)),
        "curved_triangles": int(curved.sum()),
        "invalid_pixels": int(invalid.sum()),
        "method": "polygons",
        "estimate": est,
        "seconds": time.perf_counter() - t0,
    }
    return ExactCoverage(np.clip(cov, 0.0, 1.0), np.clip(front_cov, 0.0, 1.0), ~invalid, stats)


def _empty_view(cam, centre, est, t0) -> ExactCoverage:
    """Nothing in view: coverage 0 everywhere (exact), front coverage 1 where the centre
    sees the sky."""
    w, h = cam.width, cam.height
    zero = np.zeros((h, w))
    centre = np.asarray(centre, dtype=np.int64).reshape(h, w)
    stats = {
        "triangles_projected": 0,
        "tile_pieces": 0,
        "occlusion_pairs": 0,
        "unresolved_pairs": 0,
        "curved_triangles": 0,
        "invalid_pixels": 0,
        "method": "empty",
        "estimate": est,
        "seconds": time.perf_counter() - t0,
    }
    return ExactCoverage(zero, np.where(centre < 0, 1.0, 0.0), np.ones((h, w), bool), stats)


def _cross_shape_pairs(polys, shape, check=None):
    """Candidate pairs ``(a, b)`` (``a < b``, bounding boxes overlapping) of polygons of
    different shapes: one tree per shape (few shapes), else one tree over all, queried in
    chunks."""
    ids = np.unique(shape)
    out_a, out_b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    if len(ids) <= SHAPE_TREES:
        for s in ids[:-1]:  # a loop over shapes, not triangles
            mine = np.flatnonzero(shape == s)
            other = np.flatnonzero(shape > s)
            tree = shapely.STRtree(polys[mine])
            for start in range(0, len(other), QUERY_CHUNK):
                if check is not None:
                    check()
                q = other[start : start + QUERY_CHUNK]
                i, j = tree.query(polys[q])
                a, b = mine[j], q[i]
                out_a.append(np.minimum(a, b))
                out_b.append(np.maximum(a, b))
    else:
        tree = shapely.STRtree(polys)
        for start in range(0, len(polys), QUERY_CHUNK):
            if check is not None:
                check()
            i, j = tree.query(polys[start : start + QUERY_CHUNK])
            a = i + start
            keep = (a < j) & (shape[a] != shape[j])
            out_a.append(a[keep])
            out_b.append(j[keep])
    return np.concatenate(out_a), np.concatenate(out_b)


def _shape_layers(front, back, ids):
    """Rank of each shape in a depth order where every ``front[k]`` precedes ``back[k]``
    (Kahn's algorithm over shapes), or None where the relation has a cycle."""
    edges = set(zip(front.tolist(), back.tolist(), strict=True))
    indeg = {s: 0 for s in ids.tolist()}
    succ: dict = {s: [] for s in indeg}
    for f, b in edges:
        succ[f].append(b)
        indeg[b] += 1
    ready = sorted(s for s, d in indeg.items() if d == 0)
    rank = {}
    while ready:  # a loop over shapes
        s = ready.pop(0)
        rank[s] = len(rank)
        for t in sorted(succ[s]):
            indeg[t] -= 1
            if indeg[t] == 0:
                ready.append(t)
        ready.sort()
    return rank if len(rank) == len(indeg) else None


def _layered(cam, polys, tri_idx, tset, centre, off, check):
    """The exact channels from the visible boundaries of layered shapes
    (:mod:`scenes.geometry.coverage_edges`), or None where the shapes have no depth order (an
    interpenetration, a tie between shapes, a cycle) or a shape is curved."""
    w, h = cam.width, cam.height
    shape = tset.shape[tri_idx]
    if len(polys) == 0 or np.any(tset.slack[tri_idx] > 0):
        return None
    a, b = _cross_shape_pairs(polys, shape, check)
    v, count = convex_arrays(polys)
    order = _pair_order(cam, polys, tri_idx, tset, a, b, convex=(v, count))
    a, b, _, a_front, b_front, cross, bad = order
    if bad.any() or cross.any():
        return None
    front = np.concatenate([shape[a[a_front]], shape[b[b_front]]])
    back = np.concatenate([shape[b[a_front]], shape[a[b_front]]])
    ids = np.unique(shape)
    rank = _shape_layers(front, back, ids)
    if rank is None:
        return None
    layer = np.array([rank[s] for s in ids.tolist()])[np.searchsorted(ids, shape)]
    tree = shapely.STRtree(polys)

    def pairs(idx):
        i, j = tree.query(polys[idx])
        keep = idx[i] != j
        return idx[i][keep], j[keep]

    x0, y0, x1, y1, tag = visible_segments(v, count, layer, shape, pairs, check=check)
    pieces = segment_pieces(x0 - off[0], y0 - off[1], x1 - off[0], y1 - off[1], tag, w, h)
    cov = pixel_area(None, w, h, pieces=pieces)
    centre = np.asarray(centre, dtype=np.int64).reshape(h, w)
    front_cov = np.where(centre < 0, 1.0 - cov, tagged_pixel_area(pieces, centre))
    stats = {
        "triangles_projected": int(len(np.unique(tri_idx))),
        "tile_pieces": int(len(polys)),
        "occlusion_pairs": int(a_front.sum() + b_front.sum()),
        "unresolved_pairs": 0,
        "curved_triangles": 0,
        "invalid_pixels": 0,
        "method": "layered",
        "boundary_segments": int(len(x0)),
    }
    valid = np.ones((h, w), bool)
    return ExactCoverage(np.clip(cov, 0.0, 1.0), np.clip(front_cov, 0.0, 1.0), valid, stats)
