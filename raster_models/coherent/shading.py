"""Coherent shadow maps' lookup (the paper's shader): per receiver, its light travel
direction -> ``(u, v)`` -> the id texture -> that map's matrix -> a point depth test
``z - bias <= stored``.

Receivers outside the map's square are lit (the sphere holds every caster). Point lights: a
stored depth nearer than the light's own depth in the map does not shadow (the light is
inside the sphere); a caster hidden behind such a surface is then missed (the paper's
objects lie outside the light).

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
.. [2] X. Tijsen (xaviert.be), "Coherent Shadow Maps: Uncompressed Algorithm", 2010 (lookup:
   direction -> id texture -> matrix texture -> depth test).
"""

from __future__ import annotations

import numpy as np

from .directions import uv

__all__ = ["DIRECTIONAL_ROWS", "direction_error", "lookup", "project", "shade", "travel"]


def travel(scene, pos: np.ndarray) -> np.ndarray:
    """Unit light travel directions ``(M, 3)`` at world points ``pos``: the directional
    light's direction, or from the point light to each point."""
    light = scene.light
    if light.kind == "directional":
        d = np.asarray(light.direction, dtype=np.float64)
        return np.broadcast_to(d / np.linalg.norm(d), pos.shape).copy()
    w = pos - np.asarray(light.position, dtype=np.float64)
    return w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)


#: Receivers a directional light's lookup is evaluated on (every receiver has the same
#: travel direction): a strided slice of the same layout as the full arrays, so NumPy
#: takes the same loops and the values are the full evaluation's.
DIRECTIONAL_ROWS = 64


def lookup(scene, pos: np.ndarray, id_tex: np.ndarray):
    """Light travel directions ``w`` of receivers at ``pos``, the map ids ``sel`` they look
    up in the id texture, and whether all receivers share them (a directional light: then
    ``w`` and ``sel`` are read-only broadcasts of the first receiver's)."""
    g = id_tex.shape[0]
    shared = scene.light.kind == "directional" and len(pos) > 0
    part = pos[:DIRECTIONAL_ROWS] if shared else pos
    w = travel(scene, part) if len(part) else np.zeros((0, 3))
    u, v = uv(w)
    ci = np.minimum((u * g).astype(np.int64), g - 1)
    cj = np.minimum((v * g).astype(np.int64), g - 1)
    sel = id_tex[cj, ci]
    if shared:
        return np.broadcast_to(w[:1], pos.shape), np.broadcast_to(sel[:1], len(pos)), True
    return w, sel, False


def direction_error(w: np.ndarray, dirs: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """Angle in degrees between travel directions ``w`` and their maps' directions."""
    cosang = np.clip(np.sum(w * dirs[sel], axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(cosang))


def project(scene, gbuf, projs, rec: np.ndarray, pos, sel, used, *, bias, normal_offset):
    """Where the receivers ``rec`` (at ``pos``, looking up maps ``sel``; ``used`` the sorted
    distinct ``sel``) fall in their maps: per map ``(m, mask, texel, ref, zl, inside)``
    (receivers, texel index, compare reference ``z - bias``, the light's own depth,
    inside the map's square), and which receivers lie outside their map.

    ``bias``: normalized depth (fraction of the sphere's diameter); ``normal_offset``:
    texels, the lookup moves by ``normal_offset * texel * saturate(1 - N.L) * N``."""
    n_dot_l = np.clip(gbuf.cos_l[rec], 0.0, 1.0) if normal_offset > 0.0 else None
    outside = np.zeros(len(rec), dtype=bool)
    r = projs.resolution
    records = []
    for m in used:
        # One map for every receiver (a directional light): no masking copies.
        mask = slice(None) if len(used) == 1 else sel == m
        proj = projs[int(m)]
        q = pos[mask]
        if normal_offset > 0.0:
            scale = normal_offset * proj.texel_world_size() * (1.0 - n_dot_l[mask])
            q = q + gbuf.normal[rec[mask]] * scale[:, None]
        tu, tv, tz, _ = proj.project(q)
        inside = (tu >= 0) & (tu < 1) & (tv >= 0) & (tv < 1)
        outside[mask] = ~inside
        texel = np.clip((tv * r).astype(np.int64), 0, r - 1) * r + np.clip(
            (tu * r).astype(np.int64), 0, r - 1
        )
        ref = tz - bias
        zl = -np.inf
        if scene.light.kind != "directional":
            zl = float(proj.project(np.asarray(scene.light.position, dtype=np.float64)[None])[2][0])
        records.append((int(m), mask, texel, ref, zl, inside))
    return records, outside


def shade(records: list, maps: dict, n_rec: int) -> dict:
    """Visibility of the receivers of :func:`project` per set of maps: the depth test
    ``z - bias <= stored`` (a stored depth nearer than a point light's own does not
    shadow; outside the map: lit)."""
    vis = {k: np.ones(n_rec) for k in maps}
    for m, mask, texel, ref, zl, inside in records:
        for key, depth in maps.items():
            stored = depth[m][texel].astype(np.float64)
            shadow = (ref > stored) & (stored > zl) & inside
            vis[key][mask] = np.where(shadow, 0.0, 1.0)
    return vis
