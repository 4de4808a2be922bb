"""AMD FidelityFX shadow denoiser, transcribed (vectorised NumPy, float32).

Source: GPUOpen-LibrariesAndSDKs/FidelityFX-SDK v1.1.4, commit
c6efa6bf7f2027b3ec94f28578bb5965eabb9e55, ``sdk/include/FidelityFX/gpu/denoiser/``:

- ray masks: one 32-bit mask a tile of 8 x 4 pixels, bit ``(y % 4) * 8 + x % 8`` set where
  the ray reached the light (``ffx_denoiser_shadows_util.h:41-45``; ``HitsLight`` is the
  negated hit mask, ``ffx_denoiser_shadows_callbacks_hlsl.h:198-201``);
- tile classification (``ffx_denoiser_shadows_tileclassification.h``): 8 x 8 groups; a group
  with no receiver is cleared to 0; one whose masks over tiles ``x-1..x+1``, ``y-2..y+3``
  (clamped) are all lit or all shadowed is cleared to that value (lines 47-84, 309-337);
- local moments: the 17 x 17 separable kernel ``exp(-3 i^2 / 81)`` (normalised) over the mask
  bits, rows outside the image and masks beyond a tile row's ends being 0 (lines 171-292); its
  mean is also its second moment (one bit a pixel);
- temporal pass (lines 340-423): the nearest-depth velocity of the 2 x 2 quad; disocclusion
  when the previous uv leaves ``(0, 1)`` or the relative linear-depth difference reaches
  ``lerp(1e-2, 1e-1, (1 - v.n)^8)`` (lines 96-135); Welford moments with a sample count; the
  history (bilinear, clamped) clamped to ``mean +- 0.5 sigma``; the count damped by
  ``exp(-d^2 / 20)``, ``d = (history - mean) / max(0.5 sigma, 0.001)``; variance boosted by
  ``max(16 - n, 1)`` under 16 samples; blend ``lerp(clamped, current, lerp(0.05, 1,
  sqrt(max(8 - n, 0) / 8)))``;
- three a-trous passes of steps 1, 2, 4 (``ffx_denoiser_shadows_filter.h``): 3 x 3 taps with
  kernel ``{1, 2/3, 1/6}``, weights ``exp(-|s - s_c| / sigma)`` (sigma from the 3 x 3
  ``{1/4, 1/8, 1/16}`` filtered variance plus 1e-9), ``exp(-|z - z_c| / depthSimilaritySigma)``
  (1.0 in the hybrid-shadows sample, ``hybridshadowsrendermodule.cpp:683``),
  ``saturate(n . n_c)^32``, sky neighbours and the centre excluded (the centre enters with
  weight 1); input and normals stored as float16 (``PackFloat16``); pass 0's result is the
  next frame's history (lines 285-297);
- final contrast remap ``mean^max(1.2 - variance, 1)`` (lines 321-323).

Not modelled: pass 1 leaves a cleared tile's intermediate texel unwritten on the GPU (last
frame's value); here it holds the cleared value. Mask lanes outside the image read 0. Values
stored as float16 saturate at 65504 (a damped sample count can make the Welford variance
``M2 / (n - 1)`` overflow float16; infinity would turn into NaN in the weights).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FfxState", "KERNEL_RADIUS", "ffx_step", "kernel_weights", "local_moments"]

F32 = np.float32
KERNEL_RADIUS = 8
#: filter.h: 3 x 3 variance kernel and the a-trous taps.
VARIANCE_KERNEL = np.array([[1 / 4, 1 / 8], [1 / 8, 1 / 16]], dtype=F32)
ATROUS_KERNEL = np.array([1.0, 2.0 / 3.0, 1.0 / 6.0], dtype=F32)
STEPS = (1, 2, 4)
DEPTH_SIGMA = F32(1.0)
#: The largest float16: stored values saturate there (an early frame's variance can exceed it).
F16_MAX = F32(65504.0)


@dataclass
class FfxState:
    """The denoiser's buffers carried to the next frame."""

    moments: np.ndarray  # (H, W, 3) mean, M2, sample count
    history: np.ndarray  # (H, W, 2) pass 0's (mean, variance)
    depth: np.ndarray  # (H, W) linear depth (inf: sky)


