"""SVGF as NVIDIA Falcor ships it, and A-SVGF's gradient-based history rejection on top.

Source: NVIDIAGameWorks/Falcor commit eb540f6748774680ce0039aaf3ac9279266ec521,
``Source/RenderPasses/SVGFPass/`` (the shadow factor is the illumination: albedo 1, no
emission, so luminance is the value itself):

- defaults (``SVGFPass.h:70-77``): 4 a-trous iterations, feedback tap 1, ``phiColor = 10``,
  ``phiNormal = 128``, ``alpha = 0.05``, ``momentsAlpha = 0.2``;
- reprojection (``SVGFReproject.ps.slang``): previous position ``floor(posH) + motion * dim``,
  the four bilinear taps ``int2(posPrev) + {0,1}^2`` each valid when ``iposPrev`` lies in
  ``[1, dim - 1]``, ``|Zprev - Z| / (fwidthZ + 1e-2) <= 10`` and ``|n - nPrev| / (fwidthN +
  1e-2) <= 16``; if none is, a 3 x 3 cross-bilateral fallback around ``iposPrev``; history
  length ``min(32, h + 1)``; ``alpha = max(alpha, 1 / h)`` (1 without history); moments and
  variance ``max(0, m2 - m1^2)``;
- moments filter (``SVGFFilterMoments.ps.slang``): under 4 frames of history, a 7 x 7
  cross-bilateral estimate of the moments with ``phiDepth = 3 max(fwidthZ, 1e-8)``, variance
  times ``4 / h``;
- a-trous (``SVGFAtrous.ps.slang``, ``SVGFCommon.slang``): 5 x 5 taps ``{1, 2/3, 1/6}`` at
  step ``2^i``, ``w = exp(-|l - l_c| / (phiColor sqrt(var3x3 + 1e-10)) - |z - z_c| /
  (phiDepth |offset|)) max(0, n . n_c)^phiNormal``, variance weighted by ``w^2``; iteration
  ``feedbackTap``'s output is the next frame's history (``SVGFPass.cpp:370-386``).
- G-buffer: ``linearZ`` and ``max(|ddx z|, |ddy z|)``, normal ``length(fwidth(n))``
  (``GBuffer/GBufferRaster.3d.slang:150-157``), derivatives from 2 x 2 quads as a GPU's.

Motion: Falcor's is the previous uv minus the current (``prev = uv + motion``): the oracle's
pixels over the image size. Normals are kept in float32 (Falcor octahedral-packs them in
RGBA32F: a difference below 1e-6).

**A-SVGF** (C. Schied, C. Peters, C. Dachsbacher, Gradient Estimation for Real-Time Adaptive
Temporal Filtering, HPG 2018, doi:10.1145/3233301): one gradient sample per 3 x 3 stratum
(:mod:`.frames`): ``delta = f_new - f_old`` and ``max(f_new, f_old)``, both filtered over the
stratum grid by a-trous passes of steps 1, 2, 4 (kernel ``{1, 2/3, 1/6}``, valid strata
only; the paper's luminance edge-stopping left out); ``lambda = min(1, |delta| / max)``; the
temporal weights become ``(1 - lambda) alpha + lambda`` (colour and moments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import param

__all__ = ["SvgfParams", "SvgfState", "gradient_lambda", "svgf_step"]

F32 = np.float32
KERNEL = np.array([1.0, 2.0 / 3.0, 1.0 / 6.0], dtype=F32)
VAR_KERNEL = np.array([[1 / 4, 1 / 8], [1 / 8, 1 / 16]], dtype=F32)


_SRC = "Falcor eb540f6 SVGFPass.h:70-77"


@dataclass(frozen=True)
class SvgfParams:
    """SVGF's settings, Falcor's defaults."""

    iterations: int = param(
        4, source=_SRC, help="a-trous iterations (steps 1, 2, 4, ...)", lo=1, hi=8
    )
    feedback_tap: int = param(
        1,
        source=_SRC,
        help="the iteration whose output is the next history (-1: unfiltered)",
        lo=-1,
        hi=7,
    )
    phi_color: float = param(10.0, source=_SRC, help="luminance edge-stopping scale", lo=1e-6)
    phi_normal: float = param(128.0, source=_SRC, help="normal edge-stopping exponent", lo=0.0)
    alpha: float = param(0.05, source=_SRC, help="temporal blend of the colour", lo=0.0, hi=1.0)
    moments_alpha: float = param(
        0.2, source=_SRC, help="temporal blend of the moments", lo=0.0, hi=1.0
    )


@dataclass
class SvgfState:
    illum: np.ndarray  # (H, W, 2): filtered past (value, variance)
    moments: np.ndarray  # (H, W, 2)
    history: np.ndarray  # (H, W)
    z: np.ndarray  # (H, W, 2) linear z (-1 sky) and its fwidth
    normal: np.ndarray  # (H, W, 3)


def _quad_fwidth(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``|ddx|``, ``|ddy|`` of ``a`` (H, W, ...) from aligned 2 x 2 quads (fine derivatives)."""
    h, w = a.shape[:2]
    xx = np.minimum(np.arange(w) ^ 1, w - 1)
    yy = np.minimum(np.arange(h) ^ 1, h - 1)
    return np.abs(a[:, xx] - a), np.abs(a[yy] - a)


