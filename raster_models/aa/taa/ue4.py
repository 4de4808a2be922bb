"""Unreal Engine 4.19's main temporal AA pass at ``r.PostProcessAAQuality`` 4 (``preset=ue4``),
its ``MainFastTemporalAA`` at quality 3 (``preset=ue4-high``), 4.18.3's main pass
(``preset=ue4-18``) and 4.20's (``preset=ue4-20``).

Quality: ``BaseScalability.ini`` (same repository, 04475707d16b) maps ``sg.AntiAliasingQuality``
3 (Epic) to ``r.PostProcessAAQuality`` 4 and 2 (High) to 3; ``PostProcessTemporalAA.cpp``
takes ``bUseFast = Quality == 3``, which draws ``MainFastTemporalAAPS``: the same
``PostProcessTemporalCommon.ush`` without ``AA_TONE`` (the plus weights alone, no
``1 / (Y + 4)`` and no renormalization) and without ``AA_DYNAMIC_ANTIGHOST`` (alpha written 0).

Which tree is 4.19: the stored repository Kryptexas/UE4-GameWorks-4.19.2 holds several
engine versions of these files (its PostProcessTemporalCommon.ush at 1d2c1e48bf49 sits next
to a Build.version of 4.17); the version pinned here (0341e5d5) differs from 4.18.3
(windystrife/UnrealEngine_NVIDIAGameWorks, Build.version 4.18.3 at 0bd1222b5959;
PostProcessTemporalAA.cpp at 0f9675ae7119) by exactly two things -- ``r.TemporalAACatmullRom``
defaults to 1 instead of 0, and the anti-flicker block of the blend (``+0.8 saturate(...)``,
``x (L_min + 0.5) / (L_max + 0.5)``) is compiled instead of ``#if 0`` -- so it is the later
one, the repository's 4.19 (the clean 4.19.2 tree Andra-Games-Entertainment/Unreal-Engine-4.19.2
at 591426c2af65 has the same ``r.TemporalAACatmullRom`` 1). ``ue4-18`` runs the same
transcription with those two undone. ``ue4-20``: 4.20.3's ``PostProcessTemporalAA.usf`` as a
licensee's branch has it, not Epic's release (Epic's EpicGames/UnrealEngine is readable only
by linked accounts and was not read): blackix/blackix at 03236bd0c684, a partner's fork
(Build.version 4.20.3, ``TAA_PASS_CONFIG`` 1 Main, not
``TAA_FAST``) with the C++ of folgerwang/UnrealEngine's ``PostProcessTemporalAA.cpp`` at
19747897ecf5 (``r.TemporalAACatmullRom`` 0, ``HistoryBufferUVMinMax`` at the outer texel
centres, ``TAA_CAMERA_CUT`` when no history exists): 4.18's blend and weights, the anti-ghost
reset folded into ``IgnoreHistory`` (applied after the luma and the clamp) and the first
frame a camera cut (the filtered current frame, blend 1); its per-tap history-UV clamps give
the values of 4.19's clamp-to-edge on a full-viewport history.

Pinned sources (github.com/Kryptexas/UE4-GameWorks-4.19.2, commit 0341e5d5c1c2, Epic's 4.19
tree): ``PostProcessTemporalAA.cpp`` (``r.PostProcessAAQuality`` 4 is not 3, so
``MainTemporalAAPS`` runs; ``r.TemporalAACatmullRom`` 1: the plus weights are
``CatmullRom(o.x - j.x) CatmullRom(o.y - j.y)`` renormalized over the plus;
``r.TemporalAACurrentFrameWeight`` 0.04; the output is ``PF_FloatRGBA``),
``PostProcessTemporalAA.usf`` (``MainTemporalAACommon``: ``AA_FILTERED``, ``AA_BORDER``,
``AA_CROSS`` 2, ``AA_AABB`` 0, ``AA_ROUND`` 0, ``AA_YCOCG``, ``AA_BICUBIC``,
``AA_DYNAMIC_ANTIGHOST``, ``AA_TONE``, ``AA_CLAMP``, 5 samples; ``RGBToYCoCg`` with Y = R +
2G + B; ``HdrWeightY`` ``1 / (Y + 4)``; ``WeightedLerp``), ``PostProcessTemporalCommon.ush``
(the resolve), ``Common.ush`` (``Texture2DSampleBicubic``: 5-tap Catmull-Rom),
``SceneVisibility.cpp`` (r.TemporalAASamples 8 takes the ``else`` branch: ``Halton(i + 1)``
in bases 2, 3 through the windowed Box-Muller transform, sigma 0.47, the projection moved by
``(2 x / W, -2 y / H)``: pixel ``c`` sees the point at ``c - (x, y)``, y down), ``SceneRendering.h``
(``OnFrameRenderingSetup`` increments the sample index before it is used: frame ``k`` uses
index ``(k + 1) mod 8``).

Per pixel (y-down pixels):

- the nearest of the 4 diagonals at 2 px (strict comparisons in the order of the shader)
  replaces the centre when nearer than it; the velocity is that pixel's object velocity if
  it is a moving (``dynamic``) object's, else the camera reprojection of the *centre* at the
  chosen depth; velocity in the blend ramp is in units of 2 pixels (``BackN * ViewportSize``);
- current colour: the plus-shaped texels weighted by the Catmull-Rom weights times
  ``1 / (Y + 4)`` and renormalized; the outer pixel ring takes its own texel;
- history: 5-tap Catmull-Rom at the previous position clamped to the outer pixel centres,
  replaced by the current colour where no plus neighbour is dynamic but the history's alpha
  (last frame's dynamic flag) is positive, then clamped to the plus min/max in YCoCg;
- blend: ``0.04`` raised towards 0.2 by ``Velocity / 40``, plus ``0.8 saturate(0.02 L_h /
  |L_c - L_h|)``, times ``(L_min + 0.5) / (L_max + 0.5)``, at least ``saturate(0.01 L_h / |L_c
  - L_h|)`` (history luma taken before the clamp); off screen the history is the current
  colour; the two are weighed by ``1 / (Y + 4)``.
"""

