"""NumPy references of the anti-aliasing models' Dr.Jit kernels (tests only).

The models run one implementation each, on the Dr.Jit side; these are the rules written
plainly in NumPy, for the tests to compare against within stated tolerances:

- :func:`first_of_key`, :func:`group_fragments`: a pixel's samples grouped by primitive
  (:func:`raster_models.aa.pixel_dr.first_of_key`, ``fragments_of``);
- :func:`quantize_normals`: a normal stored in a G-buffer format and read back
  (:func:`raster_models.aa.pixel_dr.store_normal`);
- :func:`cluster`: AGAA's clustering (:func:`raster_models.aa.agaa.pixels.cluster_pixels`),
  in float32 like the model or in float64;
- :func:`agaa_colors`: AGAA's material accumulation, shading and resolve in float64
  (:func:`raster_models.aa.agaa.kernels.render`) given the samples' fragments and aggregates.
"""

from __future__ import annotations

import numpy as np
from raster_oracle.raster_models.aa.fragments import (
    Fragments,
    sample_film_positions,
    shading_positions,
)
from raster_oracle.raster_models.aa.trace import fragment_attributes, shade_points
from raster_oracle.scenes.backend.raycast import trace_film

#: Pixels per grouping chunk (keeps the ``(P, N, N)`` comparison cache-sized).
GROUP_CHUNK = 1 << 15


def first_of_key(valid: np.ndarray, shape: np.ndarray, prim: np.ndarray) -> np.ndarray:
    """``(P, N)`` first sample of each sample's pixel with the same (shape, primitive)."""
    n_pix, n = valid.shape
    key = np.where(valid, (shape.astype(np.int64) << 40) ^ prim.astype(np.int64), -1)
    first = np.empty((n_pix, n), np.int64)
    for start in range(0, n_pix, GROUP_CHUNK):
        k = key[start : start + GROUP_CHUNK]
        eq = k[:, :, None] == k[:, None, :]
        first[start : start + GROUP_CHUNK] = np.argmax(eq, axis=2)
    return first