def gbuffer_z_normal(frame) -> tuple[np.ndarray, np.ndarray]:
    """``(H, W, 2)`` linear z (-1 on sky) with ``max(|ddx z|, |ddy z|)``, and ``(H, W)``
    ``length(fwidth(n))``."""
    z = np.where(frame.valid, frame.depth, F32(-1.0)).astype(F32)
    dx, dy = _quad_fwidth(z)
    zz = np.stack([z, np.maximum(dx, dy)], -1).astype(F32)
    nx, ny = _quad_fwidth(frame.normal)
    fw = np.sqrt(np.sum((nx + ny) ** 2, axis=-1)).astype(F32)
    return zz, fw


def _weight(zc, zp, phi_depth, nc, np_, phi_normal, lc, lp, phi_l):
    """``computeWeight`` (SVGFCommon.slang)."""
    wn = np.clip(np.sum(nc * np_, axis=-1), 0.0, 1.0) ** phi_normal
    with np.errstate(divide="ignore", invalid="ignore"):
        wz = np.where(phi_depth == 0, F32(0.0), np.abs(zc - zp) / phi_depth)
        wl = np.abs(lc - lp) / phi_l
    return (np.exp(-np.maximum(wl, 0) - np.maximum(wz, 0)) * wn).astype(F32)


def _load(a: np.ndarray, y, x):
    """Texture ``Load`` with zeros outside."""
    h, w = a.shape[:2]
    inside = (y >= 0) & (y < h) & (x >= 0) & (x < w)
    v = a[np.clip(y, 0, h - 1), np.clip(x, 0, w - 1)]
    mask = inside if v.ndim == inside.ndim else inside[..., None]
    return np.where(mask, v, F32(0.0))


def _valid_reproj(ipy, ipx, z, zprev, fwz, n, nprev, fwn, h, w):
    ok = (ipx >= 1) & (ipy >= 1) & (ipx <= w - 1) & (ipy <= h - 1)
    ok &= ~(np.abs(zprev - z) / (fwz + F32(1e-2)) > 10.0)
    ok &= ~(np.linalg.norm(n - nprev, axis=-1) / (fwn + F32(1e-2)) > 16.0)
    return ok


