"""A SIGMA-class shadow denoiser from NVIDIA NRD's documented settings and shader constants.

NRD's licence is not open source: this is written from its settings and constants (NVIDIA-RTX
/NRD commit a822d87f6202650da1dcebaeaf1f2c5b0b7be112), not from its code:

- input: the packed penumbra radius (:func:`.rays.pack_penumbra_sun` / ``_local``), lit where
  it is ``NRD_FP16_MAX`` (``SIGMA_Common.hlsli``, ``IsLit``);
- tile classification, 16 x 16 tiles (``SIGMA_ClassifyTiles.cs.hlsl``): a tile all lit (or
  sky) or all in umbra is skipped; its blur-radius estimate ``max radius / 16``, smoothed over
  3 x 3 tiles by ``exp2(-k d^2)``, ``k = 1.01 / (r + 0.01)`` (``SIGMA_SmoothTiles.cs.hlsl``);
- blur radius from hit distance: ``clamp(p / pixelSize, min(p / pixelSize, 2), 32)`` pixels
  (``GetKernelRadiusInPixels``, ``SIGMA_MAX_PIXEL_RADIUS = 32``, ``SIGMA_Config.hlsli:32``);
- two blur passes (``SIGMA_Blur.cs.hlsl``: blur, then post-blur on its output): a dense 5 x 5
  estimate (``NRD_BORDER = 2``; Gaussian ``exp(-0.66 r^2)``, ``AreBothLitOrUnlit`` (both
  facing the light or both not: penumbra 0 marks N.L <= 0), the
  plane-distance weight ``smoothstep(1, 0, |n . (x_s - x)| / (0.02 frustumSize))`` with
  ``planeDistanceSensitivity = 0.02``, ``NRDSettings.h:469``) preferring smaller penumbrae,
  blended with the centre by ``smoothstep(0, 2, penumbra px)``, then 8 sparse taps
  (``g_Special8``, ``Common.hlsli:207-218``) rotated per frame over the blur radius, weighted
  also by ``saturate(p_s / p_estimated)``;
- temporal stabilisation (``SIGMA_TemporalStabilization.cs.hlsl``): 5 x 5 local moments,
  history reprojected with the motion vectors (bilinear with plane-distance occlusion weights,
  threshold ``0.02 frustumSize``, ``NRD_DISOCCLUSION_THRESHOLD``), clamped to ``m1 +- sigma
  lerp(3, 1, 1 / (1 + L))``, anti-lag ``L *= 1 - sqrt(|clamped - history|)``, weight ``L / (1 +
  L)``, ``0.6 w antilag`` of the unclamped history mixed back, stabilisation strength
  ``N / (1 + N)`` with ``maxStabilizedFrameNum = 5`` (``NRDSettings.h:474``,
  ``Sigma.cpp:98-100``), history length capped at ``SIGMA_MAX_ACCUM_FRAME_NUM = 7``.

Simplified (SIGMA-class, not SIGMA): the tile value is read bilinearly (NRD: bicubic), the
history bilinearly (NRD: Catmull-Rom when all four taps agree), the kernel isotropic (no
screen-space skew) and rotated by the golden angle a frame (NRD: its own per-frame rotator),
the output kept linear (NRD stores ``sqrt`` and the caller squares it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rays import NRD_EPS, NRD_FP16_MAX

__all__ = ["SigmaState", "sigma_step"]

F32 = np.float32
BORDER = 2
MAX_PIXEL_RADIUS = F32(32.0)
PLANE_DIST_SENSITIVITY = F32(0.02)
DISOCCLUSION_THRESHOLD = F32(0.02)
TS_SIGMA_SCALE = F32(3.0)
MAX_ACCUM_FRAME_NUM = F32(7.0)
MAX_STABILIZED_FRAME_NUM = 5
_R = float(np.sqrt(2.0)) * 0.25
#: g_Special8 (Common.hlsli:207-218): (x, y, Gaussian radius)
SPECIAL8 = np.array(
    [
        (-1, 0, 1),
        (0, 1, 1),
        (1, 0, 1),
        (0, -1, 1),
        (-_R, _R, 0.5),
        (_R, _R, 0.5),
        (_R, -_R, 0.5),
        (-_R, -_R, 0.5),
    ],
    dtype=F32,
)
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


@dataclass
class SigmaState:
    shadow: np.ndarray  # (H, W) stabilised output
    history: np.ndarray  # (H, W) history length
    depth: np.ndarray  # (H, W) view depth (inf: sky)


def _gauss(r):
    return np.exp(F32(-0.66) * r * r).astype(F32)


def _smoothstep(a, b, x):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return (t * t * (3.0 - 2.0 * t)).astype(F32)


def kernel_radius(p, pixel_size, scale=1.0):
    """``GetKernelRadiusInPixels`` with the 5 x 5 estimation kernel (min 2 pixels)."""
    r = (p / pixel_size * F32(scale)).astype(F32)
    return np.clip(r, np.minimum(r, F32(2.0)), MAX_PIXEL_RADIUS)


def classify_tiles(frame) -> np.ndarray:
    """``(H, W)`` smoothed tile value: 0 where the 16 x 16 tile is all lit or all umbra."""
    h, w = frame.noisy.shape
    p = frame.penumbra
    inf = ~frame.valid
    lit = p >= NRD_FP16_MAX
    shadow0 = p == 0
    hh, ww = -(-h // 16) * 16, -(-w // 16) * 16

    def tiles(a, fill):
        a = np.pad(a, ((0, hh - h), (0, ww - w)), constant_values=fill)
        return a.reshape(hh // 16, 16, ww // 16, 16)

    all_lit = tiles(lit | inf | shadow0, True).all(axis=(1, 3))
    all_umbra = tiles(~lit | inf | shadow0, True).all(axis=(1, 3))
    px = np.where(lit | inf, F32(0.0), p)
    rad = kernel_radius(px, np.maximum(frame.pixel_size, F32(1e-12)))
    rmax = tiles(np.where(inf, F32(0.0), rad), 0.0).max(axis=(1, 3))
    x = np.where(all_lit | all_umbra, F32(0.0), F32(1.0))
    y = np.clip(rmax / F32(16.0), 0.0, 1.0).astype(F32)
    th, tw = x.shape
    k = F32(1.01) / (y + F32(0.01))
    blurry = np.zeros_like(x)
    total = np.zeros_like(x)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            wgt = np.exp2(-k * F32(di * di + dj * dj))
            ty = np.clip(np.arange(th)[:, None] + dj, 0, th - 1)
            tx = np.clip(np.arange(tw)[None, :] + di, 0, tw - 1)
            blurry += x[ty, tx] * wgt
            total += wgt
    tile = blurry / total
    return np.repeat(np.repeat(tile, 16, 0), 16, 1)[:h, :w].astype(F32)


def _plane_weight(frame, cy, cx):
    frustum = F32(min(frame.noisy.shape)) * frame.pixel_size
    d = np.abs(np.sum(frame.normal * (frame.position[cy, cx] - frame.position), axis=-1))
    return _smoothstep(1.0, 0.0, d / np.maximum(PLANE_DIST_SENSITIVITY * frustum, 1e-12))


def _blur(frame, s, pen, tile, rotation: float):
    """One ``SIGMA_Blur`` pass: ``(shadow, penumbra)``."""
    h, w = s.shape
    ys, xs = np.mgrid[0:h, 0:w]
    size = np.maximum(frame.pixel_size, F32(1e-12))
    nol_c = pen == 0  # AreBothLitOrUnlit: both facing away from the light (penumbra 0) or not
    res = np.zeros((h, w), F32)
    sx = np.zeros((h, w), F32)
    pe = np.zeros((h, w), F32)
    sy = np.zeros((h, w), F32)
    for j in range(-BORDER, BORDER + 1):
        for i in range(-BORDER, BORDER + 1):
            cy, cx = np.clip(ys + j, 0, h - 1), np.clip(xs + i, 0, w - 1)
            pn = pen[cy, cx]
            if i == 0 and j == 0:
                wt = np.ones((h, w), F32)
            else:
                wt = ((pn == 0) == nol_c).astype(F32)
                wt = wt * _gauss(F32(np.hypot(i, j) / BORDER)) * _plane_weight(frame, cy, cx)
                wt = np.where(frame.valid[cy, cx], wt, F32(0.0))
            res += wt * s[cy, cx]
            sx += wt
            wp = wt * size / (size + pn) * (pn < NRD_FP16_MAX)
            pe += wp * pn
            sy += wp
    res = res / sx
    pe = pe / np.maximum(sy, NRD_EPS)
    sy = (sy != 0).astype(F32)
    f = _smoothstep(0.0, float(BORDER), pe / size)
    res = s + (res - s) * f
    f = F32(4.0) + (F32(1.0) - F32(4.0)) * f
    res, pe, sx, sy = res * f, pe * f, f, sy * f
    radius = kernel_radius(pe, size, 1.0) * tile
    radius = np.clip(radius, np.minimum(radius, F32(2.0)), MAX_PIXEL_RADIUS)
    c, sn = np.cos(rotation), np.sin(rotation)
    inv_est = F32(1.0) / np.maximum(pe, NRD_EPS)
    for ox, oy, oz in SPECIAL8:
        rx, ry = F32(c * ox - sn * oy), F32(sn * ox + c * oy)
        fx, fy = xs + F32(0.5) + rx * radius, ys + F32(0.5) + ry * radius
        mx = np.where(fx < 0, -fx, np.where(fx > w, 2 * w - fx, fx))
        my = np.where(fy < 0, -fy, np.where(fy > h, 2 * h - fy, fy))
        mirrored = (mx != fx) | (my != fy)
        cx = np.clip(mx.astype(np.int64), 0, w - 1)
        cy = np.clip(my.astype(np.int64), 0, h - 1)
        pn = pen[cy, cx]
        wt = np.where(mirrored, F32(1.0), _gauss(F32(oz)))
        wt = wt * ((pn == 0) == nol_c) * np.clip(pn * inv_est, 0.0, 1.0)
        wt = wt * _plane_weight(frame, cy, cx) * frame.valid[cy, cx]
        res += s[cy, cx] * wt
        sx += wt
        wp = wt * size / (size + pn) * (pn < NRD_FP16_MAX)
        pe += np.where(wp == 0, F32(0.0), pn * wp)
        sy += wp
    res = res / sx
    pe = np.where(sy == 0, pen, pe / np.maximum(sy, NRD_EPS))
    early = (tile == 0) | (pen == 0) | ~frame.valid
    return np.where(early, s, res).astype(F32), np.where(early, pen, pe).astype(F32)


def _stabilise(frame, state: SigmaState | None, s, pen, tile):
    h, w = s.shape
    ys, xs = np.mgrid[0:h, 0:w]
    nol_c = pen == 0  # AreBothLitOrUnlit: both facing away from the light (penumbra 0) or not
    m1 = np.zeros((h, w), F32)
    m2 = np.zeros((h, w), F32)
    total = np.zeros((h, w), F32)
    for j in range(-BORDER, BORDER + 1):
        for i in range(-BORDER, BORDER + 1):
            cy, cx = np.clip(ys + j, 0, h - 1), np.clip(xs + i, 0, w - 1)
            if i == 0 and j == 0:
                wt = np.ones((h, w), F32)
            else:
                wt = ((pen[cy, cx] == 0) == nol_c) * _gauss(F32(np.hypot(i, j) / 2))
            m1 += s[cy, cx] * wt
            m2 += s[cy, cx] ** 2 * wt
            total += wt
    m1, m2 = m1 / total, m2 / total
    sigma = np.sqrt(np.maximum(m2 - m1 * m1, F32(0.0)))
    depth = np.where(frame.valid, frame.depth, np.inf).astype(F32)
    if state is None:
        hist_len = np.zeros((h, w), F32)
        history = s
    else:
        px = xs + F32(0.5) + frame.motion[..., 0] - F32(0.5)
        py = ys + F32(0.5) + frame.motion[..., 1] - F32(0.5)
        x0, y0 = np.floor(px).astype(np.int64), np.floor(py).astype(np.int64)
        fx, fy = (px - x0).astype(F32), (py - y0).astype(F32)
        thr = DISOCCLUSION_THRESHOLD * F32(min(h, w)) * frame.pixel_size - NRD_EPS
        num_h = np.zeros((h, w), F32)
        num_l = np.zeros((h, w), F32)
        den = np.zeros((h, w), F32)
        for dy, dx, bw in (
            (0, 0, (1 - fx) * (1 - fy)),
            (0, 1, fx * (1 - fy)),
            (1, 0, (1 - fx) * fy),
            (1, 1, fx * fy),
        ):
            ty, tx = y0 + dy, x0 + dx
            inside = (ty >= 0) & (ty < h) & (tx >= 0) & (tx < w)
            cy, cx = np.clip(ty, 0, h - 1), np.clip(tx, 0, w - 1)
            occl = inside & (np.abs(state.depth[cy, cx] - frame.depth_previous) <= thr)
            wt = np.where(occl, bw, F32(0.0)).astype(F32)
            num_h += wt * state.shadow[cy, cx]
            num_l += wt * state.history[cy, cx]
            den += wt
        ok = den > 1e-4
        history = np.where(ok, num_h / np.maximum(den, F32(1e-4)), s)
        hist_len = np.where(ok, num_l / np.maximum(den, F32(1e-4)), F32(0.0))
        history = np.clip(history, 0.0, 1.0).astype(F32)
    sigma = sigma * (TS_SIGMA_SCALE + (F32(1.0) - TS_SIGMA_SCALE) / (F32(1.0) + hist_len))
    clamped = np.clip(history, m1 - sigma, m1 + sigma)
    antilag = np.clip(F32(1.0) - np.sqrt(np.abs(clamped - history)), 0.0, 1.0)
    hist_len = hist_len * antilag
    hw = hist_len / (F32(1.0) + hist_len)
    clamped = clamped + (history - clamped) * (F32(0.6) * hw * antilag)
    strength = F32(MAX_STABILIZED_FRAME_NUM / (1.0 + MAX_STABILIZED_FRAME_NUM))
    sw = F32(1.0) - np.minimum(strength, hw)
    out = clamped + (s - clamped) * sw
    hist_len = np.minimum(hist_len + F32(1.0), MAX_ACCUM_FRAME_NUM)
    hard = (tile == 0) | (pen == 0)
    out = np.where(hard, s, out)
    hist_len = np.where(hard, MAX_ACCUM_FRAME_NUM, hist_len)
    out = np.where(frame.valid, out, F32(0.0)).astype(F32)
    return out, SigmaState(shadow=out, history=hist_len.astype(F32), depth=depth)


def sigma_step(frame, state: SigmaState | None):
    """One frame: ``(visibility (H, W) float32, new state, record)``."""
    tile = classify_tiles(frame)
    s = np.where(frame.valid, (frame.penumbra >= NRD_FP16_MAX).astype(F32), F32(0.0))
    pen = np.where(frame.valid, frame.penumbra, F32(0.0)).astype(F32)
    angle = float(frame.index) * GOLDEN_ANGLE
    s1, p1 = _blur(frame, s, pen, tile, angle)
    s2, p2 = _blur(frame, s1, p1, tile, angle + 0.5 * GOLDEN_ANGLE)
    out, new = _stabilise(frame, state, s2, p2, tile)
    return out, new, {"tile": tile, "blur": s1, "post_blur": s2}
