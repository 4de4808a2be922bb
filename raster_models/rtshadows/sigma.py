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

from dataclasses import dataclass, replace

import numpy as np

from .rays import NRD_EPS, NRD_FP16_MAX

__all__ = ["SigmaState", "sigma_step"]

#: Computation precision: float64, because the anti-lag's ``sqrt(|clamped - history|)`` turns
#: float32 rounding (1e-7) into 3e-4 differences; images are returned as float32.
FT = np.float64
F32 = np.float32
BORDER = 2
MAX_PIXEL_RADIUS = FT(32.0)
PLANE_DIST_SENSITIVITY = FT(0.02)
DISOCCLUSION_THRESHOLD = FT(0.02)
TS_SIGMA_SCALE = FT(3.0)
MAX_ACCUM_FRAME_NUM = FT(7.0)
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
    dtype=FT,
)
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


@dataclass
class SigmaState:
    shadow: np.ndarray  # (H, W) stabilised output
    history: np.ndarray  # (H, W) history length
    depth: np.ndarray  # (H, W) view depth (inf: sky)


def _gauss(r):
    return np.exp(FT(-0.66) * r * r).astype(FT)


def _smoothstep(a, b, x):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return (t * t * (3.0 - 2.0 * t)).astype(FT)


def kernel_radius(p, pixel_size, scale=1.0):
    """``GetKernelRadiusInPixels`` with the 5 x 5 estimation kernel (min 2 pixels)."""
    r = (p / pixel_size * FT(scale)).astype(FT)
    return np.clip(r, np.minimum(r, FT(2.0)), MAX_PIXEL_RADIUS)


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
    px = np.where(lit | inf, FT(0.0), p)
    rad = kernel_radius(px, np.maximum(frame.pixel_size, FT(1e-12)))
    rmax = tiles(np.where(inf, FT(0.0), rad), 0.0).max(axis=(1, 3))
    x = np.where(all_lit | all_umbra, FT(0.0), FT(1.0))
    y = np.clip(rmax / FT(16.0), 0.0, 1.0).astype(FT)
    th, tw = x.shape
    k = FT(1.01) / (y + FT(0.01))
    blurry = np.zeros_like(x)
    total = np.zeros_like(x)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            wgt = np.exp2(-k * FT(di * di + dj * dj))
            ty = np.clip(np.arange(th)[:, None] + dj, 0, th - 1)
            tx = np.clip(np.arange(tw)[None, :] + di, 0, tw - 1)
            blurry += x[ty, tx] * wgt
            total += wgt
    tile = blurry / total
    return np.repeat(np.repeat(tile, 16, 0), 16, 1)[:h, :w].astype(FT)


def _plane_weight(frame, cy, cx):
    frustum = FT(min(frame.noisy.shape)) * frame.pixel_size
    d = np.abs(np.sum(frame.normal * (frame.position[cy, cx] - frame.position), axis=-1))
    return _smoothstep(1.0, 0.0, d / np.maximum(PLANE_DIST_SENSITIVITY * frustum, 1e-12))


def _blur(frame, s, pen, tile, rotation: float):
    """One ``SIGMA_Blur`` pass: ``(shadow, penumbra)``."""
    h, w = s.shape
    ys, xs = np.mgrid[0:h, 0:w]
    size = np.maximum(frame.pixel_size, FT(1e-12))
    nol_c = pen == 0  # AreBothLitOrUnlit: both facing away from the light (penumbra 0) or not
    res = np.zeros((h, w), FT)
    sx = np.zeros((h, w), FT)
    pe = np.zeros((h, w), FT)
    sy = np.zeros((h, w), FT)
    for j in range(-BORDER, BORDER + 1):
        for i in range(-BORDER, BORDER + 1):
            cy, cx = np.clip(ys + j, 0, h - 1), np.clip(xs + i, 0, w - 1)
            pn = pen[cy, cx]
            if i == 0 and j == 0:
                wt = np.ones((h, w), FT)
            else:
                wt = ((pn == 0) == nol_c).astype(FT)
                wt = wt * _gauss(FT(np.hypot(i, j) / BORDER)) * _plane_weight(frame, cy, cx)
                wt = np.where(frame.valid[cy, cx], wt, FT(0.0))
            res += wt * s[cy, cx]
            sx += wt
            wp = wt * size / (size + pn) * (pn < NRD_FP16_MAX)
            pe += wp * pn
            sy += wp
    res = res / sx
    pe = pe / np.maximum(sy, NRD_EPS)
    sy = (sy != 0).astype(FT)
    f = _smoothstep(0.0, float(BORDER), pe / size)
    res = s + (res - s) * f
    f = FT(4.0) + (FT(1.0) - FT(4.0)) * f
    res, pe, sx, sy = res * f, pe * f, f, sy * f
    radius = kernel_radius(pe, size, 1.0) * tile
    radius = np.clip(radius, np.minimum(radius, FT(2.0)), MAX_PIXEL_RADIUS)
    c, sn = np.cos(rotation), np.sin(rotation)
    inv_est = FT(1.0) / np.maximum(pe, NRD_EPS)
    for ox, oy, oz in SPECIAL8:
        rx, ry = FT(c * ox - sn * oy), FT(sn * ox + c * oy)
        fx, fy = xs + FT(0.5) + rx * radius, ys + FT(0.5) + ry * radius
        mx = np.where(fx < 0, -fx, np.where(fx > w, 2 * w - fx, fx))
        my = np.where(fy < 0, -fy, np.where(fy > h, 2 * h - fy, fy))
        mirrored = (mx != fx) | (my != fy)
        cx = np.clip(mx.astype(np.int64), 0, w - 1)
        cy = np.clip(my.astype(np.int64), 0, h - 1)
        pn = pen[cy, cx]
        wt = np.where(mirrored, FT(1.0), _gauss(FT(oz)))
        wt = wt * ((pn == 0) == nol_c) * np.clip(pn * inv_est, 0.0, 1.0)
        wt = wt * _plane_weight(frame, cy, cx) * frame.valid[cy, cx]
        res += s[cy, cx] * wt
        sx += wt
        wp = wt * size / (size + pn) * (pn < NRD_FP16_MAX)
        pe += np.where(wp == 0, FT(0.0), pn * wp)
        sy += wp
    res = res / sx
    pe = np.where(sy == 0, pen, pe / np.maximum(sy, NRD_EPS))
    early = (tile == 0) | (pen == 0) | ~frame.valid
    return np.where(early, s, res).astype(FT), np.where(early, pen, pe).astype(FT)


