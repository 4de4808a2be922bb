"""The FidelityFX shadow denoiser model against a per-pixel transcription of the pinned HLSL
(FidelityFX-SDK v1.1.4, ffx_denoiser_shadows_*.h) on a hand-built frame pair (history,
motion, disocclusion): 32-bit masks, groups, quads and passes written out lane by lane."""

from __future__ import annotations

import math

import numpy as np
from raster_oracle.raster_models.rtshadows.ffx import ffx_step

from tests._rtshadows_frames import frame_pair

F32 = np.float32
#: float32 model against a float64 per-pixel transcription (different summation orders)
TOL = 1e-6


def _kw(i):
    w = [math.exp(-3.0 * k * k / 81.0) for k in range(9)]
    return w[i] / (w[0] + 2 * sum(w[1:]))


def _masks(f):
    h, w = f.noisy.shape
    tw, th = (w + 7) // 8, (h + 3) // 4
    m = [0] * (tw * th)
    for y in range(h):
        for x in range(w):
            if f.valid[y, x] and f.noisy[y, x] > 0.5:
                m[(y // 4) * tw + x // 8] |= 1 << ((y % 4) * 8 + x % 8)
    return m, tw, th


def _horizontal(m, tw, h, x, y):
    if y < 0 or y >= h:
        return 0.0
    t = (y // 4) * tw + x // 8
    left = m[t - 1] if x // 8 > 0 else 0
    right = m[t + 1] if x // 8 < tw - 1 else 0
    row = (y % 4) * 8
    nb = ((left >> row) & 0xFF) | (((m[t] >> row) & 0xFF) << 8) | (((right >> row) & 0xFF) << 16)
    nb >>= x % 8
    s = sum(_kw(8 - i) for i in range(8) if nb & (1 << i))
    s += _kw(0) if nb & (1 << 8) else 0.0
    return s + sum(_kw(i) for i in range(1, 9) if nb & (1 << (8 + i)))


def _classify(f, m, tw, th):
    h, w = f.noisy.shape
    out = {}
    for gy in range((h + 7) // 8):
        for gx in range((w + 7) // 8):
            recv = any(
                f.valid[y, x]
                for y in range(gy * 8, min(h, gy * 8 + 8))
                for x in range(gx * 8, min(w, gx * 8 + 8))
            )
            if not recv:
                out[gy, gx] = (True, False)
                continue
            o, a = 0, 0xFFFFFFFF
            for j in range(-2, 4):
                for i in range(-1, 2):
                    tx, ty = min(max(gx + i, 0), tw - 1), min(max(2 * gy + j, 0), th - 1)
                    o |= m[ty * tw + tx]
                    a &= m[ty * tw + tx]
            light, shadow = a == 0xFFFFFFFF, o == 0
            out[gy, gx] = (light or shadow, light)
    return out


def _bilinear(img, u, v):
    h, w = img.shape
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0

    def at(yy, xx):
        return float(img[min(max(yy, 0), h - 1), min(max(xx, 0), w - 1)])

    top = at(y0, x0) * (1 - fx) + at(y0, x0 + 1) * fx
    bot = at(y0 + 1, x0) * (1 - fx) + at(y0 + 1, x0 + 1) * fx
    return top * (1 - fy) + bot * fy


def _temporal(f, state, m, tw, tiles):
    h, w = f.noisy.shape
    lin = np.where(f.valid, f.depth, np.inf)
    out = np.zeros((h, w, 2))
    moments = np.zeros((h, w, 3))
    for y in range(h):
        for x in range(w):
            cleared, light = tiles[y // 8, x // 8]
            if cleared:
                out[y, x] = (float(light), 0.0)
                moments[y, x] = (float(light), 0.0, 1.0 if f.valid[y, x] else 0.0)
                continue
            if not f.valid[y, x]:
                continue
            # the 2 x 2 quad's nearest depth (across x, then across y)
            best_d, best_v = lin[y, x], f.motion[y, x]
            qx = x ^ 1
            if qx < w and lin[y, qx] < best_d:
                best_d, best_v = lin[y, qx], f.motion[y, qx]
            qy = y ^ 1
            if qy < h:
                d2, v2 = lin[qy, x], f.motion[qy, x]
                if qx < w and lin[qy, qx] < d2:
                    d2, v2 = lin[qy, qx], f.motion[qy, qx]
                if d2 < best_d:
                    best_v = v2
            u = (x + 0.5) / w + best_v[0] / w
            v = (y + 0.5) / h + best_v[1] / h
            cur = 1.0 if (m[(y // 4) * tw + x // 8] >> ((y % 4) * 8 + x % 8)) & 1 else 0.0
            local = sum(_kw(abs(dy)) * _horizontal(m, tw, h, x, y + dy) for dy in range(-8, 9))
            if state is None:
                dis, pm, prev = True, (0.0, 0.0, 0.0), cur
            else:
                dis = True
                ix, iy = int(u * w), int(v * h)
                if 0 < u < 1 and 0 < v < 1:
                    za = (1.0 - float(f.n_dot_v[y, x])) ** 8
                    dd = abs(float(state.depth[iy, ix]) - float(f.depth_previous[y, x]))
                    dis = dd / float(f.depth_previous[y, x]) >= 1e-2 + (1e-1 - 1e-2) * za
                pm = (0.0, 0.0, 0.0) if dis else tuple(state.moments[iy, ix])
                prev = _bilinear(state.history[..., 0], u, v)
            n = pm[2] + 1.0
            new_m = pm[0] + (cur - pm[0]) / n
            new_s = pm[1] + (cur - pm[0]) * (cur - new_m)
            var = new_s / (n - 1.0) if n > 1.0 else 1.0
            spatial = max(local - local * local, 0.0)
            sd = math.sqrt(spatial)
            clamped = min(max(prev, local - 0.5 * sd), local + 0.5 * sd)
            disc = (prev - local) / max(0.5 * sd, 0.001)
            n *= math.exp(-disc * disc / 20.0)
            if n < 16.0:
                var = max(var, spatial) * max(16.0 - n, 1.0)
            hw = math.sqrt(max(8.0 - n, 0.0) / 8.0)
            out[y, x] = (clamped + (cur - clamped) * (0.05 + 0.95 * hw), var)
            moments[y, x] = (new_m, new_s, n)
    return out, moments


def _pass(f, inp, tiles, step):
    h, w = f.noisy.shape
    x16 = np.clip(inp, -65504, 65504).astype(np.float16).astype(np.float64)
    n16 = f.normal.astype(np.float16).astype(np.float64)
    lin = np.where(f.valid, f.depth, np.inf)
    out = np.zeros((h, w, 2))
    k3 = (1.0, 2.0 / 3.0, 1.0 / 6.0)
    vk = ((1 / 4, 1 / 8), (1 / 8, 1 / 16))

    def cl(y, x):
        return min(max(y, 0), h - 1), min(max(x, 0), w - 1)

    for y in range(h):
        for x in range(w):
            cleared, light = tiles[y // 8, x // 8]
            if cleared:
                out[y, x] = (float(light), 0.0)
                continue
            if not f.valid[y, x]:
                continue
            var = sum(
                vk[abs(i)][abs(j)] * x16[cl(y + j, x + i)][1]
                for j in (-1, 0, 1)
                for i in (-1, 0, 1)
            )
            sd = math.sqrt(max(var + 1e-9, 0.0))
            ws, s0, s1 = 1.0, x16[y, x, 0], x16[y, x, 1]
            for j in (-1, 0, 1):
                for i in (-1, 0, 1):
                    q = cl(y + j * step, x + i * step)
                    if (i == 0 and j == 0) or not f.valid[q]:
                        continue
                    wt = k3[abs(i)] * k3[abs(j)] * math.exp(-abs(x16[y, x, 0] - x16[q][0]) / sd)
                    wt *= math.exp(-abs(lin[y, x] - lin[q]) / 1.0)
                    wt *= min(max(float(np.dot(n16[y, x], n16[q])), 0.0), 1.0) ** 32
                    s0 += wt * x16[q][0]
                    s1 += wt * wt * x16[q][1]
                    ws += wt
            out[y, x] = (s0 / ws, s1 / (ws * ws))
    return out


def _reference(f, state):
    m, tw, th = _masks(f)
    tiles = _classify(f, m, tw, th)
    x, moments = _temporal(f, state, m, tw, tiles)
    passes = []
    for step in (1, 2, 4):
        x = _pass(f, x, tiles, step)
        passes.append(x)
    final = np.abs(x[..., 0]) ** np.maximum(1.2 - x[..., 1], 1.0)
    return final, passes[0], moments


def test_ffx_matches_the_per_pixel_transcription_on_a_frame_pair():
    f0, f1 = frame_pair()
    out0, s0, _ = ffx_step(f0, None)
    ref0, hist0, mom0 = _reference(f0, None)
    assert np.abs(out0 - ref0).max() < TOL
    assert np.abs(s0.history - hist0).max() < TOL and np.abs(s0.moments - mom0).max() < TOL
    out1, s1, rec = ffx_step(f1, s0)
    ref1, hist1, mom1 = _reference(f1, s0)
    assert np.abs(s1.moments - mom1).max() < TOL
    assert np.abs(out1 - ref1).max() < TOL
    # the frame pair exercises what it should: cleared and denoised tiles, history used
    assert 0 < rec["tiles_cleared"] < rec["tiles"]
    assert np.all(np.isfinite(out1))


def test_ffx_still_input_converges_to_its_mean():
    """A still frame with the same noise every frame: the temporal pass accumulates it."""
    f0, _ = frame_pair(seed=9)
    state, outs = None, []
    for _ in range(12):
        out, state, _ = ffx_step(f0, state)
        outs.append(out)
    assert np.abs(outs[-1] - outs[-2]).max() < np.abs(outs[1] - outs[0]).max()
