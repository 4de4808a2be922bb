"""The layered path of exact coverage: where the shapes have one depth order wherever they
overlap, the visible boundaries come from :mod:`scenes.geometry.coverage_edges` (compiled,
work in proportion to the overlapping pairs, no polygon booleans)."""

from __future__ import annotations

import numpy as np
import shapely

from .coverage_edges import convex_arrays, visible_segments
from .coverage_polygons import pair_order
from .coverage_projection import QUERY_CHUNK
from .pixel_area import pixel_area, segment_pieces, tagged_pixel_area

__all__ = ["SHAPE_TREES", "layered_coverage"]

#: Above this many shapes the cross-shape pairs come from one tree over every polygon
#: instead of one tree per shape.
SHAPE_TREES = 64


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


def layered_coverage(cam, polys, tri_idx, tset, centre, off, check):
    """The exact channels from the visible boundaries of layered shapes
    (:mod:`scenes.geometry.coverage_edges`), or None where the shapes have no depth order (an
    interpenetration, a tie between shapes, a cycle) or a shape is curved."""
    w, h = cam.width, cam.height
    shape = tset.shape[tri_idx]
    if len(polys) == 0 or np.any(tset.slack[tri_idx] > 0):
        return None
    a, b = _cross_shape_pairs(polys, shape, check)
    v, count = convex_arrays(polys)
    order = pair_order(cam, polys, tri_idx, tset, a, b, convex=(v, count), check=check)
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
    return np.clip(cov, 0.0, 1.0), np.clip(front_cov, 0.0, 1.0), valid, stats
