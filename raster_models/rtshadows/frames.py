"""One frame of a ray-traced shadow's inputs: the G-buffer at pixel centres, one shadow ray a
pixel (:mod:`.rays`), the oracle's exact motion vectors and disocclusion, and A-SVGF's
gradient samples. What every denoiser of :mod:`raster_models.rtshadows` reads.

Conventions: images ``(H, W)``, row 0 at the top; ``motion`` is the oracle's (the previous
film position of the point seen through the pixel centre minus that centre, pixels, x right,
y down: :func:`scenes.geometry.motion.film_motion`); each denoiser converts it to its source's
convention. ``noisy`` is 1 where the pixel's ray reaches the light.

A-SVGF's gradient samples (Schied et al. 2018, section 4): the frame is split into 3 x 3
strata; in each, one pixel (chosen by a hash of the stratum and the frame) whose reprojected
previous pixel ``q`` (the nearest pixel to ``p + motion``) is on screen and not disoccluded
re-traces ``q``'s previous-frame ray sample (its noise value) from its own current surface
point. That sample replaces the pixel's own (``noisy``): still one ray a pixel, still an
unbiased sample. ``grad_new`` is it, ``grad_old`` ``q``'s previous noisy value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scenes.backend.raycast import intersect
from ...scenes.geometry.motion import film_motion
from ..gbuffer import trace_gbuffer
from .rays import F32, frame_rays

__all__ = ["STRATUM", "Frame", "build_frame", "gradient_pixels"]

#: A-SVGF's stratum size (Schied et al. 2018: 3 x 3).
STRATUM = 3


@dataclass
class Frame:
    """A frame's denoiser inputs (see the module docstring). ``pixel_size``: world size of a
    pixel at the surface's view depth (NRD's ``PixelRadiusToWorld``); ``n_dot_v`` the cosine
    between the normal and the direction to the eye; ``grad_*`` ``(Hs, Ws)``
    on the stratum grid (``grad_valid`` False where a stratum has no gradient sample,
    ``grad_index`` the flat pixel index of each stratum's sample)."""

    index: int
    noisy: np.ndarray
    receiver: np.ndarray
    valid: np.ndarray
    depth: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    n_dot_v: np.ndarray
    motion: np.ndarray
    disoccluded: np.ndarray
    depth_previous: np.ndarray
    hit_t: np.ndarray
    penumbra: np.ndarray
    pixel_size: np.ndarray
    grad_valid: np.ndarray
    grad_index: np.ndarray
    grad_new: np.ndarray
    grad_old: np.ndarray
    rays: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.noisy.shape


def gradient_pixels(width: int, height: int, frame: int) -> np.ndarray:
    """``(Hs, Ws)`` flat pixel index of each 3 x 3 stratum's gradient pixel at ``frame``: a
    multiplicative hash of (stratum, frame) picks one of the stratum's (clipped) pixels."""
    hs, ws = -(-height // STRATUM), -(-width // STRATUM)
    sy, sx = np.meshgrid(np.arange(hs), np.arange(ws), indexing="ij")
    key = (sy.astype(np.uint64) * np.uint64(73856093)) ^ (
        sx.astype(np.uint64) * np.uint64(19349663)
    )
    key = key ^ (np.uint64(frame) * np.uint64(83492791))
    pick = ((key * np.uint64(2654435761)) >> np.uint64(16)) % np.uint64(STRATUM * STRATUM)
    pick = pick.astype(np.int64)
    y = np.minimum(sy * STRATUM + pick // STRATUM, height - 1)
    x = np.minimum(sx * STRATUM + pick % STRATUM, width - 1)
    return y * width + x


def _pixel_size(camera, depth: np.ndarray) -> np.ndarray:
    if camera.kind == "perspective":
        return (2.0 * camera.tan_half_x / camera.width) * depth
    half = float(np.linalg.norm(np.asarray(camera.to_world)[:3, 0]))
    return np.full_like(depth, 2.0 * half / camera.width)


def _trace(scene, rays):
    hit = intersect(scene, rays.origin, rays.direction, tmax=rays.tmax)
    return np.where(hit["valid"].astype(bool), hit["t"], np.inf).astype(F32)


def build_frame(scene, index: int, previous: Frame | None) -> Frame:
    """The inputs of frame ``index`` of ``scene`` (the scene already at that frame);
    ``previous`` the frame before (None at the first frame: no gradient samples)."""
    cam = scene.camera
    w, h = cam.width, cam.height
    g = trace_gbuffer(scene)
    ys, xs = np.divmod(np.arange(w * h), w)
    mo = film_motion(scene, xs + 0.5, ys + 0.5)
    recv = g.receiver & g.valid
    sel = np.flatnonzero(recv)
    noise_px, noise_py = xs[sel], ys[sel]
    noise_frame = np.full(sel.size, index)
    gidx = gradient_pixels(w, h, index)
    gvalid = np.zeros(gidx.shape, dtype=bool)
    gold = np.zeros(gidx.shape, dtype=F32)
    if previous is not None:
        mx, my = mo["motion_x"][gidx], mo["motion_y"][gidx]
        qx = np.floor(xs[gidx] + 0.5 + mx).astype(np.int64)
        qy = np.floor(ys[gidx] + 0.5 + my).astype(np.int64)
        inside = (qx >= 0) & (qx < w) & (qy >= 0) & (qy < h)
        q = np.where(inside, qy * w + qx, 0)
        gvalid = inside & recv[gidx] & ~mo["disoccluded"][gidx] & previous.receiver.ravel()[q]
        gold = np.where(gvalid, previous.noisy.ravel()[q], 0).astype(F32)
        # the gradient pixels trace q's previous noise (A-SVGF's reused random numbers)
        pos_in_sel = np.searchsorted(sel, gidx[gvalid])
        noise_px[pos_in_sel], noise_py[pos_in_sel] = qx[gvalid], qy[gvalid]
        noise_frame[pos_in_sel] = index - 1
    rays = _frame_rays(scene.light, g, sel, noise_px, noise_py, noise_frame)
    hit_t = np.full(w * h, np.inf, dtype=F32)
    hit_t[sel] = _trace(scene, rays)
    noisy = np.where(recv, np.isinf(hit_t), 0).astype(F32)
    penumbra = np.full(w * h, 0.0, dtype=F32)
    penumbra[sel] = rays.pack(hit_t[sel])
    depth = np.where(g.valid, g.depth, 0.0)
    if cam.kind == "perspective":
        to_eye = cam.position - g.position
        to_eye /= np.maximum(np.linalg.norm(to_eye, axis=1), 1e-30)[:, None]
    else:
        to_eye = np.broadcast_to(-cam.forward, g.position.shape)
    n_dot_v = np.where(g.valid, np.einsum("ij,ij->i", to_eye, g.normal), 0.0)
    return Frame(
        index=index,
        noisy=noisy.reshape(h, w),
        receiver=recv.reshape(h, w),
        valid=g.valid.reshape(h, w),
        depth=depth.astype(F32).reshape(h, w),
        position=g.position.astype(F32).reshape(h, w, 3),
        normal=g.normal.astype(F32).reshape(h, w, 3),
        n_dot_v=n_dot_v.astype(F32).reshape(h, w),
        motion=np.stack([mo["motion_x"], mo["motion_y"]], -1).reshape(h, w, 2),
        disoccluded=mo["disoccluded"].reshape(h, w),
        depth_previous=mo["depth_previous"].reshape(h, w),
        hit_t=hit_t.reshape(h, w),
        penumbra=penumbra.reshape(h, w),
        pixel_size=_pixel_size(cam, depth).astype(F32).reshape(h, w),
        grad_valid=gvalid,
        grad_index=gidx,
        grad_new=np.where(gvalid, noisy[gidx], 0).astype(F32),
        grad_old=gold,
        rays=int(sel.size),
    )


def _frame_rays(light, g, sel, px, py, frames):
    """The rays of the receivers ``sel``, each with its own noise pixel and frame (one call
    to :func:`.rays.frame_rays` per distinct frame: the current one and, for A-SVGF's gradient
    samples, the previous)."""
    rays = frame_rays(light, g.position[sel], g.normal[sel], px, py, int(frames.max(initial=0)))
    for f in np.unique(frames):
        if f == frames.max(initial=0):
            continue
        m = frames == f
        other = frame_rays(light, g.position[sel][m], g.normal[sel][m], px[m], py[m], int(f))
        rays.direction[m], rays.tmax[m] = other.direction, other.tmax
    return rays
