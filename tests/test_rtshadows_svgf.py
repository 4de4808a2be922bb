"""SVGF (Falcor eb540f6 SVGFPass) and A-SVGF's gradient rejection against per-pixel
transcriptions of the slang passes on a hand-built frame pair (history, motion,
disocclusion)."""

from __future__ import annotations

import math

import numpy as np
from raster_oracle.raster_models.rtshadows.svgf import (
    SvgfParams,
    gbuffer_z_normal,
    gradient_lambda,
    svgf_step,
)

from tests._rtshadows_frames import frame_pair

#: float32 model against a float64 per-pixel transcription
TOL = 1e-6
P = SvgfParams()
K3 = (1.0, 2.0 / 3.0, 1.0 / 6.0)


def _load(a, y, x):
    h, w = a.shape[:2]
    if 0 <= y < h and 0 <= x < w:
        return np.asarray(a[y, x], dtype=np.float64)
    return np.zeros(a.shape[2:])


def _weight(zc, zp, phid, nc, nq, lc, lp, phil):
    wn = min(max(float(np.dot(nc, nq)), 0.0), 1.0) ** P.phi_normal
    wz = 0.0 if phid == 0 else abs(zc - zp) / phid
    return math.exp(-max(abs(lc - lp) / phil, 0.0) - max(wz, 0.0)) * wn


def _valid(ipy, ipx, z, zp, fz, n, nq, fn, h, w):
    if ipx < 1 or ipy < 1 or ipx > w - 1 or ipy > h - 1:
        return False
    if abs(zp - z) / (fz + 1e-2) > 10.0:
        return False
    return not np.linalg.norm(n - nq) / (fn + 1e-2) > 16.0


def _reproject_pixel(f, st, zz, fwn, y, x):
    h, w = zz.shape[:2]
    mx, my = f.motion[y, x]
    ipx, ipy = int(x + mx + 0.5), int(y + my + 0.5)
    px, py = x + mx, y + my
    z, n = zz[y, x, 0], f.normal[y, x]
    fx, fy = px - math.floor(px), py - math.floor(py)
    wts = ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy)
    offs = ((0, 0), (1, 0), (0, 1), (1, 1))
    vs = [
        _valid(
            ipy,
            ipx,
            z,
            _load(st.z, int(py) + oy, int(px) + ox)[0],
            zz[y, x, 1],
            n,
            _load(st.normal, int(py) + oy, int(px) + ox),
            fwn[y, x],
            h,
            w,
        )
        for ox, oy in offs
    ]
    ill, mom, sw, ok = 0.0, np.zeros(2), 0.0, any(vs)
    if ok:
        for k, (ox, oy) in enumerate(offs):
            if vs[k]:
                ill += wts[k] * _load(st.illum, int(py) + oy, int(px) + ox)[0]
                mom += wts[k] * _load(st.moments, int(py) + oy, int(px) + ox)
                sw += wts[k]
        ok = sw >= 0.01
        ill, mom = (ill / sw, mom / sw) if ok else (0.0, np.zeros(2))
    if not ok:
        cnt, ill, mom = 0, 0.0, np.zeros(2)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                q = (ipy + dy, ipx + dx)
                if _valid(
                    ipy,
                    ipx,
                    z,
                    _load(st.z, *q)[0],
                    zz[y, x, 1],
                    n,
                    _load(st.normal, *q),
                    fwn[y, x],
                    h,
                    w,
                ):
                    ill += _load(st.illum, *q)[0]
                    mom = mom + _load(st.moments, *q)
                    cnt += 1
        ok = cnt > 0
        ill, mom = (ill / cnt, mom / cnt) if ok else (0.0, np.zeros(2))
    hist = float(_load(st.history, ipy, ipx)) if ok else 0.0
    return ill, mom, hist, ok