def kernel_weights() -> np.ndarray:
    """``KERNEL_WEIGHT(i) / sum`` for ``i = 0..8`` (tileclassification.h:171-187)."""
    i = np.arange(KERNEL_RADIUS + 1, dtype=np.float64)
    w = np.exp(-3.0 * i * i / ((KERNEL_RADIUS + 1.0) ** 2)).astype(F32)
    total = F32(w[0] + F32(2.0) * np.sum(w[1:], dtype=F32))
    return (w / total).astype(F32)


def _pad_to(a: np.ndarray, ty: int, tx: int) -> np.ndarray:
    h, w = a.shape
    return np.pad(a, ((0, -h % ty), (0, -w % tx)))


def local_moments(bits: np.ndarray) -> np.ndarray:
    """The 17 x 17 local mean of the lit bits ``(H, W)`` (zero outside the image)."""
    k = kernel_weights()
    full = np.concatenate([k[::-1], k[1:]])
    h, w = bits.shape
    b = np.pad(bits.astype(F32), ((KERNEL_RADIUS, KERNEL_RADIUS), (KERNEL_RADIUS, KERNEL_RADIUS)))
    horiz = np.zeros((h + 2 * KERNEL_RADIUS, w), dtype=F32)
    for i, wi in enumerate(full):
        horiz += wi * b[:, i : i + w]
    out = np.zeros((h, w), dtype=F32)
    for i, wi in enumerate(full):
        out += wi * horiz[i : i + h]
    return out


