"""The compiled passes of the layered exact-coverage path (scenes.geometry.coverage_edges):
interval sweeps, edge clipping through visible_segments, and convex overlaps, against
closed forms and shapely."""

import numpy as np
import shapely
from raster_oracle.scenes.geometry import coverage_edges as ce


def _tagged_areas(polys, layer, tag):
    """Area enclosed per tag by the visible boundary segments (Green's theorem)."""
    polys = np.asarray(polys, dtype=object)
    v, count = ce.convex_arrays(polys)
    tree = shapely.STRtree(polys)

    def pairs(idx):
        i, j = tree.query(polys[idx])
        keep = idx[i] != j
        return idx[i][keep], j[keep]

    x0, y0, x1, y1, t = ce.visible_segments(v, count, np.asarray(layer), np.asarray(tag), pairs)
    cross = 0.5 * (x0 * y1 - x1 * y0)
    return {int(k): float(cross[t == k].sum()) for k in np.unique(t)}


def test_interval_sweep_closed_form():
    """[0, 1] less [0.2, 0.4] u [0.3, 0.5] u [0.7, 0.8] on one edge, nothing on another; and
    the pieces between consecutive ends inside that union."""
    full = (np.array([0, 1]), np.zeros(2), np.ones(2))
    cut = (np.array([0, 0, 0]), np.array([0.2, 0.3, 0.7]), np.array([0.4, 0.5, 0.8]))
    g, lo, hi = ce._segments_of(full, cut, groups=2)
    assert g.tolist() == [0, 0, 0, 1]
    assert np.allclose(lo, [0.0, 0.5, 0.8, 0.0]) and np.allclose(hi, [0.2, 0.7, 1.0, 1.0])
    g, lo, hi = ce._segments_of(full, cut, b_in=True, groups=2)  # elementary pieces
    assert g.tolist() == [0, 0, 0, 0]
    assert np.allclose(lo, [0.2, 0.3, 0.4, 0.7]) and np.allclose(hi, [0.3, 0.4, 0.5, 0.8])


def test_union_and_occlusion_areas_closed_form():
    """Two 2 x 2 squares overlapping by 1 x 1: one layer bounds their union (7); in two
    layers the front keeps 4 and the back shows 3. Any order of the polygons."""
    a, b = shapely.box(0, 0, 2, 2), shapely.box(1, 1, 3, 3)
    for polys in ([a, b], [b, a]):
        assert np.isclose(sum(_tagged_areas(polys, [0, 0], [5, 5]).values()), 7.0)
    assert np.allclose(list(_tagged_areas([a, b], [0, 1], [0, 1]).values()), [4.0, 3.0])
    assert np.allclose(list(_tagged_areas([b, a], [1, 0], [1, 0]).values()), [4.0, 3.0])


def test_convex_overlaps_match_shapely():
    """Random triangles and quads: each pair's overlap area equals shapely's, its vertices
    lie in both polygons; disjoint pairs have no area and no vertex."""
    rng = np.random.default_rng(7)
    polys = []
    for k in rng.integers(3, 5, 300):
        c = rng.uniform(0, 9, 2)
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        r = rng.uniform(1, 4)
        polys.append(
            shapely.convex_hull(shapely.MultiPoint(c + r * np.c_[np.cos(ang), np.sin(ang)]))
        )
    polys = np.asarray(polys, dtype=object)
    a, b = np.arange(0, 300, 2), np.arange(1, 300, 2)
    v, count = ce.convex_arrays(polys)
    xy, owner, area = ce.convex_overlaps(v, count, a, b)
    want = shapely.area(shapely.intersection(polys[a], polys[b]))
    assert np.abs(area - want).max() < 1e-9
    assert ((want > 0) & (area > 0)).sum() > 20 and ((want == 0) & (area == 0)).sum() > 20
    dist = np.maximum(
        shapely.distance(shapely.points(xy), polys[a[owner]]),
        shapely.distance(shapely.points(xy), polys[b[owner]]),
    )
    assert dist.max() < 1e-9
    assert not np.isin(np.flatnonzero(want == 0), owner).any()
