"""Exact pixel coverage of convex polygons in image space (test helper, vectorized).

Every pixel square is clipped by each edge's half-plane of a convex polygon (Sutherland-
Hodgman, vectorized over pixels) and the area of what remains is its coverage.
"""

from __future__ import annotations

import numpy as np


def _clip(poly, count, a, b, c):
    """Clip polygons (P, V, 2) with ``count`` vertices by a*x + b*y + c >= 0."""
    p, v, _ = poly.shape
    idx = np.arange(v)
    nxt_idx = (idx[None, :] + 1) % np.maximum(count[:, None], 1)
    cur = poly
    nxt = np.take_along_axis(poly, nxt_idx[..., None].repeat(2, -1), axis=1)
    dc = a * cur[..., 0] + b * cur[..., 1] + c
    dn = a * nxt[..., 0] + b * nxt[..., 1] + c
    real = idx[None, :] < count[:, None]
    inside_c, inside_n = dc >= 0, dn >= 0
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(dc != dn, dc / (dc - dn), 0.0)
    cross = cur + t[..., None] * (nxt - cur)
    out = np.stack([cur, cross], axis=2).reshape(p, 2 * v, 2)
    keep = np.stack([real & inside_c, real & (inside_c != inside_n)], axis=2).reshape(p, 2 * v)
    order = np.argsort(~keep, axis=1, kind="stable")
    out = np.take_along_axis(out, order[..., None].repeat(2, -1), axis=1)
    new_count = keep.sum(axis=1)
    return out, new_count


def _area(poly, count):
    v = poly.shape[1]
    idx = np.arange(v)
    valid = idx[None, :] < count[:, None]
    first = poly[:, :1, :]
    poly = np.where(valid[..., None], poly, first)
    nxt = np.roll(poly, -1, axis=1)
    last = np.maximum(count - 1, 0)
    nxt[np.arange(len(poly)), last] = poly[:, 0]
    cross = poly[..., 0] * nxt[..., 1] - poly[..., 1] * nxt[..., 0]
    return 0.5 * np.abs(np.sum(np.where(valid, cross, 0.0), axis=1))


def polygon_coverage(vertices, width: int, height: int) -> np.ndarray:
    """Fraction of each pixel (H, W) covered by a convex polygon (K, 2) in film pixels."""
    vtx = np.asarray(vertices, dtype=np.float64)
    signed = np.sum(vtx[:, 0] * np.roll(vtx[:, 1], -1) - np.roll(vtx[:, 0], -1) * vtx[:, 1])
    if signed < 0:
        vtx = vtx[::-1]
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    x0, y0 = xx.ravel(), yy.ravel()
    poly = np.zeros((len(x0), 4, 2))
    poly[:, 0] = np.stack([x0, y0], 1)
    poly[:, 1] = np.stack([x0 + 1, y0], 1)
    poly[:, 2] = np.stack([x0 + 1, y0 + 1], 1)
    poly[:, 3] = np.stack([x0, y0 + 1], 1)
    count = np.full(len(x0), 4)
    for i in range(len(vtx)):
        (px, py), (qx, qy) = vtx[i], vtx[(i + 1) % len(vtx)]
        # inside = left of the edge for counter-clockwise (in x-right, y-down: signed > 0)
        a, b = -(qy - py), qx - px
        c = -(a * px + b * py)
        poly, count = _clip(poly, count, a, b, c)
    return _area(poly, count).reshape(height, width)
