"""The depth prepass / G-buffer a shadow technique shades: one sample at every pixel centre.

Built on :func:`scenes.backend.raycast.trace_film_dr` (the oracle's own primary-ray path),
evaluating
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

from ..scenes import backend
from ..scenes.backend.raycast import CHUNK, trace_film_dr
from ..scenes.shading.phong import receiver_mask
from .drjit import numpy_view

__all__ = ["GBuffer", "points_gbuffer", "plane_derivatives", "trace_gbuffer"]


@dataclass
class GBuffer:
    """Flat ``(H*W,)`` pixel arrays (row-major, row 0 at the top).

    ``receiver`` = valid, facing the light (N.L > 0) and, for a spot light, inside its cone:
    the pixels a shadow technique must answer for (the oracle's ``lit`` is False elsewhere).
    ``lit`` (the oracle's exact shadow ray at the pixel centre) is only filled with
    ``with_lit=True``; models never read it. ``shape`` (index into the scene's shapes) and
    ``prim`` (primitive within the shape: a mesh's face) of the visible surface, -1 where
    nothing was hit, are filled by :func:`trace_gbuffer` (``None`` for arbitrary points).
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
    shape: np.ndarray | None = None
    prim: np.ndarray | None = None

    @property
    def size(self) -> int:
        return self.width * self.height

    def image(self, flat: np.ndarray) -> np.ndarray:
        return np.asarray(flat, dtype=np.float32).reshape(self.height, self.width)


def plane_derivatives(camera, position, geo_normal) -> tuple[np.ndarray, np.ndarray]:
    """``dP/dx``, ``dP/dy`` (world units per pixel, ``(N, 3)`` float64) on the planes through
    world points ``position`` with geometric normals ``geo_normal`` (``(N, 3)``): the ray
    differentials of ``camera``'s pixel grid, in float64 (:func:`trace_gbuffer` computes the
    same in its kernel, at pixel centres)."""
    m = np.asarray(camera.to_world, np.float64)
    rot = m[:3, :3]
    w, h = camera.width, camera.height
    dsx, dsy = -2.0 / w, -2.0 / (h * camera.aspect)
    cam_o = m[:3, 3]
    if camera.kind == "perspective":
        t = camera.tan_half_x
        dd = [rot @ np.array([dsx * t, 0, 0]), rot @ np.array([0, dsy * t, 0])]
        do = [np.zeros(3), np.zeros(3)]
        d = position - cam_o
        tau = np.ones(len(position))
    else:
        dd = [np.zeros(3), np.zeros(3)]
        do = [rot @ np.array([dsx, 0, 0]), rot @ np.array([0, dsy, 0])]
        d = np.broadcast_to(rot[:, 2], position.shape)
        tau = np.zeros(len(position))
    nd = np.sum(geo_normal * d, axis=1)
    nd = np.where(np.abs(nd) > 1e-12, nd, 1e-12)
    out = []
    for o_k, d_k in zip(do, dd, strict=True):
        dtau = -((geo_normal @ o_k) + tau * (geo_normal @ d_k)) / nd
        out.append(o_k[None, :] + d * dtau[:, None] + d_k[None, :] * tau[:, None])
    return out[0], out[1]


def points_gbuffer(scene, *, position, normal, geo_normal, depth, valid) -> GBuffer:
    """A G-buffer of ``N`` arbitrary shading points (one row of ``N`` "pixels"), e.g. the
    fragments of an anti-aliasing model, for a shadow technique to shade.

    Parameters
    ----------
    scene : scenes.LoadedScene (its camera and light).
    position, normal, geo_normal : ``(N, 3)`` world points, shading and geometric normals.
    depth : ``(N,)`` view depth (camera units along its forward axis).
    valid : ``(N,)`` bool, False where no surface was hit.

    ``cos_l``, ``receiver`` (valid, N.L > 0, inside a spot light's cone) and the screen
    derivatives (:func:`plane_derivatives`) are computed here, in float64.
    """
    pos = np.asarray(position, np.float64)
    nrm = np.asarray(normal, np.float64)
    valid = np.asarray(valid, bool)
    wl, _ = scene.light.to_light(pos)
    cos_l = np.where(valid, np.sum(nrm * wl, axis=1), 0.0)
    dpdx, dpdy = plane_derivatives(scene.camera, pos, np.asarray(geo_normal, float))
    return GBuffer(
        width=len(pos),
        height=1,
        valid=valid,
        depth=np.asarray(depth, np.float64),
        position=pos,
        normal=nrm,
        cos_l=cos_l,
        receiver=receiver_mask(valid=valid, cos_l=cos_l, to_light=wl, light=scene.light),
        dpdx=dpdx,
        dpdy=dpdy,
    )


def _vec(mi, a):
    import drjit as dr

    # Kernel parameters, not literals: one compiled kernel serves every camera.
    return mi.Vector3f(*(dr.opaque(mi.Float, float(a[k])) for k in range(3)))


def _surface_derivatives_dr(mi, camera, x, y, p, n, valid) -> list:
    """dP/dx and dP/dy (Dr.Jit vectors, 0 at invalid pixels) of the visible surface's plane
    at film points ``(x, y)``: the camera ray's derivatives intersected with the plane of
    the hit ``p`` with normal ``n``."""
    import drjit as dr

    dd_x, dd_y, do_x, do_y = camera.film_derivatives()
    (ox, oy, oz), (dx, dy, dz) = camera.local_ray(x, y)
    o_l = mi.Vector3f(ox, oy, oz)
    d_l = mi.Vector3f(dx, dy, dz)
    m = np.asarray(camera.to_world, dtype=np.float64)
    rot = m[:3, :3]
    r = [[dr.opaque(mi.Float, float(rot[i, j])) for j in range(3)] for i in range(3)]

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
    return derivs


def trace_gbuffer(scene, camera=None, *, with_lit: bool = False) -> GBuffer:
    """G-buffer of ``camera`` (default: the scene's) at every pixel centre."""
    mi = backend.mitsuba()
    import drjit as dr

    camera = camera or scene.camera
    w, h = camera.width, camera.height
    n_pix = w * h
    # float32 values (as a GPU G-buffer) widened to float64 inside the kernel; invalid pixels 0.
    # One launch (up to CHUNK pixels, 1080p included): its evaluated 1-D arrays become the
    # G-buffer's (NumPy views); (N, 3) fields and several launches are copied.
    single = n_pix <= CHUNK
    if single:
        out: dict = {}
    else:
        out = {k: np.empty(n_pix, dtype=np.float64) for k in ("depth", "cos_l")} | {
            k: np.empty((n_pix, 3), dtype=np.float64) for k in ("p", "n", "dpdx", "dpdy")
        }
        out |= {k: np.empty(n_pix, dtype=bool) for k in ("valid", "receiver")}
        out |= {k: np.empty(n_pix, dtype=np.int32) for k in ("shape", "prim")}
        if with_lit:
            out["lit"] = np.empty(n_pix, dtype=bool)
    for start in range(0, n_pix, CHUNK):
        stop = min(n_pix, start + CHUNK)
        idx = dr.arange(mi.UInt32, start, stop)
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(scene, x, y, color=False, camera=camera)
        valid = res["valid"]
        p = res["position"]
        n = res["normal"]
        derivs = _surface_derivatives_dr(mi, camera, x, y, p, n, valid)
        wl, _ = scene.light.to_light(p)
        f64 = mi.Float64

        def wide(a, valid=valid, f64=f64):
            return f64(dr.select(valid, a, 0.0))

        cols = {
            "p": [wide(c) for c in (p.x, p.y, p.z)],
            "n": [wide(c) for c in (n.x, n.y, n.z)],
            "dpdx": [f64(c) for c in (derivs[0].x, derivs[0].y, derivs[0].z)],
            "dpdy": [f64(c) for c in (derivs[1].x, derivs[1].y, derivs[1].z)],
            "depth": wide(res["depth"]),
            "cos_l": wide(res["cos_l"]),
        }
        receiver = receiver_mask(valid=valid, cos_l=res["cos_l"], to_light=wl, light=scene.light)
        arrays = {
            "depth": cols["depth"],
            "cos_l": cols["cos_l"],
            "valid": valid,
            "receiver": receiver,
            "shape": res["shape"],
            "prim": res["prim"],
        }
        if with_lit:
            arrays["lit"] = res["lit"]
        vectors = {key: cols[key] for key in ("p", "n", "dpdx", "dpdy")}
        dr.eval(*arrays.values(), *[c for v in vectors.values() for c in v])
        sl = slice(start, stop)
        if single:
            # Interleaved (N, 3) by Dr.Jit from the evaluated columns: cheaper than three
            # strided NumPy writes into freshly allocated memory.
            flat = {key: dr.ravel(mi.Vector3d(*val)) for key, val in vectors.items()}
            dr.eval(*flat.values())
            out |= {key: numpy_view(val).reshape(n_pix, 3) for key, val in flat.items()}
        else:
            for key, val in vectors.items():
                for k in range(3):
                    out[key][sl, k] = numpy_view(val[k])
        for key, val in arrays.items():
            if single:
                out[key] = numpy_view(val)
            else:
                out[key][sl] = numpy_view(val)
    valid = out["valid"]
    pos, nrm, cos_l, depth = out["p"], out["n"], out["cos_l"], out["depth"]
    receiver = out["receiver"]
    return GBuffer(
        width=w,
        height=h,
        valid=valid,
        depth=depth,
        position=pos,
        normal=nrm,
        cos_l=cos_l,
        receiver=receiver,
        dpdx=out["dpdx"],
        dpdy=out["dpdy"],
        lit=out.get("lit"),
        shape=out["shape"],
        prim=out["prim"],
    )