from __future__ import annotations

import math

import numpy as np

from .hardware import catmull_rom_5tap, half_float
from .jitter import halton

__all__ = ["N_SAMPLES", "SIGMA", "closest_offset", "jitter", "plus_weights", "step"]

#: r.TemporalAASamples.
N_SAMPLES = 8
#: 0.47 * r.TemporalAAFilterSize (1).
SIGMA = 0.47
#: r.TemporalAACurrentFrameWeight.
CURRENT_FRAME_WEIGHT = 0.04
#: AA_CROSS.
CROSS = 2
#: The plus-shaped samples (PlusIndexes 1, 3, 4, 5, 7) as (dx, dy), y down.
PLUS = ((0, -1), (-1, 0), (0, 0), (1, 0), (0, 1))


def jitter(frame: int) -> np.ndarray:
    """``(SampleX, SampleY)``: the sample of pixel ``c`` lies at ``c - (SampleX, SampleY)``
    in y-down pixels; returned as that offset, ``-(SampleX, SampleY)``."""
    return -sample_xy(frame)


def sample_xy(frame: int) -> np.ndarray:
    """``View.TemporalJitterPixels`` of frame ``frame``."""
    index = (frame + 1) % N_SAMPLES
    u1, u2 = halton(index + 1, 2), halton(index + 1, 3)
    window = math.exp(-0.5 * (0.5 / SIGMA) ** 2)
    theta = 2.0 * math.pi * u2
    r = SIGMA * math.sqrt(-2.0 * math.log((1.0 - u1) * window + u1))
    return np.array([r * math.cos(theta), r * math.sin(theta)])


def _catmull_rom(x: float) -> float:
    ax = abs(x)
    if ax > 1.0:
        return ((-0.5 * ax + 2.5) * ax - 4.0) * ax + 2.0
    return (1.5 * ax - 2.5) * ax * ax + 1.0