def _stabilise(frame, state: SigmaState | None, s, pen, tile):
    h, w = s.shape
    ys, xs = np.mgrid[0:h, 0:w]
    nol_c = pen == 0  # AreBothLitOrUnlit: both facing away from the light (penumbra 0) or not
    m1 = np.zeros((h, w), FT)
    m2 = np.zeros((h, w), FT)
    total = np.zeros((h, w), FT)
    for j in range(-BORDER, BORDER + 1):
        for i in range(-BORDER, BORDER + 1):
            cy, cx = np.clip(ys + j, 0, h - 1), np.clip(xs + i, 0, w - 1)
            if i == 0 and j == 0:
                wt = np.ones((h, w), FT)
            else:
                wt = ((pen[cy, cx] == 0) == nol_c) * _gauss(FT(np.hypot(i, j) / 2))
            m1 += s[cy, cx] * wt
            m2 += s[cy, cx] ** 2 * wt
            total += wt
    m1, m2 = m1 / total, m2 / total
    sigma = np.sqrt(np.maximum(m2 - m1 * m1, FT(0.0)))
    depth = np.where(frame.valid, frame.depth, np.inf).astype(FT)
    if state is None:
        hist_len = np.zeros((h, w), FT)
        history = s
    else:
        px = xs + FT(0.5) + frame.motion[..., 0] - FT(0.5)
        py = ys + FT(0.5) + frame.motion[..., 1] - FT(0.5)
        x0, y0 = np.floor(px).astype(np.int64), np.floor(py).astype(np.int64)
        fx, fy = (px - x0).astype(FT), (py - y0).astype(FT)
        thr = DISOCCLUSION_THRESHOLD * FT(min(h, w)) * frame.pixel_size - NRD_EPS
        num_h = np.zeros((h, w), FT)
        num_l = np.zeros((h, w), FT)
        den = np.zeros((h, w), FT)
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
            wt = np.where(occl, bw, FT(0.0)).astype(FT)
            num_h += wt * state.shadow[cy, cx]
            num_l += wt * state.history[cy, cx]
            den += wt
        ok = den > 1e-4
        history = np.where(ok, num_h / np.maximum(den, FT(1e-4)), s)
        hist_len = np.where(ok, num_l / np.maximum(den, FT(1e-4)), FT(0.0))
        history = np.clip(history, 0.0, 1.0).astype(FT)
    sigma = sigma * (TS_SIGMA_SCALE + (FT(1.0) - TS_SIGMA_SCALE) / (FT(1.0) + hist_len))
    clamped = np.clip(history, m1 - sigma, m1 + sigma)
    antilag = np.clip(FT(1.0) - np.sqrt(np.abs(clamped - history)), 0.0, 1.0)
    hist_len = hist_len * antilag
    hw = hist_len / (FT(1.0) + hist_len)
    clamped = clamped + (history - clamped) * (FT(0.6) * hw * antilag)
    strength = FT(MAX_STABILIZED_FRAME_NUM / (1.0 + MAX_STABILIZED_FRAME_NUM))
    sw = FT(1.0) - np.minimum(strength, hw)
    out = clamped + (s - clamped) * sw
    hist_len = np.minimum(hist_len + FT(1.0), MAX_ACCUM_FRAME_NUM)
    hard = (tile == 0) | (pen == 0)
    out = np.where(hard, s, out)
    hist_len = np.where(hard, MAX_ACCUM_FRAME_NUM, hist_len)
    out = np.where(frame.valid, out, FT(0.0)).astype(F32)
    return out, SigmaState(shadow=out, history=hist_len.astype(F32), depth=depth)


def _wide(frame):
    """The frame's float arrays the blur and stabilisation read, in :data:`FT`."""
    return replace(
        frame,
        pixel_size=frame.pixel_size.astype(FT),
        position=frame.position.astype(FT),
        normal=frame.normal.astype(FT),
        depth_previous=frame.depth_previous.astype(FT),
    )


def sigma_step(frame, state: SigmaState | None):
    """One frame: ``(visibility (H, W) float32, new state, record)``."""
    tile = classify_tiles(frame)
    s = np.where(frame.valid, (frame.penumbra >= NRD_FP16_MAX).astype(FT), FT(0.0))
    pen = np.where(frame.valid, frame.penumbra, FT(0.0)).astype(FT)
    angle = float(frame.index) * GOLDEN_ANGLE
    s1, p1 = _blur(frame, s, pen, tile, angle)
    s2, p2 = _blur(frame, s1, p1, tile, angle + 0.5 * GOLDEN_ANGLE)
    out, new = _stabilise(frame, state, s2, p2, tile)
    record = {"tile": tile, "blur": s1.astype(F32), "post_blur": s2.astype(F32)}
    return out.astype(F32), new, record
