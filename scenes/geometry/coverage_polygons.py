"""The polygon path of exact coverage: each triangle's visible polygon is its projection
less the union of what is in front of it (shapely 2, vectorised over all triangles and
pairs), interpenetrating pairs split along their intersection line, ties and curved
silhouettes turned into invalid pixels."""

from __future__ import annotations

import math

import numpy as np
import shapely

from .coverage_edges import convex_overlaps
from .coverage_projection import (
    AREA_MIN,
    FILM_MARGIN,
    QUERY_CHUNK,
    chunked,
    clip_plane,
    nearness,
    planes,
    polygons_of,
)
from .pixel_area import edge_pieces, pixel_area, tagged_pixel_area, touched_pixels

__all__ = [
    "DEPTH_REL_TOL",
    "INVALID_AREA",
    "OVERLAP_SURE",
    "PAIR_CHUNK",
    "pair_order",
    "polygon_coverage",
]

#: Relative tolerance of the depth comparison of two planes at an overlap vertex: float64
#: rounding of planes from float32 vertices is about 1e-16; contact lines (a box on the
#: ground) meet at zero and must not read as interpenetration.
DEPTH_REL_TOL = 1e-9
#: Overlap area (px^2) above which the layered path takes an overlap's vertices from compiled
#: convex clipping instead of the polygon boolean (below: touching edges, where rounding
#: could leave a sliver the boolean does not have).
OVERLAP_SURE = 1e-6
#: Candidate pairs depth-ordered at a time (a deadline is checked between chunks).
PAIR_CHUNK = 1 << 16
#: A pixel is invalid where a not-exact region covers more than this area of it (px^2).
INVALID_AREA = 1e-12


def _classify_pairs(camera, polys, tri_idx, tset, check=None):
    """Overlapping projected pairs: ``(front, back)`` index pairs (into ``polys``) where one
    is in front over the whole overlap, and ``(a, b, overlap)`` where they interpenetrate,
    tie (coplanar, of two shapes) or come within a curved shape's tessellation bound of each
    other."""
    tree = shapely.STRtree(polys)
    a, b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    step = QUERY_CHUNK // 8  # a stack of panes: every piece meets a hundred others
    for start in range(0, len(polys), step):  # chunks: a signal handler runs between
        if check is not None:
            check()
        i, j = tree.query(polys[start : start + step], predicate="intersects")
        a.append(i + start)
        b.append(j)
    a, b = np.concatenate(a), np.concatenate(b)
    keep = a < b
    o = pair_order(camera, polys, tri_idx, tset, a[keep], b[keep], check=check)
    a, b, over, a_front, b_front, cross, bad = o
    n, c = planes(tset.tris[tri_idx])
    a_near, b_near = _split_overlap(
        camera, over[cross], n[a[cross]], c[a[cross]], n[b[cross]], c[b[cross]], check
    )
    back = np.concatenate([b[a_front], a[b_front], b[cross], a[cross]])
    # what hides the back one: the overlap (inside the back polygon: unions stay local), or
    # the front one's side of the intersection line
    occluder = np.concatenate([over[a_front], over[b_front], a_near, b_near])
    return back, occluder, (a[bad], b[bad], over[bad])


def pair_order(camera, polys, tri_idx, tset, a, b, convex=None, check=None):
    """Depth order of the candidate pairs ``(a, b)``: :func:`_pair_order` in chunks of
    :data:`PAIR_CHUNK` pairs, ``check`` called before each (the same arrays as one call)."""
    if len(a) <= PAIR_CHUNK:
        if check is not None:
            check()
        return _pair_order(camera, polys, tri_idx, tset, a, b, convex, check)
    parts = []
    for s in range(0, len(a), PAIR_CHUNK):
        if check is not None:
            check()
        sl = slice(s, s + PAIR_CHUNK)
        parts.append(_pair_order(camera, polys, tri_idx, tset, a[sl], b[sl], convex, check))
    out = [np.concatenate([p[k] for p in parts]) for k in range(7) if k != 2]
    over = None if convex is not None else np.concatenate([p[2] for p in parts])
    return (*out[:2], over, *out[2:])


def _pair_order(camera, polys, tri_idx, tset, a, b, convex, check):
    """Depth order of the candidate pairs ``(a, b)`` whose overlap has an area:
    ``(a, b, overlap, a_front, b_front, cross, bad)`` (``cross``: planar triangles that
    interpenetrate; ``bad``: not exact, see :func:`_classify_pairs`).

    ``convex``: :func:`convex_arrays` of ``polys``; given, the vertices of overlaps of more
    than :data:`OVERLAP_SURE` px^2 come from :func:`convex_overlaps` (compiled, no polygon
    boolean; the same points up to rounding) and ``overlap`` is None."""
    if convex is None:
        over = chunked(shapely.intersection, polys[a], polys[b], check=check)
        big = shapely.area(over) > AREA_MIN
        a, b, over = a[big], b[big], over[big]
        xy, owner = shapely.get_coordinates(over, return_index=True)
    else:
        xy, owner, big = _overlap_vertices(convex, polys, a, b, check)
        a, b, over = a[big], b[big], None
    n, c = planes(tset.tris[tri_idx])
    ta, tb = a[owner], b[owner]
    qa = nearness(camera, xy[:, 0], xy[:, 1], n[ta], c[ta])
    qb = nearness(camera, xy[:, 0], xy[:, 1], n[tb], c[tb])
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