def plus_weights(frame: int, version: str = "4.19") -> np.ndarray:
    """``PlusWeights`` (order of :data:`PLUS`): Catmull-Rom (4.19 and its fast pass,
    r.TemporalAACatmullRom 1) or the Gaussian ``exp(-2.29 d^2)`` (4.18 and 4.20,
    r.TemporalAACatmullRom 0)."""
    jx, jy = sample_xy(frame)
    if version in ("4.18", "4.20"):
        w = np.array([math.exp(-2.29 * ((dx - jx) ** 2 + (dy - jy) ** 2)) for dx, dy in PLUS])
    else:
        w = np.array([_catmull_rom(dx - jx) * _catmull_rom(dy - jy) for dx, dy in PLUS])
    return w / w.sum()


def to_ycocg(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return np.stack([r + 2.0 * g + b, 2.0 * r - 2.0 * b, -r + 2.0 * g - b], -1)


def to_rgb(c):
    y, co, cg = 0.25 * c[..., 0], 0.25 * c[..., 1], 0.25 * c[..., 2]
    return np.stack([y + co - cg, y + cg, y - co - cg], -1)


def _at(img, xi, yi):
    h, w = img.shape[:2]
    return img[np.clip(yi, 0, h - 1), np.clip(xi, 0, w - 1)]


def closest_offset(depth):
    """``(ox, oy, chosen)``: the velocity offset (texels) and the chosen view depth
    (``AA_CROSS`` with an inverted-Z buffer: larger device depth = smaller view depth)."""
    h, w = depth.shape
    yi, xi = np.mgrid[0:h, 0:w]
    dx_, dy_, dz_, dw_ = (
        _at(depth, xi + sx * CROSS, yi + sy * CROSS)
        for sx, sy in ((-1, -1), (1, -1), (-1, 1), (1, 1))
    )
    off_x = np.full((h, w), float(CROSS))
    off_y = np.full((h, w), float(CROSS))
    xx = np.where(dx_ < dy_, -float(CROSS), float(CROSS))  # Depths.x > Depths.y
    off_x = np.where(dz_ < dw_, -float(CROSS), off_x)
    xy, zw = np.minimum(dx_, dy_), np.minimum(dz_, dw_)
    upper = xy < zw
    off_y = np.where(upper, -float(CROSS), off_y)
    off_x = np.where(upper, xx, off_x)
    nearest = np.minimum(xy, zw)
    use = nearest < depth
    ox = np.where(use, off_x, 0.0).astype(int)
    oy = np.where(use, off_y, 0.0).astype(int)
    return ox, oy, np.where(use, nearest, depth)


def _sat_ratio(num, den):
    """``saturate(num / den)`` as a GPU evaluates it: x/0 is inf (1), 0/0 is NaN (0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        q = num / den
    return np.clip(np.nan_to_num(q, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)


def step(history, samples, frame: int, mv, depth, dynamic, camera_prev, version: str = "4.19"):
    """One frame of the main pass.

    ``history``: the previous output ``(H, W, 4)`` (RGB + the dynamic flag) or None on
    frame 0 (``AddTemporalAA``: "No history so use current as history", the scene colour;
    its alpha taken as 0); ``mv``: each sample's motion to
    the previous frame (pixels); ``depth``: view depth (inf sky); ``dynamic``: where a moving
    object is seen (it writes the velocity buffer); ``camera_prev(depth)``: the previous
    film position ``(x, y)`` of each pixel centre's ray point at view depth ``depth``.

    Returns ``(output (H, W, 4), blend, velocity (H, W, 2), discarded)``: the velocity used
    (pixels) and where the history was replaced by the current colour (off screen or by the
    dynamic anti-ghosting).
    """
    h, w = depth.shape
    src = half_float(samples)
    yi, xi = np.mgrid[0:h, 0:w]
    x, y = xi + 0.5, yi + 0.5
    camera_cut = history is None and version == "4.20"  # TAA_CAMERA_CUT without a history
    fast = version == "4.19-high"  # MainFastTemporalAA: no AA_TONE, no AA_DYNAMIC_ANTIGHOST
    if history is None:
        history = np.concatenate([src, np.zeros((h, w, 1))], -1)
    ox, oy, chosen = closest_offset(depth)
    cam_x, cam_y = camera_prev(chosen)
    dyn_n = _at(dynamic, xi + ox, yi + oy)
    mv_n = _at(mv, xi + ox, yi + oy)
    back_x = np.where(dyn_n, mv_n[..., 0], cam_x - x)
    back_y = np.where(dyn_n, mv_n[..., 1], cam_y - y)
    velocity = 2.0 * np.hypot(back_x, back_y)  # BackN * ViewportSize: 2 px units
    px, py = x + back_x, y + back_y
    off = (px <= 0.0) | (px >= w) | (py <= 0.0) | (py >= h)
    px, py = np.clip(px, 0.5, w - 0.5), np.clip(py, 0.5, h - 0.5)
    nb = [to_ycocg(_at(src, xi + dx, yi + dy)) for dx, dy in PLUS]
    weights = plus_weights(frame, version)
    if fast:  # AA_TONE 0: Filtered = sum(PlusWeights[i] * Neighbor), no division
        filtered = sum(wk * n for wk, n in zip(weights, nb, strict=True))
    else:
        sw = [wk / (n[..., 0] + 4.0) for wk, n in zip(weights, nb, strict=True)]
        filtered = sum(s[..., None] * n for s, n in zip(sw, nb, strict=True))
        filtered = filtered / sum(sw)[..., None]
    border = (xi == 0) | (xi == w - 1) | (yi == 0) | (yi == h - 1)
    filtered = np.where(border[..., None], nb[2], filtered)
    lo = np.minimum.reduce(nb)
    hi = np.maximum.reduce(nb)
    hist = catmull_rom_5tap(history, px, py)
    hist_c, hist_a = to_ycocg(hist[..., :3]), hist[..., 3]
    dyn_plus = np.logical_or.reduce([_at(dynamic, xi + dx, yi + dy) for dx, dy in PLUS])
    ghost = ~dyn_plus & (hist_a > 0) & (not fast)
    if version != "4.20":  # 4.18/4.19 replace the history before its luma and clamp
        hist_c = np.where(ghost[..., None], filtered, hist_c)
    l_min, l_max, l_hist = lo[..., 0], hi[..., 0], hist_c[..., 0]
    hist_c = np.clip(hist_c, lo, hi)
    l_cur = filtered[..., 0]
    diff = np.abs(l_cur - l_hist)
    blend = CURRENT_FRAME_WEIGHT + (0.2 - CURRENT_FRAME_WEIGHT) * np.clip(velocity / 40.0, 0, 1)
    if version in ("4.19", "4.19-high"):  # under #if 0 in 4.18.3 and 4.20.3
        blend = blend + 0.8 * _sat_ratio(0.02 * l_hist, diff)
        blend = blend * (l_min + 0.5) / (l_max + 0.5)
    blend = np.maximum(blend, _sat_ratio(0.01 * l_hist, diff))
    ignore = off | (ghost if version == "4.20" else False) | camera_cut
    if camera_cut:
        blend = np.ones_like(blend)
    hist_c = np.where(ignore[..., None], filtered, hist_c)
    wa = (1.0 - blend) / (hist_c[..., 0] + 4.0)
    wb = blend / (filtered[..., 0] + 4.0)
    rcp = 1.0 / (wa + wb)
    out = hist_c * (wa * rcp)[..., None] + filtered * (wb * rcp)[..., None]
    rgb = np.maximum(np.nan_to_num(to_rgb(out), nan=0.0), 0.0)
    alpha = np.zeros_like(depth) if fast else dynamic.astype(np.float64)
    out = half_float(np.concatenate([rgb, alpha[..., None]], -1))
    return out, blend, np.stack([back_x, back_y], -1), ignore | ghost