def _classify(bits: np.ndarray, valid: np.ndarray):
    """Per 8 x 8 group: ``(skip_sky, all_in_light, all_in_shadow)`` ``(Gh, Gw)`` booleans."""
    b = _pad_to(bits, 4, 8)
    th, tw = b.shape[0] // 4, b.shape[1] // 8
    tiles = b.reshape(th, 4, tw, 8)
    tile_all = tiles.all(axis=(1, 3))
    tile_any = tiles.any(axis=(1, 3))
    gh, gw = -(-bits.shape[0] // 8), -(-bits.shape[1] // 8)
    gy, gx = np.meshgrid(np.arange(gh), np.arange(gw), indexing="ij")
    all_l = np.ones((gh, gw), dtype=bool)
    any_l = np.zeros((gh, gw), dtype=bool)
    for j in range(-2, 4):
        for i in range(-1, 2):
            ty = np.clip(2 * gy + j, 0, th - 1)
            tx = np.clip(gx + i, 0, tw - 1)
            all_l &= tile_all[ty, tx]
            any_l |= tile_any[ty, tx]
    v = _pad_to(valid, 8, 8).reshape(gh, 8, gw, 8)
    return ~v.any(axis=(1, 3)), all_l, ~any_l


def _group_map(a: np.ndarray, h: int, w: int) -> np.ndarray:
    return np.repeat(np.repeat(a, 8, axis=0), 8, axis=1)[:h, :w]


def _bilinear_clamp(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``SampleLevel`` with a linear, clamped sampler at uv ``(u, v)``."""
    h, w = img.shape
    x = u * F32(w) - F32(0.5)
    y = v * F32(h) - F32(0.5)
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0).astype(F32), (y - y0).astype(F32)
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)

    def at(yy, xx):
        return img[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]

    top = at(y0, x0) * (1 - fx) + at(y0, x0 + 1) * fx
    bot = at(y0 + 1, x0) * (1 - fx) + at(y0 + 1, x0 + 1) * fx
    return (top * (1 - fy) + bot * fy).astype(F32)


def _closest_velocity(vel: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """The velocity of the nearest depth of each aligned 2 x 2 quad (quad reads across x, then
    y; ties keep the first)."""
    h, w = depth.shape
    d = np.pad(depth, ((0, h % 2), (0, w % 2)), constant_values=np.inf)
    v = np.pad(vel, ((0, h % 2), (0, w % 2), (0, 0)))
    xx = np.arange(d.shape[1]) ^ 1
    yy = np.arange(d.shape[0]) ^ 1
    dx, vx = d[:, xx], v[:, xx]
    take = dx < d
    d1, v1 = np.where(take, dx, d), np.where(take[..., None], vx, v)
    dy, vy = d1[yy], v1[yy]
    take = dy < d1
    return np.where(take[..., None], vy, v1)[:h, :w]


def _temporal(frame, state: FfxState | None, bits, local):
    """The temporal pass at every pixel: ``(shadow, variance)`` and the new moments."""
    h, w = bits.shape
    cur = bits.astype(F32)
    depth = np.where(frame.valid, frame.depth, np.inf).astype(F32)
    vel = (frame.motion / np.array([w, h])).astype(F32)  # uv units, previous = uv + velocity
    vel = _closest_velocity(vel, depth)
    ys, xs = np.mgrid[0:h, 0:w]
    uv_x = ((xs + F32(0.5)) / F32(w)).astype(F32)
    uv_y = ((ys + F32(0.5)) / F32(h)).astype(F32)
    pu, pv = (uv_x + vel[..., 0]).astype(F32), (uv_y + vel[..., 1]).astype(F32)
    inside = (pu > 0) & (pu < 1) & (pv > 0) & (pv < 1)
    ix = np.clip((pu * F32(w)).astype(np.int64), 0, w - 1)
    iy = np.clip((pv * F32(h)).astype(np.int64), 0, h - 1)
    if state is None:
        disocc = np.ones((h, w), dtype=bool)
        prev_m = np.zeros((h, w, 3), dtype=F32)
        previous = cur
    else:
        z_al = (F32(1.0) - frame.n_dot_v.astype(F32)) ** 8
        lin = frame.depth_previous.astype(F32)
        with np.errstate(invalid="ignore", divide="ignore"):
            diff = np.abs(state.depth[iy, ix] - lin) / lin
        tol = F32(1e-2) + (F32(1e-1) - F32(1e-2)) * z_al
        disocc = ~inside | ~(diff < tol)
        prev_m = np.where(disocc[..., None], F32(0.0), state.moments[iy, ix])
        previous = _bilinear_clamp(state.history[..., 0], pu, pv)
    n = prev_m[..., 2] + F32(1.0)
    old_m, old_s = prev_m[..., 0], prev_m[..., 1]
    new_m = old_m + (cur - old_m) / n
    new_s = old_s + (cur - old_m) * (cur - new_m)
    variance = np.where(n > 1, new_s / np.maximum(n - 1, F32(1e-30)), F32(1.0)).astype(F32)
    spatial = np.maximum(local - local * local, F32(0.0))
    sd = np.sqrt(spatial)
    clamped = np.clip(previous, local - F32(0.5) * sd, local + F32(0.5) * sd)
    disc = (previous - local) / np.maximum(F32(0.5) * sd, F32(0.001))
    n = (n * np.exp(-disc * disc / F32(20.0))).astype(F32)
    boost = n < 16
    variance = np.where(
        boost, np.maximum(variance, spatial) * np.maximum(F32(16.0) - n, F32(1.0)), variance
    )
    hw = np.sqrt(np.maximum(F32(8.0) - n, F32(0.0)) / F32(8.0))
    a = F32(0.05) + (F32(1.0) - F32(0.05)) * hw
    out = clamped + (cur - clamped) * a
    recv = frame.valid
    shadow = np.where(recv, out, F32(0.0)).astype(F32)
    variance = np.where(recv, variance, F32(0.0)).astype(F32)
    moments = np.stack([new_m, new_s, n], -1).astype(F32)
    moments = np.where(recv[..., None], moments, F32(0.0))
    return shadow, variance, moments


def _atrous(inp, frame, depth, normal16, cleared, light, step):
    """One filter pass (filter.h:126-271) on ``inp`` ``(H, W, 2)``."""
    h, w = depth.shape
    x16 = np.clip(inp, -F16_MAX, F16_MAX).astype(np.float16).astype(F32)
    ys, xs = np.mgrid[0:h, 0:w]

    def at(a, dy, dx):
        return a[np.clip(ys + dy, 0, h - 1), np.clip(xs + dx, 0, w - 1)]

    var = np.zeros((h, w), dtype=F32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            var += VARIANCE_KERNEL[abs(dx), abs(dy)] * at(x16[..., 1], dy, dx)
    sd = np.sqrt(np.maximum(var + F32(1e-9), F32(0.0)))
    wsum = np.ones((h, w), dtype=F32)
    ssum = x16.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dx == 0 and dy == 0:
                continue
            s_n = at(x16, dy * step, dx * step)
            z_n = at(depth, dy * step, dx * step)
            n_n = at(normal16, dy * step, dx * step)
            wt = ATROUS_KERNEL[abs(dx)] * ATROUS_KERNEL[abs(dy)]
            wt = wt * np.exp(-np.abs(x16[..., 0] - s_n[..., 0]) / sd)
            with np.errstate(invalid="ignore"):
                wz = np.exp(-np.abs(depth - z_n) / DEPTH_SIGMA)
            wt = wt * np.where(np.isfinite(z_n), wz, F32(0.0))
            dot = np.clip(np.sum(normal16 * n_n, axis=-1), 0.0, 1.0)
            wt = (wt * dot**32).astype(F32)
            ssum += np.stack([wt, wt * wt], -1) * s_n
            wsum += wt
    out = np.stack([ssum[..., 0] / wsum, ssum[..., 1] / (wsum * wsum)], -1).astype(F32)
    out = np.where(frame.valid[..., None], out, F32(0.0))
    cleared_val = np.stack([light.astype(F32), np.zeros((h, w), F32)], -1)
    return np.where(cleared[..., None], cleared_val, out).astype(F32)


def ffx_step(frame, state: FfxState | None):
    """One frame: ``(visibility (H, W) float32, new state, record)``. ``record`` holds the
    pass-by-pass images (``temporal``, ``pass0..2``) and the classification counts."""
    h, w = frame.noisy.shape
    bits = (frame.noisy > 0.5) & frame.valid
    skip_sky, all_l, all_s = _classify(bits, frame.valid)
    cleared_g = skip_sky | all_l | all_s
    cleared = _group_map(cleared_g, h, w)
    light = _group_map(all_l & ~skip_sky, h, w)
    local = local_moments(bits)
    shadow, variance, moments = _temporal(frame, state, bits, local)
    recv_f = frame.valid.astype(F32)
    shadow = np.where(cleared, light.astype(F32), shadow)
    variance = np.where(cleared, F32(0.0), variance)
    clear_m = np.stack([light.astype(F32), np.zeros_like(recv_f), recv_f], -1)
    moments = np.where(cleared[..., None], clear_m, moments).astype(F32)
    depth = np.where(frame.valid, frame.depth, np.inf).astype(F32)
    normal16 = frame.normal.astype(np.float16).astype(F32)
    x = np.stack([shadow, variance], -1)
    passes = []
    for step in STEPS:
        x = _atrous(x, frame, depth, normal16, cleared, light, step)
        passes.append(x)
    remap = np.maximum(F32(1.2) - x[..., 1], F32(1.0))
    out = np.power(np.abs(x[..., 0]), remap).astype(F32)
    new = FfxState(moments=moments, history=passes[0], depth=depth)
    record = {
        "temporal": np.stack([shadow, variance], -1),
        "passes": passes,
        "tiles_cleared": int(cleared_g.sum()),
        "tiles": int(cleared_g.size),
    }
    return out, new, record