def _overlap_vertices(convex, polys, a, b, check=None):
    """The vertices ``(M, 2)`` of the overlaps of the pairs ``(a, b)`` that have an area,
    the pair each belongs to (numbered among those) and which pairs have one: compiled
    convex clipping where the overlap is sure (over :data:`OVERLAP_SURE`); the polygon
    boolean, as :func:`pair_order` has it, for the touching, thin or disjoint rest."""
    xy, owner, area = convex_overlaps(*convex, a, b)
    sure = area > OVERLAP_SURE
    doubt = np.flatnonzero(~sure)
    over = chunked(shapely.intersection, polys[a[doubt]], polys[b[doubt]], check=check)
    big = sure.copy()
    big[doubt] = shapely.area(over) > AREA_MIN
    xy_d, own_d = shapely.get_coordinates(over, return_index=True)
    keep = sure[owner]
    xy = np.concatenate([xy[keep], xy_d])
    owner = np.concatenate([owner[keep], doubt[own_d]])
    keep = big[owner]
    return xy[keep], (np.cumsum(big) - 1)[owner[keep]], big


def _split_overlap(camera, over, na, ca, nb, cb, check=None):
    """The parts of overlaps ``over`` where plane ``a`` / plane ``b`` is nearer: the
    overlap clipped by the half-plane ``q_a - q_b >= 0`` / ``<= 0`` of the film, the
    nearness difference being affine in the film position (:func:`nearness`)."""
    if len(over) == 0:
        return over, over
    k = len(over)
    probe = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    g = np.stack(
        [
            nearness(camera, np.full(k, px), np.full(k, py), na, ca)
            - nearness(camera, np.full(k, px), np.full(k, py), nb, cb)
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
        v, count = clip_plane(pts, np.full(k, 4), dist)
        sides.append(
            chunked(shapely.intersection, over, polygons_of(v[..., :2], count), check=check)
        )
    return sides[0], sides[1]


def _visible(polys, back, occluder, check=None):
    """Each polygon less the union of what is in front of it (``occluder[i]`` in front of
    ``polys[back[i]]``; vectorised per polygon, in chunks of about :data:`QUERY_CHUNK`
    occluders, ``check`` called before each: a stack of panes puts dozens in front of each
    piece)."""
    vis = polys.copy()
    if not len(back):
        return vis
    order = np.argsort(back, kind="stable")
    occluder, back = occluder[order], back[order]
    ids, first, counts = np.unique(back, return_index=True, return_counts=True)
    bounds = _chunk_bounds(counts, QUERY_CHUNK)
    for s, e in zip(bounds[:-1], bounds[1:], strict=True):
        if check is not None:
            check()
        lo, hi = first[s], first[e - 1] + counts[e - 1]
        groups = shapely.geometrycollections(
            occluder[lo:hi], indices=np.repeat(np.arange(e - s), counts[s:e])
        )
        union = shapely.union_all(groups[:, None], axis=1)
        vis[ids[s:e]] = shapely.difference(polys[ids[s:e]], union)
    return vis


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


def _chunk_bounds(sizes: np.ndarray, most: int) -> list[int]:
    """Start indices of chunks of consecutive elements of ``sizes`` whose sums stay near
    ``most`` (an element larger than it is a chunk of its own), and the end."""
    ends = np.cumsum(sizes)
    starts = np.unique(np.searchsorted(ends, np.arange(0, int(ends[-1]), most), side="right"))
    return sorted({0, *starts.tolist(), len(sizes)})


def polygon_coverage(cam, polys, tri_idx, tset, centre, off, check=None):
    """The exact channels of the film polygons ``polys`` (tile pieces of the triangles
    ``tri_idx`` of ``tset``) seen by ``cam``, the pixel grid moved by ``off``: ``(coverage,
    front_coverage, valid, stats)``, each visible polygon its projection less the union of
    what is in front of it."""
    w, h = cam.width, cam.height
    back, occluder, (bad_a, bad_b, bad_over) = _classify_pairs(cam, polys, tri_idx, tset, check)
    vis = _visible(polys, back, occluder, check)
    if check is not None:
        check()
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
    }
    return np.clip(cov, 0.0, 1.0), np.clip(front_cov, 0.0, 1.0), ~invalid, stats