def group_fragments(valid: np.ndarray, shape=None, prim=None, *, first=None) -> Fragments:
    """Group the samples of each pixel by primitive; ``valid``/``shape``/``prim`` are (P, N),
    or ``first`` (P, N) gives each sample's representative slot."""
    n_pix, n = valid.shape
    if first is None:
        first = first_of_key(valid, shape, prim)
    first = np.asarray(first)
    rep = (first == np.arange(n, dtype=first.dtype)[None, :]) & valid
    flat = rep.ravel()
    # fragment ids in pixel-major order; a sample's fragment is its representative's id
    fid = np.cumsum(flat, dtype=np.int64) - 1
    lane = np.where(valid, np.arange(n_pix)[:, None] * n + first, 0)
    of_sample = np.where(valid, fid[lane], -1)
    reps = np.flatnonzero(flat)
    count = np.bincount(of_sample.ravel() + 1, minlength=len(reps) + 1)[1:]
    return Fragments(reps // n, reps % n, count, of_sample)


def quantize_normals(n: np.ndarray, fmt: str) -> np.ndarray:
    """Unit normals ``(..., 3)`` as stored in ``fmt`` and read back (float32, as a shader
    reads them)."""
    f32 = np.float32
    n = np.asarray(n, f32)
    if fmt == "rgba16f":
        return n.astype(np.float16).astype(f32)
    if fmt == "rgb10a2":
        q = np.floor(np.clip(n * f32(0.5) + f32(0.5), f32(0), f32(1)) * f32(1023) + f32(0.5))
        return q * f32(2 / 1023) - f32(1)
    if fmt == "oct16":
        l1 = np.sum(np.abs(n), axis=-1, keepdims=True)
        p = n / np.where(l1 > 0, l1, 1.0)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
        u = np.where(z < 0, (1 - np.abs(y)) * sx, x)
        v = np.where(z < 0, (1 - np.abs(x)) * sy, y)
        u = np.round(np.clip(u, -1, 1) * 32767.0) / 32767.0
        v = np.round(np.clip(v, -1, 1) * 32767.0) / 32767.0
        zz = 1.0 - np.abs(u) - np.abs(v)
        t = np.maximum(-zz, 0.0)
        u = u - np.where(u >= 0, t, -t)
        v = v - np.where(v >= 0, t, -t)
        out = np.stack([u, v, zz], axis=-1)
        return (out / np.linalg.norm(out, axis=-1, keepdims=True)).astype(f32)
    raise ValueError(f"unknown normal format {fmt!r}")


def cluster(valid, depth, normal, k: int, threshold: float, depth_weight: float, *, dtype=None):
    """Aggregate index ``(P, N)`` of every sample (-1: sky) by AGAA's published rule (see
    :mod:`raster_models.aa.agaa.model`), in ``dtype`` (float32, the model's precision, by
    default; float64 tells which decisions float32 rounding can flip)."""
    f = np.dtype(dtype or np.float32).type
    v = np.asarray(valid, bool)
    vf = v.astype(f)
    z = np.asarray(depth, f) * vf
    nrm = np.asarray(normal, f)
    cnt = np.maximum(vf.sum(axis=1), f(1))
    z_mean = z.sum(axis=1) / cnt
    z_mean = np.where(z_mean > 0, z_mean, f(1))[:, None]
    n_mean = np.einsum("pn,pnc->pc", vf, nrm) / cnt[:, None]
    w = f(depth_weight)
    low = f(-np.inf)

    def distance(z_b, n_b):
        cos = np.einsum("pnc,pc->pn", nrm, n_b)
        return w * np.abs(z - z_b) / z_mean + (f(1) - cos)

    d_mean = distance(z_mean, n_mean)
    seed1 = np.argmax(np.where(v, d_mean, low), axis=1)
    take = np.arange(len(v))
    d1 = distance(z[take, seed1][:, None], nrm[take, seed1])
    seed2 = np.argmax(np.where(v, d1, low), axis=1)
    d2 = distance(z[take, seed2][:, None], nrm[take, seed2])
    split = (k >= 2) & (d1[take, seed2] > threshold)
    agg = np.where(split[:, None] & (d2 < d1), 1, 0)
    return np.where(v, agg, -1)


def sample_points(scene, x, y) -> dict:
    """The surface points the rays through film positions ``x``, ``y`` meet (the oracle's
    :func:`scenes.backend.raycast.trace_film`): ``valid``, ``position``, ``normal``, ``geo_normal``
    (the shading normal: the test scenes are flat-shaded meshes), view ``depth``."""
    g = trace_film(scene, x, y)
    return {
        "valid": g["valid"],
        "position": g["position"],
        "normal": g["normal"],
        "geo_normal": g["normal"],
        "depth": np.asarray(g["depth"], np.float64),
    }


def agaa_colors(scene, offsets, first, aggregate, *, visibility) -> np.ndarray:
    """AGAA's pixel colours ``(P, 3)`` (float64) from the samples' representative slots
    ``first`` and aggregates ``aggregate`` (``(P, N)``, ``first == N`` for sky): every
    aggregate's attributes averaged over its samples in float64 (each sample adds its
    fragment's attributes at the pixel centre), shaded once with the filtered normal and its
    filtered visibility (the mean over its samples of the ``visibility`` function at each
    sample's own surface point, :func:`sample_points`), weighted by its coverage."""
    n_pix, n = first.shape
    valid = first < n
    frags = group_fragments(valid, first=np.where(valid, first, 0))
    sx, sy = sample_film_positions(frags, offsets, scene.width)
    cx, cy = shading_positions(frags, offsets, scene.width, False, n)
    attrs = fragment_attributes(scene, sx, sy, cx, cy)
    keys = ("albedo", "normal", "position", "to_eye", "geo_normal")
    table = np.concatenate([np.asarray(attrs[key], np.float64) for key in keys], axis=1)
    pix, slot = np.nonzero(valid)
    a_slot = pix * 2 + aggregate[pix, slot]  # at most two aggregates a pixel
    of = frags.of_sample[pix, slot]
    slots, inverse = np.unique(a_slot, return_inverse=True)
    weight = np.bincount(inverse).astype(np.float64)
    sums = np.zeros((len(slots), table.shape[1]))
    np.add.at(sums, inverse, table[of])
    means = sums / weight[:, None]
    agg = {key: means[:, 3 * i : 3 * i + 3] for i, key in enumerate(keys)}
    g = agg["geo_normal"]
    g_len = np.linalg.norm(g, axis=1, keepdims=True)
    agg["geo_normal"] = np.where(g_len > 1e-6, g / np.maximum(g_len, 1e-30), agg["normal"])
    e = agg["to_eye"]
    agg["to_eye"] = e / np.linalg.norm(e, axis=1, keepdims=True)
    agg["offset"] = np.zeros(len(slots))
    np.maximum.at(agg["offset"], inverse, np.asarray(attrs["offset"], np.float64)[of])
    agg["valid"] = np.ones(len(slots), bool)
    agg["depth"] = (agg["position"] - scene.camera.position) @ scene.camera.forward
    offs = np.asarray(offsets, np.float64)
    w = scene.width
    pts = sample_points(scene, pix % w + offs[slot, 0], pix // w + offs[slot, 1])
    vis_s = np.where(pts["valid"], np.asarray(visibility(pts), np.float64), 0.0)
    vis = np.bincount(inverse, weights=vis_s, minlength=len(slots)) / weight
    rgb, _ = shade_points(scene, agg, visibility=vis, filtered_normal=True)
    color = np.zeros((n_pix, 3))
    np.add.at(color, slots // 2, rgb.astype(np.float64) * (weight / n)[:, None])
    return color
