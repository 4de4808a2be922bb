"""The depth prepass / G-buffer a shadow technique shades: one sample at every pixel centre.

Built on :func:`scenes.raycast.trace_film_dr` (the oracle's own primary-ray path), evaluating
only what a shadow technique reads, plus the screen-space derivatives of the visible
position, ``dP/dx`` and ``dP/dy`` (world units per pixel), computed exactly on the tangent
plane of the visible surface (ray differentials): what a GPU's ``ddx/ddy`` of the
interpolated position gives on a planar triangle. They feed the Jacobian of shadow-texel
coordinates with respect to screen pixels (resolution error, receiver-plane bias). Like a
GPU G-buffer, values are float32 (returned as float64 arrays).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes import backend
from scenes.raycast import CHUNK, trace_film_dr

__all__ = ["GBuffer", "trace_gbuffer"]


@dataclass
class GBuffer:
    """Flat ``(H*W,)`` pixel arrays (row-major, row 0 at the top).

    ``receiver`` = valid, facing the light (N.L > 0) and, for a spot light, inside its cone:
    the pixels a shadow technique must answer for (the oracle's ``lit`` is False elsewhere).
    ``lit`` (the oracle's exact shadow ray at the pixel centre) is only filled with
    ``with_lit=True``; models never read it.
    """

    width: int
    height: int
    valid: np.ndarray
    depth: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    cos_l: np.ndarray
    receiver: np.ndarray
    dpdx: np.ndarray
    dpdy: np.ndarray
    lit: np.ndarray | None = None

    @property
    def size(self) -> int:
        return self.width * self.height

    def image(self, flat: np.ndarray) -> np.ndarray:
        return np.asarray(flat, dtype=np.float32).reshape(self.height, self.width)


def _vec(mi, a):
    return mi.Vector3f(float(a[0]), float(a[1]), float(a[2]))


def trace_gbuffer(scene, camera=None, *, with_lit: bool = False) -> GBuffer:
    """G-buffer of ``camera`` (default: the scene's) at every pixel centre."""
    mi = backend.mitsuba()
    import drjit as dr

    camera = camera or scene.camera
    w, h = camera.width, camera.height
    n_pix = w * h
    m = np.asarray(camera.to_world, dtype=np.float64)
    rot = m[:3, :3]
    # d(local ray)/d(film x, y) from Camera.local_ray: sx = 1 - 2x/W, sy = (1 - 2y/H)/aspect.
    dsx, dsy = -2.0 / w, -2.0 / (h * camera.aspect)
    if camera.kind == "perspective":
        t = camera.tan_half_x
        dd_x, dd_y = rot @ np.array([dsx * t, 0, 0]), rot @ np.array([0, dsy * t, 0])
        do_x = do_y = np.zeros(3)
    else:
        dd_x = dd_y = np.zeros(3)
        do_x, do_y = rot @ np.array([dsx, 0, 0]), rot @ np.array([0, dsy, 0])
    out = {k: np.empty(n_pix, dtype=np.float32) for k in ("depth", "cos_l")} | {
        k: np.empty((n_pix, 3), dtype=np.float32) for k in ("p", "n", "dpdx", "dpdy")
    }
    valid_out = np.empty(n_pix, dtype=bool)
    cone_out = np.empty(n_pix, dtype=bool)
    lit_out = np.empty(n_pix, dtype=bool) if with_lit else None
    for start in range(0, n_pix, CHUNK):
        stop = min(n_pix, start + CHUNK)
        idx = dr.arange(mi.UInt32, start, stop)
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(scene, x, y, color=False, camera=camera)
        valid = res["valid"]
        p = res["position"]
        n = res["normal"]
        (ox, oy, oz), (dx, dy, dz) = camera.local_ray(x, y)
        o_l = mi.Vector3f(ox, oy, oz)
        d_l = mi.Vector3f(dx, dy, dz)
        r = [[float(rot[i, j]) for j in range(3)] for i in range(3)]

        def to_world(v, r=r):
            return mi.Vector3f(
                r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z,
                r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
                r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z,
            )

        d = to_world(d_l)
        o = to_world(o_l) + _vec(mi, m[:3, 3])
        nd = dr.dot(n, d)
        nd = dr.select(dr.abs(nd) > 1e-12, nd, 1e-12)
        tau = dr.dot(n, p - o) / nd
        derivs = []
        for do, dd in ((do_x, dd_x), (do_y, dd_y)):
            do_v, dd_v = _vec(mi, do), _vec(mi, dd)
            dtau = -(dr.dot(n, do_v) + tau * dr.dot(n, dd_v)) / nd
            derivs.append(dr.select(valid, do_v + d * dtau + dd_v * tau, mi.Vector3f(0.0)))
        wl, _ = scene.light.to_light(p)
        cone = scene.light.in_cone(wl)
        evals = [valid, p, n, res["depth"], res["cos_l"], cone, *derivs]
        if with_lit:
            evals.append(res["lit"])
        dr.eval(*evals)
        sl = slice(start, stop)
        valid_out[sl] = np.array(valid)
        out["p"][sl] = np.array(p).T
        out["n"][sl] = np.array(n).T
        out["depth"][sl] = np.array(res["depth"])
        out["cos_l"][sl] = np.array(res["cos_l"])
        cone_out[sl] = np.array(cone)
        out["dpdx"][sl] = np.array(derivs[0]).T
        out["dpdy"][sl] = np.array(derivs[1]).T
        if with_lit:
            lit_out[sl] = np.array(res["lit"])
    valid = valid_out
    pos = np.where(valid[:, None], out["p"], 0.0).astype(np.float64)
    nrm = np.where(valid[:, None], out["n"], 0.0).astype(np.float64)
    cos_l = np.where(valid, out["cos_l"], 0.0).astype(np.float64)
    depth = np.where(valid, out["depth"], 0.0).astype(np.float64)
    receiver = valid & (cos_l > 0.0) & cone_out
    return GBuffer(
        width=w,
        height=h,
        valid=valid,
        depth=depth,
        position=pos,
        normal=nrm,
        cos_l=cos_l,
        receiver=receiver,
        dpdx=out["dpdx"].astype(np.float64),
        dpdy=out["dpdy"].astype(np.float64),
        lit=lit_out,
    )