def _reproject(frame, state, zz, fwn):
    """``loadPrevData``: previous (value, variance-less) illumination, moments, history and
    success at every pixel."""
    h, w = zz.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    mot = frame.motion.astype(F32)  # = motion_uv * dim
    ipx = (xs + mot[..., 0] + F32(0.5)).astype(np.int64)
    ipy = (ys + mot[..., 1] + F32(0.5)).astype(np.int64)
    ppx, ppy = (xs + mot[..., 0]).astype(F32), (ys + mot[..., 1]).astype(F32)
    bx, by = ppx.astype(np.int64), ppy.astype(np.int64)  # int2(): towards zero
    z, n = zz[..., 0], frame.normal
    fx, fy = ppx - np.floor(ppx), ppy - np.floor(ppy)
    wts = [(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy]
    illum = np.zeros((h, w), F32)
    mom = np.zeros((h, w, 2), F32)
    sumw = np.zeros((h, w), F32)
    anyv = np.zeros((h, w), bool)
    for k, (ox, oy) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
        ly, lx = by + oy, bx + ox
        zp = _load(state.z[..., 0], ly, lx)
        nprev = _load(state.normal, ly, lx)
        v = _valid_reproj(ipy, ipx, z, zp, zz[..., 1], n, nprev, fwn, h, w)
        anyv |= v
        wk = np.where(v, wts[k], F32(0.0))
        illum += wk * _load(state.illum[..., 0], ly, lx)
        mom += wk[..., None] * _load(state.moments, ly, lx)
        sumw += wk
    ok = anyv & (sumw >= 0.01)
    with np.errstate(invalid="ignore", divide="ignore"):
        illum = np.where(ok, illum / sumw, F32(0.0))
        mom = np.where(ok[..., None], mom / sumw[..., None], F32(0.0))
    # the 3 x 3 cross-bilateral fallback around iposPrev
    fb_i = np.zeros((h, w), F32)
    fb_m = np.zeros((h, w, 2), F32)
    cnt = np.zeros((h, w), F32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ly, lx = ipy + dy, ipx + dx
            v = _valid_reproj(
                ipy,
                ipx,
                z,
                _load(state.z[..., 0], ly, lx),
                zz[..., 1],
                n,
                _load(state.normal, ly, lx),
                fwn,
                h,
                w,
            )
            fb_i += np.where(v, _load(state.illum[..., 0], ly, lx), F32(0.0))
            fb_m += np.where(v[..., None], _load(state.moments, ly, lx), F32(0.0))
            cnt += v
    use_fb = ~anyv | ~ok
    fb_ok = use_fb & (cnt > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        illum = np.where(fb_ok, fb_i / cnt, illum)
        mom = np.where(fb_ok[..., None], fb_m / cnt[..., None], mom)
    success = np.where(use_fb, fb_ok, ok)
    hist = np.where(success, _load(state.history, ipy, ipx), F32(0.0))
    illum = np.where(success, illum, F32(0.0))
    mom = np.where(success[..., None], mom, F32(0.0))
    return illum.astype(F32), mom.astype(F32), hist.astype(F32), success


def _filter_moments(illum, moments, hist, zz, normal, p: SvgfParams):
    """SVGFFilterMoments.ps.slang: ``(H, W, 2)`` (value, variance)."""
    h, w = hist.shape
    ys, xs = np.mgrid[0:h, 0:w]
    lc, zc, zd = illum[..., 0], zz[..., 0], zz[..., 1]
    phi_depth = np.maximum(zd, F32(1e-8)) * F32(3.0)
    sw = np.zeros((h, w), F32)
    si = np.zeros((h, w), F32)
    sm = np.zeros((h, w, 2), F32)
    for dy in range(-3, 4):
        for dx in range(-3, 4):
            py, px = ys + dy, xs + dx
            inside = (py >= 0) & (py < h) & (px >= 0) & (px < w)
            cy, cx = np.clip(py, 0, h - 1), np.clip(px, 0, w - 1)
            wt = _weight(
                zc,
                zz[cy, cx, 0],
                phi_depth * F32(np.hypot(dx, dy)),
                normal,
                normal[cy, cx],
                p.phi_normal,
                lc,
                illum[cy, cx, 0],
                F32(p.phi_color),
            )
            wt = np.where(inside, wt, F32(0.0))
            sw += wt
            si += wt * illum[cy, cx, 0]
            sm += wt[..., None] * moments[cy, cx]
    sw = np.maximum(sw, F32(1e-6))
    si, sm = si / sw, sm / sw[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        var = (sm[..., 1] - sm[..., 0] * sm[..., 0]) * (F32(4.0) / hist)
    out = np.stack([si, var], -1).astype(F32)
    keep = (hist >= 4.0) | (zc < 0)
    return np.where(keep[..., None], illum, out)


def _atrous(illum, zz, normal, step: int, p: SvgfParams):
    """SVGFAtrous.ps.slang, one iteration."""
    h, w = zz.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    var = np.zeros((h, w), F32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            var += VAR_KERNEL[abs(dx), abs(dy)] * _load(illum[..., 1], ys + dy, xs + dx)
    phi_l = F32(p.phi_color) * np.sqrt(np.maximum(F32(0.0), F32(1e-10) + var))
    phi_depth = np.maximum(zz[..., 1], F32(1e-8)) * F32(step)
    lc, zc = illum[..., 0], zz[..., 0]
    sw = np.ones((h, w), F32)
    s = illum.copy()
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            if dx == 0 and dy == 0:
                continue
            py, px = ys + dy * step, xs + dx * step
            inside = (py >= 0) & (py < h) & (px >= 0) & (px < w)
            cy, cx = np.clip(py, 0, h - 1), np.clip(px, 0, w - 1)
            wt = _weight(
                zc,
                zz[cy, cx, 0],
                phi_depth * F32(np.hypot(dx, dy)),
                normal,
                normal[cy, cx],
                p.phi_normal,
                lc,
                illum[cy, cx, 0],
                phi_l,
            )
            wt = np.where(inside, wt * KERNEL[abs(dx)] * KERNEL[abs(dy)], F32(0.0))
            sw += wt
            s += np.stack([wt, wt * wt], -1) * illum[cy, cx]
    out = np.stack([s[..., 0] / sw, s[..., 1] / (sw * sw)], -1).astype(F32)
    return np.where((zc < 0)[..., None], illum, out)


def gradient_lambda(frame, shape) -> np.ndarray:
    """A-SVGF's ``lambda`` ``(H, W)`` from the frame's gradient samples (module docstring)."""
    h, w = shape
    valid = frame.grad_valid
    delta = np.where(valid, frame.grad_new - frame.grad_old, F32(0.0)).astype(F32)
    norm = np.where(valid, np.maximum(frame.grad_new, frame.grad_old), F32(0.0)).astype(F32)
    wv = valid.astype(F32)
    hs, ws = valid.shape
    ys, xs = np.mgrid[0:hs, 0:ws]
    for step in (1, 2, 4):
        sd, sn, sw = (np.zeros((hs, ws), F32) for _ in range(3))
        for dy in range(-2, 3):
            for dx in range(-2, 3):
                py, px = ys + dy * step, xs + dx * step
                inside = (py >= 0) & (py < hs) & (px >= 0) & (px < ws)
                cy, cx = np.clip(py, 0, hs - 1), np.clip(px, 0, ws - 1)
                k = np.where(inside, KERNEL[abs(dx)] * KERNEL[abs(dy)] * wv[cy, cx], F32(0.0))
                sd += k * delta[cy, cx]
                sn += k * norm[cy, cx]
                sw += k
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = np.where(sw > 0, sd / sw, F32(0.0)).astype(F32)
            norm = np.where(sw > 0, sn / sw, F32(0.0)).astype(F32)
        wv = (sw > 0).astype(F32)
    with np.errstate(invalid="ignore", divide="ignore"):
        lam = np.where(norm > 1e-6, np.minimum(np.abs(delta) / norm, F32(1.0)), F32(0.0))
    full = np.repeat(np.repeat(lam.astype(F32), 3, axis=0), 3, axis=1)
    return full[:h, :w]


def svgf_step(frame, state: SvgfState | None, p: SvgfParams | None = None, *, adaptive=False):
    """One frame: ``(visibility (H, W) float32, new state, record)``; ``adaptive`` runs
    A-SVGF's gradient-based rejection (``record["lambda"]``)."""
    p = SvgfParams() if p is None else p
    h, w = frame.noisy.shape
    zz, fwn = gbuffer_z_normal(frame)
    cur = np.where(frame.valid, frame.noisy, F32(0.0)).astype(F32)
    if state is None:
        prev_i = np.zeros((h, w), F32)
        prev_m = np.zeros((h, w, 2), F32)
        hist = np.zeros((h, w), F32)
        ok = np.zeros((h, w), bool)
    else:
        prev_i, prev_m, hist, ok = _reproject(frame, state, zz, fwn)
    hist = np.minimum(F32(32.0), np.where(ok, hist + F32(1.0), F32(1.0))).astype(F32)
    alpha = np.where(ok, np.maximum(F32(p.alpha), F32(1.0) / hist), F32(1.0))
    alpha_m = np.where(ok, np.maximum(F32(p.moments_alpha), F32(1.0) / hist), F32(1.0))
    record: dict = {}
    if adaptive:
        lam = gradient_lambda(frame, (h, w))
        alpha = (F32(1.0) - lam) * alpha + lam
        alpha_m = (F32(1.0) - lam) * alpha_m + lam
        record["lambda"] = lam
    m = np.stack([cur, cur * cur], -1)
    m = (prev_m + (m - prev_m) * alpha_m[..., None]).astype(F32)
    var = np.maximum(F32(0.0), m[..., 1] - m[..., 0] * m[..., 0])
    illum = np.stack([prev_i + (cur - prev_i) * alpha, var], -1).astype(F32)
    x = _filter_moments(illum, m, hist, zz, frame.normal, p)
    past = illum
    tap = min(p.feedback_tap, p.iterations - 1)
    for i in range(p.iterations):
        x = _atrous(x, zz, frame.normal, 1 << i, p)
        if i == tap:
            past = x
    if p.feedback_tap < 0:
        past = illum
    new = SvgfState(illum=past, moments=m, history=hist, z=zz, normal=frame.normal)
    out = np.where(frame.valid, x[..., 0], F32(0.0)).astype(F32)
    record["history_length"] = hist
    return out, new, record
