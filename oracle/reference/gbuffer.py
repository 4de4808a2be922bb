"""The pixel-centre channel groups: ``id``, ``depth``, ``position``, ``normal``, ``albedo``
(one ray through each pixel centre: the G-buffer) and ``tangent32`` (the lit fraction of the
32 FTIZB points on the tangent plane at each centre). No sampling noise, no standard error.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend
from ...scenes.backend.raycast import trace_film_dr
from . import settings
from .settings import CENTRE_GROUPS, CHANNEL_GROUPS, channel_names

__all__ = ["centre_channels", "tangent32_channel"]


def centre_channels(loaded, groups: set[str], progress) -> dict[str, np.ndarray]:
    """G-buffer channels from one ray through each pixel centre."""
    mi = backend.mitsuba()
    import drjit as dr

    h, w = loaded.height, loaded.width
    npix = w * h
    out = {
        name: np.zeros(npix, dtype=np.float32)
        for name in channel_names([g for g in CHANNEL_GROUPS if g in groups and g in CENTRE_GROUPS])
    }
    for start in range(0, npix, settings.SAMPLES_PER_CHUNK):
        idx = dr.arange(mi.UInt32, start, min(npix, start + settings.SAMPLES_PER_CHUNK))
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(loaded, x, y, color=False)
        sl = slice(start, start + dr.width(idx))
        if "id" in groups:
            out["id"][sl] = np.array(res["shape"])
        if "depth" in groups:
            out["depth"][sl] = np.array(res["depth"])
        for g, key, names in (
            ("position", "position", "XYZ"),
            ("normal", "normal", "XYZ"),
            ("albedo", "albedo", "RGB"),
        ):
            if g in groups:
                arr = np.array(res[key])
                valid = np.array(res["valid"])
                for i, c in enumerate(names):
                    out[f"{g}.{c}"][sl] = np.where(valid, arr[i], 0.0)
        if progress is not None:
            progress.update(dr.width(idx))
    return {k: v.reshape(h, w) for k, v in out.items()}


def tangent32_channel(loaded) -> np.ndarray:
    """Lit fraction of the 32 FTIZB points on the tangent plane at each pixel centre.

    The points ``P + a dP/dx + b dP/dy`` (:data:`scenes.geometry.tangent32.TANGENT_POINTS_32`, the
    table the ``izb`` model uses) of the surface seen through the pixel centre, each with the
    oracle's exact shadow ray (offset along the centre's normal as for a surface point of the
    same shape); N.L and the spot cone are evaluated per point with the centre's normal. Sky
    pixels are 1. Exact for those points: no sampling noise.
    """
    mi = backend.mitsuba()
    import drjit as dr

    from ...scenes.backend.alpha_hit import closest_hit_alpha, loaded_alpha
    from ...scenes.backend.raycast import camera_rays_dr, occluded_from_dr
    from ...scenes.geometry.tangent32 import tangent_derivatives_dr, tangent_offsets
    from ...scenes.shading.phong import facing, receiver_mask

    w, h = loaded.width, loaded.height
    npix = w * h
    a_np, b_np = tangent_offsets()
    k_n = len(a_np)
    out = np.zeros(npix, dtype=np.float64)
    per_chunk = max(1, settings.SAMPLES_PER_CHUNK // k_n)
    light = loaded.light
    alpha = loaded_alpha(loaded)  # alpha-tested shapes: cut out (None: plain queries)
    for start in range(0, npix, per_chunk):
        stop = min(npix, start + per_chunk)
        idx = dr.arange(mi.UInt32, (stop - start) * k_n)
        pix = idx // k_n + start
        k = idx % k_n
        x = mi.Float(pix % w) + 0.5
        y = mi.Float(pix // w) + 0.5
        ray = camera_rays_dr(loaded.camera, x, y)
        si, _, _ = closest_hit_alpha(
            loaded.mi_scene, ray, alpha, flags=mi.RayFlags.All, coherent=True
        )
        valid = si.is_valid()
        n = facing(si.sh_frame.n, -ray.d)
        dpdx, dpdy = tangent_derivatives_dr(loaded.camera, x, y, si.p, n)
        a = dr.gather(mi.Float, mi.Float(a_np), k)
        b = dr.gather(mi.Float, mi.Float(b_np), k)
        q = si.p + dpdx * a + dpdy * b
        wl, _ = light.to_light(q)
        candidate = receiver_mask(valid=valid, cos_l=dr.dot(n, wl), to_light=wl, light=light)
        blocked = occluded_from_dr(
            loaded.mi_scene, light, q, si.n, wl, si.shape, candidate, alpha=alpha
        )
        lit = dr.select(valid, dr.select(candidate & ~blocked, 1.0, 0.0), 1.0)
        total = dr.block_reduce(dr.ReduceOp.Add, lit, k_n, mode="evaluated")
        dr.eval(total)
        out[start:stop] = np.array(total, dtype=np.float64) / k_n
    return out.reshape(h, w).astype(np.float32)
