"""Hand-built frame pairs for the rtshadows denoiser transcription tests: a tilted ground in
depth, a near box that moves one pixel right between the frames (the band it uncovers is
disoccluded), camera still otherwise; noisy one-ray visibility and NRD penumbrae from a fixed
seed."""

from __future__ import annotations

import numpy as np
from raster_oracle.raster_models.rtshadows.frames import Frame, gradient_pixels

F32 = np.float32


def _frame(index, h, w, rng, box_x0, previous=None):
    ys, xs = np.mgrid[0:h, 0:w]
    depth = (5.0 + 0.1 * ys + 0.02 * xs).astype(F32)
    box = (xs >= box_x0) & (xs < box_x0 + 5) & (ys >= 4) & (ys < 10)
    depth = np.where(box, F32(2.0), depth).astype(F32)
    valid = ~((ys == 0) & (xs < 3))  # a little sky
    normal = np.zeros((h, w, 3), F32)
    normal[..., 1] = 1.0
    normal[box] = np.array([0.0, 0.6, 0.8], F32)
    pos = np.stack([xs * 0.05, np.zeros_like(depth), depth], -1).astype(F32)
    pos[box, 1] = 0.5
    noisy = (rng.random((h, w)) < np.where(xs < w // 2, 0.8, 0.3)).astype(F32)
    noisy[ys >= h // 2] = 1.0  # a fully lit half: tile classification clears it
    noisy = np.where(valid, noisy, F32(0.0))
    pen = np.where(noisy > 0.5, F32(65504.0), (rng.random((h, w)) * 0.3).astype(F32))
    pen[(ys == 5) & (xs == 1)] = 0.0  # a pixel facing away from the light
    pen = np.where(valid, pen, F32(0.0)).astype(F32)
    motion = np.zeros((h, w, 2))
    # the box moved right by one pixel since the previous frame
    motion[box, 0] = -1.0
    prev_box = (xs >= box_x0 - 1) & (xs < box_x0 + 4) & (ys >= 4) & (ys < 10)
    disocc = ~box & prev_box
    depth_prev = np.where(box, 2.0, depth).astype(F32)
    gidx = gradient_pixels(w, h, index)
    gvalid = np.zeros(gidx.shape, bool)
    if previous is not None:
        gvalid = (gidx % 3 != 1) & valid.ravel()[gidx]
    grad_new = np.where(gvalid, noisy.ravel()[gidx], 0).astype(F32)
    grad_old = np.where(gvalid, rng.random(gidx.shape) < 0.5, 0).astype(F32)
    return Frame(
        index=index,
        noisy=noisy,
        receiver=valid,
        valid=valid,
        depth=np.where(valid, depth, 0).astype(F32),
        position=pos,
        normal=normal,
        n_dot_v=np.where(box, F32(0.8), F32(0.6)).astype(F32),
        motion=motion,
        disoccluded=disocc,
        depth_previous=depth_prev,
        hit_t=np.where(noisy > 0.5, np.inf, 1.0).astype(F32),
        penumbra=pen,
        pixel_size=(0.004 * depth).astype(F32),
        grad_valid=gvalid,
        grad_index=gidx,
        grad_new=grad_new,
        grad_old=grad_old,
        rays=int(valid.sum()),
    )


def frame_pair(h=32, w=24, seed=5):
    """Frames 0 and 1 (``h``, ``w`` multiples of 8 and 3 are convenient)."""
    rng = np.random.default_rng(seed)
    f0 = _frame(0, h, w, rng, 9)
    f1 = _frame(1, h, w, rng, 10, previous=f0)
    return f0, f1
