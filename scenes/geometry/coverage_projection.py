"""Clipping and projection of world triangles to film polygons for exact coverage: the near
and far planes (Mitsuba's rays run from the near to the far plane), the film and its margin,
the tiles large polygons are cut into, and the affine nearness of a plane along film rays."""

from __future__ import annotations

import math

import numpy as np
import shapely

__all__ = [
    "AREA_MIN",
    "BIG_TILES",
    "FILM_MARGIN",
    "QUERY_CHUNK",
    "TILES_ACROSS",
    "chunked",
    "clip_plane",
    "film_boxes",
    "nearness",
    "planes",
    "polygons_of",
    "project",
    "tile",
]

#: Projected triangles or overlaps below this area (px^2) are dropped: slivers of rounding
#: (an edge shared by two triangles) whose area cannot move a pixel's coverage by 1e-12.
AREA_MIN = 1e-12
#: Film margin (pixels) kept around the film when clipping projected triangles.
FILM_MARGIN = 1.0
#: Tiles across the film: each projected triangle is cut into the tiles it covers before the
#: depth resolution, so every union and difference is local (the union of 3,600 crossing
#: blades over a backdrop cost seconds per tile instead of minutes for the whole film).
TILES_ACROSS = 16
#: Polygons covering more than this many tiles' area are cut into tiles (see ``tile``).
BIG_TILES = 4.0
#: Polygons per chunk of a bounding-box query (a long C call is cut so that a signal
#: handler runs between chunks).
QUERY_CHUNK = 8192


def clip_plane(v, count, dist):
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


def project(camera, tris, check=None):
    """Film polygons (shapely, clipped to the film) of the triangles, and each one's index;
    in chunks (a signal handler runs between them, and ``check``)."""
    polys, idx = [np.empty(0, dtype=object)], [np.zeros(0, np.int64)]
    for start in range(0, len(tris), QUERY_CHUNK):
        if check is not None:
            check()
        p, i = _project_chunk(camera, tris[start : start + QUERY_CHUNK])
        polys.append(p)
        idx.append(i + start)
    return np.concatenate(polys), np.concatenate(idx)


def _project_chunk(camera, tris):
    """:func:`project` of one chunk."""
    v, count = tris, np.full(len(tris), 3)
    for sign, plane in ((1.0, camera.near), (-1.0, camera.far)):  # near, then far
        depth = (v - camera.position) @ camera.forward
        v, count = clip_plane(v, count, sign * (depth - plane))
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


def tile(polys, tri_idx, width: int, height: int):
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


def planes(tris):
    """World planes ``n . p = c`` of the triangles: ``(T, 3)`` normals and ``(T,)`` offsets."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return n, np.einsum("ij,ij->i", n, tris[:, 0])


def nearness(camera, x, y, n, c):
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


def chunked(fn, *arrays, check=None, bounds=None):
    """``fn(*arrays)`` (an element-wise shapely function) in chunks of
    :data:`QUERY_CHUNK` elements (``bounds``: the chunks' start indices and the end, when
    elements differ in cost): one long C call is cut so that a signal handler runs between,
    and ``check`` (a deadline, :func:`coverage_cost.deadline_check`) is called before each."""
    n = len(arrays[0])
    if bounds is None:
        if n <= QUERY_CHUNK and check is None:
            return fn(*arrays)
        bounds = [*range(0, n, QUERY_CHUNK), n]
    parts = [np.empty(0, dtype=object)]
    for s, e in zip(bounds[:-1], bounds[1:], strict=True):
        if check is not None:
            check()
        parts.append(fn(*(x[s:e] for x in arrays)))
    return np.concatenate(parts)


def polygons_of(v, count):
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


def film_boxes(camera, tris):
    """The triangles' parts between the near and far planes that meet the film and its
    margin: a dict of their film bounding boxes ``box`` ``(N, 4)`` (x0, y0, x1, y1, clipped
    to the film and its margin), their projected polygons ``film`` ``(N, K, 2)`` with
    ``count`` vertices each, their ``area`` (px^2, at most their clipped box's) and their
    ``index`` among ``tris``; None when none does. Also the largest distance from the camera
    of a vertex of a triangle that reaches that range."""
    v, count = tris, np.full(len(tris), 3)
    with np.errstate(all="ignore"):
        for sign, plane in ((1.0, camera.near), (-1.0, camera.far)):
            depth = (v - camera.position) @ camera.forward
            v, count = clip_plane(v, count, sign * (depth - plane))
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
    if not keep.any():
        return None, far
    film, count, used = film[keep], count[keep], used[keep]
    # shoelace area of each polygon (its unused slots repeat nothing: closed by index)
    nxt = (np.arange(film.shape[1])[None, :] + 1) % count[:, None]
    x, y = film[..., 0], film[..., 1]
    xn, yn = np.take_along_axis(x, nxt, 1), np.take_along_axis(y, nxt, 1)
    with np.errstate(all="ignore"):
        area = 0.5 * np.abs(np.where(used, x * yn - xn * y, 0.0).sum(axis=1))
    box = box[keep]
    area = np.minimum(area, (box[:, 2] - box[:, 0]) * (box[:, 3] - box[:, 1]))
    index = np.flatnonzero(ok)[keep]
    return {"box": box, "film": film, "count": count, "area": area, "index": index}, far
