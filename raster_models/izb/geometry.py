"""IZB geometry: the scene's occluder triangles, their shadow volumes, and conservative
rasterization of triangles over a light-space grid (all vectorized, chunked by rows).

Shadow volume of a triangle under a directional light travelling along ``d`` (unit): the
three edge planes through each edge and ``d`` (unit normals along ``(v_j - v_i) x d`` turned
to face the third vertex: a plane value is a distance) and the triangle's own plane (unit
normal turned along ``d``, pushed away from the light by ``epsilon`` world units). Under a
spot light at ``L`` the edge planes pass through ``L`` (unit normals along ``(v_i - L) x
(v_j - L)``): the three half-spaces meet in the cone from ``L`` through the triangle (one
nappe: the cone spanned by ``v_i - L``). A point ``q`` is in shadow of the triangle when
every edge plane has ``q`` on its inner side (``>= 0``: closed) and ``n . (q - v0) > eps``.
Triangles whose plane contains ``d`` (or ``L``) have zero projected area, cast no shadow and
are culled.

Conservative rasterization: a texel square ``[i, i+1] x [j, j+1]`` (texel units) overlaps a
2D triangle exactly when it overlaps its bounding box and, for each edge, the square's corner
farthest inside the edge's half-plane is inside (the separating axis theorem for a triangle
and a box in 2D: the box axes and the three edge normals). A margin of
:data:`CONSERVATIVE_MARGIN` texels keeps rounding from dropping a touched texel (an extra
fragment costs tests, never a wrong answer).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "CONSERVATIVE_MARGIN",
    "HIT_REACH",
    "MEMO_KEY",
    "RASTER_CHUNK",
    "chunks_by_total",
    "conservative_fragments",
    "grown_fragments",
    "ray_hits",
    "onto_own_planes",
    "scene_triangles",
    "surface_triangles",
    "shadow_volumes",
]

#: Texels of slack in the conservative overlap test (float64 rounding of edge functions is
#: ~1e-12 texels at 16384^2; a million times that keeps every touched texel).
CONSERVATIVE_MARGIN = 1e-6

#: How far from its G-buffer position (relative to ``1 + max|p|``) a pixel ray's hit on the
#: point's own plane is taken as its exact hit (:func:`ray_hits`): float32 rounding
#: puts the position about 2^-22 of that from it; 2^-12 keeps a margin and drops a ray nearly
#: parallel to the plane (no stable hit).
HIT_REACH = 2.0**-12

#: Candidate (texel) tests per rasterization chunk: bounds memory (~100 MiB a chunk).
RASTER_CHUNK = 1 << 22

#: Key of the occluder triangles in ``LoadedScene.memo``.
MEMO_KEY = "izb_triangles"

#: Key of each shape's first triangle and plane rule in ``LoadedScene.memo``
#: (:func:`surface_triangles`).
RANGES_KEY = "izb_triangle_ranges"

#: A shape's triangles: its own faces (a mesh: Mitsuba's primitive index is the face), all in
#: one plane (a rectangle or disk: any of them holds the surface), or none in the surface (a
#: sphere or cylinder: the tessellation only approximates it).
FACES, PLANAR, CURVED = 0, 1, 2

#: Triangles whose unit normal has ``|n . d|`` below this are edge-on to the light: zero
#: projected area, no shadow (their neighbours' volumes cover the same rays).
EDGE_ON = 1e-9


def scene_triangles(scene) -> np.ndarray:
    """World-space triangles ``(T, 3, 3)`` float64 of every shape of the scene, in the
    scene's shape order (analytic shapes tessellated as :func:`scenes.formats.export.shape_mesh`
    does). Kept in ``scene.memo["izb_triangles"]`` (geometry only: shared by every camera
    and light of the scene)."""
    tris = scene.memo.get(MEMO_KEY)
    if tris is None:
        from ...scenes import backend
        from ...scenes.geometry.tessellation import shape_mesh

        mi = backend.mitsuba()
        parts, first, rule = [], [], []
        for shape in scene.mi_scene.shapes():  # a loop over shapes, not triangles
            v, f = shape_mesh(mi, shape)
            first.append(sum(len(q) for q in parts))
            kind = shape.class_name()
            rule.append(PLANAR if kind in ("Rectangle", "Disk") else CURVED)
            if "vertex_positions" in mi.traverse(shape).keys():
                rule[-1] = FACES
            parts.append(np.asarray(v, dtype=np.float64)[np.asarray(f, dtype=np.int64)])
        tris = np.concatenate(parts) if parts else np.zeros((0, 3, 3))
        scene.memo[MEMO_KEY] = tris
        scene.memo[RANGES_KEY] = (np.asarray(first, np.int64), np.asarray(rule, np.int64))
    return tris


def surface_triangles(scene, shape: np.ndarray, prim: np.ndarray) -> np.ndarray:
    """Index into :func:`scene_triangles` of a triangle lying in the surface of each visible
    point (``shape``, ``prim``: a G-buffer's shape and primitive indices), -1 where there is
    none: the mesh face ``prim``, a rectangle's or disk's first triangle (its plane), nothing
    on a sphere or cylinder or where nothing was hit."""
    scene_triangles(scene)
    first, rule = scene.memo[RANGES_KEY]
    out = np.full(len(shape), -1, dtype=np.int64)
    hit = shape >= 0
    s = shape[hit].astype(np.int64)
    idx = first[s] + np.where(rule[s] == FACES, prim[hit], 0)
    out[hit] = np.where(rule[s] == CURVED, -1, idx)
    return out


def onto_own_planes(tris: np.ndarray, own: np.ndarray, p: np.ndarray):
    """Points ``p (N, 3)`` moved along their own triangle's normal onto its plane, in float64
    (``own``: index into ``tris`` of each point's triangle, -1: left as is), and whether each
    was moved.

    A G-buffer position is float32: it lies up to a few ulps of ``|p|`` off its surface, so its
    distance to its own triangle's plane (zero in truth) is rounding of that size, 0.06 mm
    1,000 units from the origin. On the plane it is float64 rounding (about 2^-50 of ``|p|``),
    and a distance to another triangle's plane is known to that precision too: what lets the
    epsilon band (:func:`raster_models.izb.kernel.band_floor`) flag gaps far below float32
    rounding. The move is along the normal only, by that rounding: the sample stays where the
    pixel's ray met the surface, up to float32 precision, as the oracle's own rays start
    (:func:`ray_hits` gives the exact hit).
    """
    p = np.array(p, dtype=np.float64)
    moved = own >= 0
    t = tris[own[moved]]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(n, axis=1)
    ok = length > 0.0  # zero-area triangles have no plane
    n = n[ok] / length[ok, None]
    rows = np.flatnonzero(moved)[ok]
    dist = np.sum((p[rows] - t[ok, 0]) * n, axis=1)
    p[rows] -= dist[:, None] * n
    moved[:] = False
    moved[rows] = True
    return p, moved


def ray_hits(tris: np.ndarray, own: np.ndarray, p: np.ndarray, origins, directions):
    """Where rays meet the planes of triangles ``own`` (index into ``tris``), in float64: the
    pixels' exact hits of points ``p (N, 3)`` on their own planes (:func:`onto_own_planes`)
    from the pixels' camera rays ``origins``, ``directions`` ``(N, 3)``
    (:meth:`scenes.camera.Camera.rays`), put back on the plane along its normal.

    Within its plane the G-buffer position lies beside the pixel's true hit by float32
    rounding (3.6e-6 units at the origin for a 15-unit rectangle 1 unit from the camera,
    1.3e-4 units 1,000 units out): enough to put a pixel outside an occluder's edge plane that
    an exact ray from its true hit is inside, which the epsilon band must flag
    (:class:`raster_models.izb.kernel.PairTester`). A point keeps ``p`` where its ray is
    parallel to the plane or meets it farther than :data:`HIT_REACH` from it.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        normal /= np.linalg.norm(normal, axis=1)[:, None]  # per triangle, then per point
        n, v0 = normal[own], tris[own, 0]
        s = np.einsum("ij,ij->i", v0 - origins, n) / np.einsum("ij,ij->i", directions, n)
        h = directions * s[:, None]
        h += origins
        h -= np.einsum("ij,ij->i", h - v0, n)[:, None] * n  # the hit's rounding off the plane
        reach = HIT_REACH * (1.0 + np.abs(p).max(axis=1))
        use = np.abs(h - p).max(axis=1) <= reach  # False where h is not finite
    return np.where(use[:, None], h, p)


def shadow_volumes(tris: np.ndarray, direction, epsilon: float, *, position=None):
    """Planes of each triangle's shadow volume.

    Directional light along ``direction`` (``position=None``): edge planes contain the edge
    and the direction. Spot light at ``position``: edge planes contain the edge and the
    light (the volume is the cone from the light through the triangle, beyond it).

    Returns
    -------
    keep : ``(T,)`` bool, False for triangles edge-on to the light (culled).
    planes : ``(K, 4, 4)`` float64 for the kept triangles: rows are three edge planes and the
        triangle plane, each ``(nx, ny, nz, c)``; a point ``q`` is shadowed when
        ``n . q + c >= 0`` for the edge rows and ``> 0`` for the triangle row (whose ``c``
        includes ``-epsilon``; its normal is unit length, turned away from the light).
    """
    v0, v1, v2 = tris[:, 0], tris[:, 1], tris[:, 2]
    nt = np.cross(v1 - v0, v2 - v0)
    norm = np.linalg.norm(nt, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        nt = nt / norm[:, None]
    if position is None:
        d = np.asarray(direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        facing = nt @ d
    else:
        light = np.asarray(position, dtype=np.float64)
        to_tri = (v0 + v1 + v2) / 3.0 - light
        dist = np.linalg.norm(to_tri, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            facing = np.einsum("ij,ij->i", nt, to_tri) / dist
    keep = np.isfinite(facing) & (np.abs(facing) > EDGE_ON) & (norm > 0)
    v0, v1, v2, nt, facing = v0[keep], v1[keep], v2[keep], nt[keep], facing[keep]
    nt = nt * np.sign(facing)[:, None]
    planes = np.empty((len(v0), 4, 4))
    for row, (a, b, c) in enumerate(((v0, v1, v2), (v1, v2, v0), (v2, v0, v1))):
        if position is None:
            ne = np.cross(b - a, d)
        else:
            ne = np.cross(a - light, b - light)
        s = np.sign(np.einsum("ij,ij->i", ne, c - a))
        length = np.linalg.norm(ne, axis=1)
        # unit length (a plane value is a distance: the band's edge slack is one); an edge
        # along the light direction has no plane and stays 0 (always inside)
        s = np.divide(s, length, out=np.zeros_like(s), where=length > 0)
        ne = ne * s[:, None]
        planes[:, row, :3] = ne
        planes[:, row, 3] = -np.einsum("ij,ij->i", ne, a)
    planes[:, 3, :3] = nt
    planes[:, 3, 3] = -np.einsum("ij,ij->i", nt, v0) - epsilon
    return keep, planes


def _edge_functions(uv: np.ndarray):
    """Inward edge functions ``e(u, v) = a u + b v + c`` of 2D triangles ``(T, 3, 2)``."""
    p = uv
    area = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (
        p[:, 2, 0] - p[:, 0, 0]
    )
    sgn = np.where(area >= 0, 1.0, -1.0)
    coef = np.empty((len(p), 3, 3))
    for row, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        a = -(p[:, j, 1] - p[:, i, 1])
        b = p[:, j, 0] - p[:, i, 0]
        c = -(a * p[:, i, 0] + b * p[:, i, 1])
        coef[:, row] = np.stack([a, b, c], axis=1) * sgn[:, None]
    return coef


def chunks_by_total(sizes: np.ndarray, limit: int):
    """Slices of consecutive items whose ``sizes`` add up to at most ``limit`` (at least one
    item each, so an item larger than ``limit`` forms a chunk of its own)."""
    ends = np.cumsum(sizes)
    cut = 0
    while cut < len(ends):
        base = ends[cut - 1] if cut else 0
        stop = max(int(np.searchsorted(ends, base + limit, side="right")), cut + 1)
        yield slice(cut, stop)
        cut = stop


def conservative_fragments(uv: np.ndarray, resolution: int):
    """Texels every 2D triangle touches (conservative rasterization), chunk by chunk.

    Parameters
    ----------
    uv : ``(T, 3, 2)`` triangle vertices in texel units (``u`` right, ``v`` down: texel
        ``(i, j)`` covers ``[i, i+1) x [j, j+1)``).
    resolution : texels per side ``R``; texels outside ``[0, R)^2`` are clipped.

    Yields
    ------
    (tri, texel) : int64 arrays, triangle index into ``uv`` and texel id ``j * R + i``, for
    chunks of at most about :data:`RASTER_CHUNK` candidate texels (one triangle's bounding
    box is split by rows, so memory is bounded for any triangle size).
    """
    for tri, texel, _ in grown_fragments(uv, resolution, margin=0.0):  # chunks
        yield tri, texel


def grown_fragments(uv: np.ndarray, resolution: int, *, margin: float):
    """:func:`conservative_fragments` of the triangles grown by ``margin`` texels: every
    texel within that distance (max-norm) of a triangle, with ``exact`` (bool), whether the
    triangle itself touches it (a fragment of :func:`conservative_fragments`); with
    ``margin=0`` every fragment is exact. Yields ``(tri, texel, exact)`` chunks."""
    r = int(resolution)
    if len(uv) == 0:
        return
    tight = np.floor(uv.min(axis=1)).astype(np.int64), np.floor(uv.max(axis=1)).astype(np.int64)
    lo = np.floor(uv.min(axis=1) - margin).astype(np.int64)
    hi = np.floor(uv.max(axis=1) + margin).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, r - 1)
    ok = np.all(hi >= lo, axis=1)
    idx = np.nonzero(ok)[0]
    if len(idx) == 0:
        return
    lo, hi = lo[idx], hi[idx]
    tight = tight[0][idx], tight[1][idx]
    coef = _edge_functions(uv[idx])
    width = hi[:, 0] - lo[:, 0] + 1
    height = hi[:, 1] - lo[:, 1] + 1
    # Work units: one (triangle, bounding-box row) each, at most R candidates.
    row_tri = np.repeat(np.arange(len(idx)), height)
    row_start = np.cumsum(height) - height
    row_j = lo[row_tri, 1] + (np.arange(len(row_tri)) - row_start[row_tri])
    row_w = width[row_tri]
    for sl in chunks_by_total(row_w, RASTER_CHUNK):  # chunks of rows
        t = np.repeat(row_tri[sl], row_w[sl])
        j = np.repeat(row_j[sl], row_w[sl])
        first = np.cumsum(row_w[sl]) - row_w[sl]
        i = lo[t, 0] + (np.arange(len(t)) - np.repeat(first, row_w[sl]))
        inside = _touched(coef, t, i, j, CONSERVATIVE_MARGIN + margin)
        t, i, j = t[inside], i[inside], j[inside]
        if margin > 0:  # the fragments (few) again, without the margin
            exact = (i >= tight[0][t, 0]) & (i <= tight[1][t, 0])
            exact &= (j >= tight[0][t, 1]) & (j <= tight[1][t, 1])
            exact &= _touched(coef, t, i, j, CONSERVATIVE_MARGIN)
        else:
            exact = np.ones(len(t), dtype=bool)
        yield idx[t], j * r + i, exact


def _touched(coef, t, i, j, margin: float) -> np.ndarray:
    """Whether texels ``(i, j)`` lie within ``margin`` texels of triangles ``t`` (edge
    functions ``coef``): for each edge, the texel's corner farthest inside is inside."""
    inside = np.ones(len(t), dtype=bool)
    for e in range(3):  # the three edges
        a, b, c = coef[t, e, 0], coef[t, e, 1], coef[t, e, 2]
        best = a * (i + (a > 0)) + b * (j + (b > 0)) + c
        inside &= best >= -margin * (np.abs(a) + np.abs(b))
    return inside
