"""The SIGMA-class model against a per-pixel transcription of its documented steps (NRD
a822d87 settings and constants: tiles, blur radius from the penumbra, dense + sparse blur,
stabilisation) on a hand-built frame pair."""

from __future__ import annotations

import math

import numpy as np
from raster_oracle.raster_models.rtshadows.sigma import SPECIAL8, classify_tiles, sigma_step

from tests._rtshadows_frames import frame_pair

TOL = 1e-6  # float64 model (float32 output) against float64 loops
LIT = 65504.0


def _ss(a, b, x):
    t = min(max((x - a) / (b - a), 0.0), 1.0)
    return t * t * (3 - 2 * t)


def _radius(p, size, scale=1.0):
    r = p / size * scale
    return min(max(r, min(r, 2.0)), 32.0)


def _tiles(f):
    h, w = f.noisy.shape
    th, tw = -(-h // 16), -(-w // 16)
    x, y = np.zeros((th, tw)), np.zeros((th, tw))
    for ty in range(th):
        for tx in range(tw):
            a_lit = a_umb = True
            rmax = 0.0
            for yy in range(ty * 16, ty * 16 + 16):
                for xx in range(tx * 16, tx * 16 + 16):
                    if yy >= h or xx >= w:
                        continue
                    p, inf = float(f.penumbra[yy, xx]), not f.valid[yy, xx]
                    lit = p >= LIT
                    a_lit &= lit or inf or p == 0
                    a_umb &= (not lit) or inf or p == 0
                    if not inf:
                        rmax = max(rmax, _radius(0.0 if lit else p, float(f.pixel_size[yy, xx])))
            x[ty, tx] = 0.0 if (a_lit or a_umb) else 1.0
            y[ty, tx] = min(max(rmax / 16.0, 0.0), 1.0)
    out = np.zeros((th, tw))
    for ty in range(th):
        for tx in range(tw):
            k = 1.01 / (y[ty, tx] + 0.01)
            s = t = 0.0
            for dj in (-1, 0, 1):
                for di in (-1, 0, 1):
                    wt = 2.0 ** (-k * (di * di + dj * dj))
                    s += x[min(max(ty + dj, 0), th - 1), min(max(tx + di, 0), tw - 1)] * wt
                    t += wt
            out[ty, tx] = s / t
    return np.repeat(np.repeat(out, 16, 0), 16, 1)[:h, :w]


def _plane(f, y, x, qy, qx):
    fr = min(f.noisy.shape) * float(f.pixel_size[y, x])
    d = abs(float(np.dot(f.normal[y, x], f.position[qy, qx] - f.position[y, x])))
    return _ss(1.0, 0.0, d / max(0.02 * fr, 1e-12))


def _blur(f, s, pen, tile, rot):
    h, w = s.shape
    rs, rp = s.copy(), pen.copy()
    for y in range(h):
        for x in range(w):
            pc = pen[y, x]
            if tile[y, x] == 0 or pc == 0 or not f.valid[y, x]:
                continue
            size = max(float(f.pixel_size[y, x]), 1e-12)
            res = sx = pe = sy = 0.0
            for j in range(-2, 3):
                for i in range(-2, 3):
                    qy, qx = min(max(y + j, 0), h - 1), min(max(x + i, 0), w - 1)
                    pn = pen[qy, qx]
                    if i == 0 and j == 0:
                        wt = 1.0
                    else:
                        wt = float((pn == 0) == (pc == 0)) * math.exp(
                            -0.66 * (math.hypot(i, j) / 2) ** 2
                        )
                        wt *= _plane(f, y, x, qy, qx) * f.valid[qy, qx]
                    res += wt * s[qy, qx]
                    sx += wt
                    wp = wt * size / (size + pn) * (pn < LIT)
                    pe += wp * pn
                    sy += wp
            res /= sx
            pe /= max(sy, 1e-6)
            sy = float(sy != 0)
            fb = _ss(0.0, 2.0, pe / size)
            res = s[y, x] + (res - s[y, x]) * fb
            fb = 4.0 - 3.0 * fb
            res, pe, sx, sy = res * fb, pe * fb, fb, sy * fb
            radius = _radius(pe, size) * tile[y, x]
            radius = min(max(radius, min(radius, 2.0)), 32.0)
            inv = 1.0 / max(pe, 1e-6)
            for ox, oy, oz in SPECIAL8.astype(np.float64):
                rx = math.cos(rot) * ox - math.sin(rot) * oy
                ry = math.sin(rot) * ox + math.cos(rot) * oy
                fx, fy = x + 0.5 + rx * radius, y + 0.5 + ry * radius
                mx = -fx if fx < 0 else (2 * w - fx if fx > w else fx)
                my = -fy if fy < 0 else (2 * h - fy if fy > h else fy)
                wt = 1.0 if (mx != fx or my != fy) else math.exp(-0.66 * oz * oz)
                qx, qy = min(max(int(mx), 0), w - 1), min(max(int(my), 0), h - 1)
                pn = pen[qy, qx]
                wt *= float((pn == 0) == (pc == 0)) * min(max(pn * inv, 0.0), 1.0)
                wt *= _plane(f, y, x, qy, qx) * f.valid[qy, qx]
                res += s[qy, qx] * wt
                sx += wt
                wp = wt * size / (size + pn) * (pn < LIT)
                pe += 0.0 if wp == 0 else pn * wp
                sy += wp
            rs[y, x] = res / sx
            rp[y, x] = pc if sy == 0 else pe / sy
    return rs, rp


def _stabilise(f, st, s, pen, tile):
    h, w = s.shape
    out, hl = np.zeros((h, w)), np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            m1 = m2 = tot = 0.0
            for j in range(-2, 3):
                for i in range(-2, 3):
                    qy, qx = min(max(y + j, 0), h - 1), min(max(x + i, 0), w - 1)
                    wt = (
                        1.0
                        if i == j == 0
                        else float((pen[qy, qx] == 0) == (pen[y, x] == 0))
                        * math.exp(-0.66 * (math.hypot(i, j) / 2) ** 2)
                    )
                    m1, m2, tot = m1 + s[qy, qx] * wt, m2 + s[qy, qx] ** 2 * wt, tot + wt
            m1, m2 = m1 / tot, m2 / tot
            sig = math.sqrt(max(m2 - m1 * m1, 0.0))
            if st is None:
                L, hist = 0.0, s[y, x]
            else:
                px, py = x + f.motion[y, x, 0], y + f.motion[y, x, 1]
                x0, y0 = math.floor(px), math.floor(py)
                fx, fy = px - x0, py - y0
                thr = 0.02 * min(h, w) * float(f.pixel_size[y, x]) - 1e-6
                nh = nl = den = 0.0
                for dy, dx, bw in (
                    (0, 0, (1 - fx) * (1 - fy)),
                    (0, 1, fx * (1 - fy)),
                    (1, 0, (1 - fx) * fy),
                    (1, 1, fx * fy),
                ):
                    ty, tx = y0 + dy, x0 + dx
                    if (
                        0 <= ty < h
                        and 0 <= tx < w
                        and abs(st.depth[ty, tx] - f.depth_previous[y, x]) <= thr
                    ):
                        nh, nl, den = (
                            nh + bw * st.shadow[ty, tx],
                            nl + bw * st.history[ty, tx],
                            den + bw,
                        )
                ok = den > 1e-4
                hist = min(max(nh / max(den, 1e-4), 0.0), 1.0) if ok else s[y, x]
                L = nl / max(den, 1e-4) if ok else 0.0
            sig *= 3.0 + (1.0 - 3.0) / (1.0 + L)
            cl = min(max(hist, m1 - sig), m1 + sig)
            al = min(max(1.0 - math.sqrt(abs(cl - hist)), 0.0), 1.0)
            L *= al
            hw = L / (1 + L)
            cl += (hist - cl) * (0.6 * hw * al)
            sw = 1.0 - min(5.0 / 6.0, hw)
            o = cl + (s[y, x] - cl) * sw
            L = min(L + 1.0, 7.0)
            if tile[y, x] == 0 or pen[y, x] == 0:
                o, L = s[y, x], 7.0
            out[y, x], hl[y, x] = (o if f.valid[y, x] else 0.0), L
    return out, hl


def _reference(f, st):
    tile = _tiles(f)
    s = np.where(f.valid, (f.penumbra >= LIT).astype(float), 0.0)
    pen = np.where(f.valid, f.penumbra, 0.0).astype(np.float64)
    ga = math.pi * (3 - math.sqrt(5))
    s1, p1 = _blur(f, s, pen, tile, f.index * ga)
    s2, p2 = _blur(f, s1, p1, tile, f.index * ga + 0.5 * ga)
    return tile, s1, _stabilise(f, st, s2, p2, tile)


def test_sigma_matches_the_per_pixel_transcription_on_a_frame_pair():
    f0, f1 = frame_pair()
    out0, s0, rec0 = sigma_step(f0, None)
    tile, s1, (ref0, hl0) = _reference(f0, None)
    assert np.abs(classify_tiles(f0) - tile).max() < 1e-6
    assert 0 < tile.max() and tile.min() < tile.max()
    assert np.abs(rec0["blur"] - s1).max() < TOL
    assert np.abs(out0 - ref0).max() < TOL and np.abs(s0.history - hl0).max() < TOL
    out1, s1_, _ = sigma_step(f1, s0)
    _, _, (ref1, hl1) = _reference(f1, s0)
    assert np.abs(out1 - ref1).max() < TOL and np.abs(s1_.history - hl1).max() < TOL
    # the history was used somewhere (length above 1 where not hard shadow)
    assert (hl1[(hl1 < 7.0)] > 1.0).any()