def _reference(f, st, lam=None):
    h, w = f.noisy.shape
    zz, fwn = gbuffer_z_normal(f)
    zz, fwn = zz.astype(np.float64), fwn.astype(np.float64)
    illum = np.zeros((h, w, 2))
    moms = np.zeros((h, w, 2))
    hists = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            cur = float(f.noisy[y, x]) if f.valid[y, x] else 0.0
            if st is None:
                pi, pm, hi, ok = 0.0, np.zeros(2), 0.0, False
            else:
                pi, pm, hi, ok = _reproject_pixel(f, st, zz, fwn, y, x)
            hi = min(32.0, hi + 1.0 if ok else 1.0)
            a = max(P.alpha, 1.0 / hi) if ok else 1.0
            am = max(P.moments_alpha, 1.0 / hi) if ok else 1.0
            if lam is not None:
                a, am = (1 - lam[y, x]) * a + lam[y, x], (1 - lam[y, x]) * am + lam[y, x]
            m = pm + (np.array([cur, cur * cur]) - pm) * am
            illum[y, x] = (pi + (cur - pi) * a, max(0.0, m[1] - m[0] ** 2))
            moms[y, x], hists[y, x] = m, hi
    # SVGFFilterMoments
    x0 = illum.copy()
    for y in range(h):
        for x in range(w):
            if hists[y, x] >= 4.0 or zz[y, x, 0] < 0:
                continue
            sw, si, sm = 0.0, 0.0, np.zeros(2)
            for dy in range(-3, 4):
                for dx in range(-3, 4):
                    qy, qx = y + dy, x + dx
                    if not (0 <= qy < h and 0 <= qx < w):
                        continue
                    wt = _weight(
                        zz[y, x, 0],
                        zz[qy, qx, 0],
                        max(zz[y, x, 1], 1e-8) * 3.0 * math.hypot(dx, dy),
                        f.normal[y, x],
                        f.normal[qy, qx],
                        illum[y, x, 0],
                        illum[qy, qx, 0],
                        P.phi_color,
                    )
                    sw, si, sm = sw + wt, si + wt * illum[qy, qx, 0], sm + wt * moms[qy, qx]
            sw = max(sw, 1e-6)
            si, sm = si / sw, sm / sw
            x0[y, x] = (si, (sm[1] - sm[0] ** 2) * 4.0 / hists[y, x])
    x = x0
    past = None
    for it in range(P.iterations):
        step, nxt = 1 << it, x.copy()
        for y in range(h):
            for xx in range(w):
                if zz[y, xx, 0] < 0:
                    continue
                var = sum(
                    (0.25, 0.125, 0.0625)[abs(i) + abs(j)] * _load(x, y + j, xx + i)[1]
                    for j in (-1, 0, 1)
                    for i in (-1, 0, 1)
                )
                phil = P.phi_color * math.sqrt(max(0.0, 1e-10 + var))
                sw, s = 1.0, x[y, xx].copy()
                for j in range(-2, 3):
                    for i in range(-2, 3):
                        qy, qx = y + j * step, xx + i * step
                        if (i == 0 and j == 0) or not (0 <= qy < h and 0 <= qx < w):
                            continue
                        wt = (
                            _weight(
                                zz[y, xx, 0],
                                zz[qy, qx, 0],
                                max(zz[y, xx, 1], 1e-8) * step * math.hypot(i, j),
                                f.normal[y, xx],
                                f.normal[qy, qx],
                                x[y, xx, 0],
                                x[qy, qx, 0],
                                phil,
                            )
                            * K3[abs(i)]
                            * K3[abs(j)]
                        )
                        sw += wt
                        s += np.array([wt, wt * wt]) * x[qy, qx]
                nxt[y, xx] = (s[0] / sw, s[1] / (sw * sw))
        x = nxt
        if it == P.feedback_tap:
            past = x
    return np.where(f.valid, x[..., 0], 0.0), past, moms, hists


def _lambda_reference(f):
    v = f.grad_valid
    d = np.where(v, f.grad_new - f.grad_old, 0.0).astype(np.float64)
    n = np.where(v, np.maximum(f.grad_new, f.grad_old), 0.0).astype(np.float64)
    wv = v.astype(np.float64)
    hs, ws = v.shape
    for step in (1, 2, 4):
        nd, nn, nw = np.zeros((hs, ws)), np.zeros((hs, ws)), np.zeros((hs, ws))
        for y in range(hs):
            for x in range(ws):
                sd = sn = sw = 0.0
                for j in range(-2, 3):
                    for i in range(-2, 3):
                        qy, qx = y + j * step, x + i * step
                        if 0 <= qy < hs and 0 <= qx < ws:
                            k = K3[abs(i)] * K3[abs(j)] * wv[qy, qx]
                            sd, sn, sw = sd + k * d[qy, qx], sn + k * n[qy, qx], sw + k
                nd[y, x] = sd / sw if sw > 0 else 0.0
                nn[y, x] = sn / sw if sw > 0 else 0.0
                nw[y, x] = sw > 0
        d, n, wv = nd, nn, nw
    lam = np.where(n > 1e-6, np.minimum(np.abs(d) / np.where(n > 0, n, 1), 1.0), 0.0)
    h, w = f.noisy.shape
    return np.repeat(np.repeat(lam, 3, 0), 3, 1)[:h, :w]


def test_svgf_matches_the_per_pixel_transcription_on_a_frame_pair():
    f0, f1 = frame_pair()
    out0, s0, _ = svgf_step(f0, None)
    ref0, past0, _, _ = _reference(f0, None)
    assert np.abs(out0 - ref0).max() < TOL and np.abs(s0.illum - past0).max() < TOL
    out1, s1, rec = svgf_step(f1, s0)
    ref1, past1, m1, h1 = _reference(f1, s0)
    assert np.abs(s1.moments - m1).max() < TOL and np.array_equal(s1.history, h1)
    assert np.abs(out1 - ref1).max() < TOL
    # history was found (and lost where the box uncovered the wall)
    assert h1.max() == 2.0 and h1.min() == 1.0


def test_asvgf_lambda_and_step_match_the_transcription():
    f0, f1 = frame_pair()
    lam = gradient_lambda(f1, f1.noisy.shape)
    want = _lambda_reference(f1)
    assert np.abs(lam - want).max() < TOL
    assert 0.0 < lam.max() <= 1.0
    _, s0, _ = svgf_step(f0, None, adaptive=True)
    out1, _, rec = svgf_step(f1, s0, adaptive=True)
    ref1, _, _, _ = _reference(f1, s0, lam=want)
    assert np.abs(out1 - ref1).max() < TOL
    assert np.array_equal(rec["lambda"], lam)


def test_asvgf_without_change_keeps_svgf():
    """No gradient (f_new == f_old everywhere): A-SVGF is SVGF."""
    f0, f1 = frame_pair()
    f1.grad_old = f1.grad_new.copy()
    _, s0, _ = svgf_step(f0, None)
    a, _, _ = svgf_step(f1, s0)
    b, _, rec = svgf_step(f1, s0, adaptive=True)
    assert np.array_equal(a, b) and rec["lambda"].max() == 0.0
