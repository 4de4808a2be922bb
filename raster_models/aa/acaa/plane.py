"""The depth ACAA's depth tests compare: each triangle's screen-space depth plane, set up in
float32 from its window-space vertices and evaluated at the sample position, as a
rasterizer does (:func:`raster_models.depth.plane_setup`), then stored in the depth format.

Exact ray depths of two coplanar surfaces round alike almost everywhere (a sloped decal with
its own vertices: 97.6 % of its samples tied where an OpenGL rasterizer ties 26 %); planes set
up from different float32 vertices differ in their last bits, so such surfaces tie on some
samples and on the others the lower one wins (z-fighting).

Triangles of meshes only; an analytic shape (sphere, disk, ...) and a triangle that a
rasterizer would clip at the near plane (a vertex behind it) keep the float32 depth of the
exact hit, as do triangles with no area on screen.
"""

from __future__ import annotations

import numpy as np

from ....scenes import backend
from ... import depth as _depth
from .groups import normalized_depth

__all__ = ["depth_tests", "mesh_table", "raster_depths", "stored_raster_depths"]


def mesh_table(scene) -> list:
    """Per shape of ``scene`` (``scene.shape_names`` order): ``(vertices (V, 3) float32,
    faces (F, 3) int64)`` of a mesh as the scene stores it, None for an analytic shape;
    memoized in ``scene.memo``."""
    table = scene.memo.get("acaa.mesh_table")
    if table is None:
        mi = backend.mitsuba()
        table = []
        for shape in scene.mi_scene.shapes():  # one entry per shape (a list-length loop)
            if not shape.is_mesh():
                table.append(None)
                continue
            params = mi.traverse(shape)
            v = np.array(params["vertex_positions"], np.float32).reshape(-1, 3)
            f = np.array(params["faces"], np.int64).reshape(-1, 3)
            table.append((v, f))
        scene.memo["acaa.mesh_table"] = table
    return table


def raster_depths(scene, shape, prim, sx, sy, view_depth) -> np.ndarray:
    """Normalized depth (float32 values, as float64) a rasterizer computes for primitive
    ``prim`` of shape ``shape`` at film positions ``(sx, sy)``; ``view_depth`` (the exact
    hit's) gives the fallback of the module docstring."""
    cam = scene.camera
    shape = np.asarray(shape, np.int64)
    prim = np.asarray(prim, np.int64)
    out = normalized_depth(cam, view_depth).astype(np.float32)
    table = mesh_table(scene)
    for k in np.unique(shape):  # one round per shape present (a list-length loop)
        if k < 0 or table[k] is None:
            continue
        sel = np.flatnonzero(shape == k)
        verts, faces = table[k]
        tri = verts[faces[prim[sel]]]  # (m, 3 vertices, 3)
        x, y, z, w = _depth.window_vertices(cam, tri)
        a0, dzdx, dzdy, ok = _depth.plane_setup(x, y, z)
        if cam.kind == "perspective":
            ok &= (w >= np.float32(cam.near)).all(axis=1)
        val = _depth.plane_eval(a0, dzdx, dzdy, np.asarray(sx)[sel], np.asarray(sy)[sel])
        out[sel] = np.where(ok, val, out[sel])
    return out.astype(np.float64)


def stored_raster_depths(scene, shape, prim, sx, sy, view_depth, fmt: str) -> np.ndarray:
    """:func:`raster_depths` stored in depth format ``fmt`` (float64, one launch of
    :func:`raster_models.depth.quantize_dr`)."""
    mi = backend.mitsuba()
    d = raster_depths(scene, shape, prim, sx, sy, view_depth)
    if len(d) == 0:
        return d
    return _depth.quantize_dr(mi, mi.Float64(d), fmt).numpy()


def depth_tests(scene, candidates: list, window: float, fmt: str, offsets) -> dict | None:
    """The stored rasterized depths at the samples where another group's surface can tie
    with the nearest one: the candidates of :func:`.trace.prepass` (per group ``(pixel,
    sample, depth, hit, hit_depth, hit_shape, hit_prim, near_shape, near_prim)``) whose hit
    lies within ``window`` (view depth) behind the nearest hit.

    Returns None without such a candidate, else a dict: ``rows`` ``(pixel, sample, shape,
    prim)`` of the candidates' surfaces and ``q_hit`` their stored depths; ``keys`` the
    distinct samples (``pixel * N + sample``, sorted), ``inv`` each row's index into them,
    ``first`` the first row of each; ``near`` ``(shape, prim)`` of each sample's nearest
    surface, ``q_near`` its stored depth and ``low`` the lowest stored depth at the sample
    (the value a LESS prepass keeps).
    """
    n = len(offsets)
    offs = np.asarray(offsets, np.float32).reshape(-1, 2)
    w = scene.width
    rows = []
    for pix, smp, depth, hit, hit_depth, h_shape, h_prim, n_shape, n_prim in candidates:
        near = hit.copy()
        if np.isfinite(window):  # equal stored depths lie within the tie distance
            near &= hit_depth <= depth + np.float32(window)
        ci = np.flatnonzero(near)
        rows.append([a[ci] for a in (pix, smp, depth, hit_depth, h_shape, h_prim, n_shape, n_prim)])
    if not rows or sum(len(r[0]) for r in rows) == 0:
        return None
    pix, smp, depth, hit_depth, h_shape, h_prim, n_shape, n_prim = (
        np.concatenate(parts) for parts in zip(*rows, strict=True)
    )
    sx = (pix % w).astype(np.float32) + offs[smp, 0]
    sy = (pix // w).astype(np.float32) + offs[smp, 1]
    q_hit = stored_raster_depths(scene, h_shape, h_prim, sx, sy, hit_depth, fmt)
    keys, first, inv = np.unique(pix * n + smp, return_index=True, return_inverse=True)
    near = (n_shape[first], n_prim[first])
    q_near = stored_raster_depths(scene, *near, sx[first], sy[first], depth[first], fmt)
    low = q_near.copy()
    np.minimum.at(low, inv, q_hit)
    return {
        "rows": (pix, smp, h_shape, h_prim),
        "q_hit": q_hit,
        "keys": keys,
        "inv": inv,
        "first": first,
        "near": near,
        "q_near": q_near,
        "low": low,
    }
