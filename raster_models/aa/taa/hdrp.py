"""Unity HDRP's TAA with the camera's shipped defaults (``preset=hdrp``: ``TAAQuality``
Medium, the default; ``preset=hdrp-high``: High).

Pinned sources (github.com/Unity-Technologies/Graphics, package
``com.unity.render-pipelines.high-definition``; the newest stored copies: only the shader's
commit is known to the source index, the other files are the stored copies that match it -- the
``.hlsl`` whose ``GetBlendFactor`` takes the shader's ``_BaseBlendFactor`` and which has
``ModifyBlendWithMotionVectorRejection`` and ``GetUpsampleConfidence``, the C# that sets
``_TaaPostParameters``/``_TaaPostParameters1`` as the shader reads them):
``Runtime/PostProcessing/Shaders/TemporalAntiAliasing.shader`` at 003084f5d112 (tier defines:
Medium = YCoCg, 5-tap bicubic history, plus-shaped 4 neighbours, variance box, no central
filter, direct clip, anti-flicker, perceptual space; High adds the 8 neighbours, the
Blackman-Harris central filter with its quad swizzle and the motion-dependent anti-flicker;
``FragTAA``), ``TemporalAntialiasing.hlsl`` (the stored copy whose ``GetBlendFactor`` takes
``baseBlendFactor``: ``HistoryBicubic5Tap``, ``VarianceNeighbourhood``, ``DirectClipToAABB``,
``SharpenColor``, ``HistoryContrast``, ``Fetch4`` with
``ClampAndScaleForBilinearWithCustomScale``), ``HDAdditionalCameraData.cs``
(``taaSharpenStrength`` 0.5, ``TAAQuality`` Medium, ``taaHistorySharpening`` 0.35,
``taaAntiFlicker`` 0.5, ``taaMotionVectorRejection`` 0, ``taaAntiHistoryRinging`` false,
``taaBaseBlendFactor`` 0.875, ``taaJitterScale`` 1), ``HDRenderPipeline.PostProcess.cs``
``PrepareTAAPassData`` (anti-flicker ``lerp(0, 3.5, 0.5)``, contrast for the maximum
anti-flicker ``0.7 - lerp(0, 0.3, Mathf.SmoothStep(0.5, 1, 0.5))`` = 0.475 (Unity's
``Mathf.SmoothStep(from, to, t)`` interpolates *between* from and to), base blend ``1 -
0.875``), ``HDCamera.cs``
(``GetJitteredProjectionMatrix``: Halton ``(i + 1)`` in bases 2, 3 minus 0.5 with ``i =
taaFrameIndex``, which ``Update`` increments (modulo 8) before ``UpdateAllViewConstants``
builds the jittered projection, so frame ``k`` uses ``i = (k + 1) mod 8``; the frustum moves by
the offset, so the sample of pixel ``c`` lies at ``c + (x, -y)`` in y-down pixels),
``Color.hlsl`` (``RGBToYCoCg`` adds ``YCOCG_CHROMA_BIAS`` 128/255 to Co and Cg: the perceptual
weights scale the biased chroma, as shipped), ``RenderPipelineSettings`` (``colorBufferFormat``
R11G11B10: the input and history buffers).

High's central filter (``preset=hdrp-high``) follows the released C# the shader was shipped
with, not the newer stored ``ComputeWeights``: needle-mirror/com.unity.render-pipelines.high-
definition tag ``12.1.0/Unity-2021.2.0b16`` (commit 3178738b1464591a32ed19b931125863779f3ae9)
``Runtime/RenderPipeline/HDRenderPipeline.PostProcess.cs`` :1534-1545 (``TAASampleOffsets``:
the centre, ``(0, 1), (1, 0), (-1, 0), (0, -1)``, then the diagonals ``(-1, 1), (1, -1),
(1, 1), (-1, -1)``), :1576-1589 (weights ``exp(-0.5 / 0.22 |o - taaJitter|^2)``, normalized
over the nine), :1598-1600 (the centre's into ``_TaaPostParameters1.y``, then
``_TaaFilterWeights`` and ``_TaaFilterWeights1`` in that order); the same lines at tag
``13.0.0/Unity-2022.1.0a12`` (a645acddce977beddce5abef20e64f95d35c7c7b) :1526-1537,
:1570-1571, :1591-1592. That order is the one ``SwizzleFilterWeights``
(``TemporalAntiAliasing.shader`` :187-199 at both tags: "filterParams2 for { (-1, 1), (1, -1),
(1, 1), (-1, -1) }") and ``GatherNeighbourhood`` (``TemporalAntialiasing.hlsl`` :482-496:
neighbours 4-7 at ``(-q.x, q.y), (q.x, -q.y), q, -q``) expect.

Per pixel (y-down pixels, ``q`` = the quad offset ``(x & 1) * 2 - 1`` per axis, pointing away
from the pixel's 2x2-quad partner):

- every ``Fetch`` clamps its coordinate to ``size - 1`` before a bilinear fetch (the last row
  and column read half the next-to-last texel) -- the border ring rule, with ``offScreen``:
  a history position at or beyond the outer pixel centres takes the current colour;
- the velocity of the nearest of the centre and its 4 diagonals (reversed-Z ``step``: the
  last of equal depths wins), read point-sampled;
- history: bicubic (sharpening 0.35) from 5 bilinear fetches, its fourth at
  ``(tc3.x, tc0.y)`` as shipped, clamped to ``[0, 65472]``, weighted by ``1 / (1 + Y)``;
- neighbours: the plus (``n0 = (0, q.y)``, ``n1 = (q.x, 0)`` fetched, ``n2``, ``n3`` the quad
  partners' central colours; High adds the 4 diagonals), all weighted by ``1 / (1 + Y)``;
- box: mean of the neighbours and the centre ``+- stdDev (1.5 + antiFlicker
  smoothstep(0.05, 0.475, temporal contrast))``, then the direct clip towards its centre;
- sharpening (0.5): ``c + max(0, c - avg) * 1.5`` in linear RGB;
- blend ``max(saturate(0.125 / (1 + (Y_max - Y_min) / Y_history)), 0.03)``, the lerp undone by
  ``1 / (1 - Y)``, back to RGB, clamped to ``[0, 65472]``.
"""

from __future__ import annotations

import numpy as np

from .filters import bilinear
from .hardware import r11g11b10
from .jitter import halton

__all__ = ["QUALITIES", "jitter", "step"]

QUALITIES = ("medium", "high")
#: ``kMaxSampleCount`` (HDCamera.cs).
N_SAMPLES = 8
CLAMP_MAX = 65472.0
CHROMA_BIAS = 128.0 / 255.0
HISTORY_SHARPENING = 0.35
SHARPEN_STRENGTH = 0.5
BASE_BLEND = 1.0 - 0.875
ANTI_FLICKER = 0.0 + (3.5 - 0.0) * 0.5
#: ``0.7 - lerp(0, 0.3, Mathf.SmoothStep(0.5, 1.0, 0.5))``.
CONTRAST_FOR_MAX_ANTI_FLICKER = 0.7 - 0.3 * (1.0 * 0.5 + 0.5 * 0.5)
#: ``TAASampleOffsets`` 1..8 (HDRP 12.1.0 HDRenderPipeline.PostProcess.cs:1534-1545, 13.0.0
#: :1526-1537), in the order the weights arrive: ``_TaaFilterWeights`` then
#: ``_TaaFilterWeights1`` (the diagonals as ``SwizzleFilterWeights`` expects them).
SAMPLE_OFFSETS = ((0, 1), (1, 0), (-1, 0), (0, -1), (-1, 1), (1, -1), (1, 1), (-1, -1))


def jitter(frame: int) -> np.ndarray:
    """The sample's offset from the pixel centre (y-down pixels)."""
    j = jitter_unity(frame)
    return np.array([j[0], -j[1]])


def jitter_unity(frame: int) -> np.ndarray:
    """``taaJitter.xy`` (Unity's y-up pixels)."""
    i = (frame + 1) % N_SAMPLES + 1  # taaFrameIndex is incremented in Update before use
    return np.array([halton(i, 2) - 0.5, halton(i, 3) - 0.5])


def to_ycocg(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return np.stack(
        [
            0.25 * r + 0.5 * g + 0.25 * b,
            0.5 * r - 0.5 * b + CHROMA_BIAS,
            -0.25 * r + 0.5 * g - 0.25 * b + CHROMA_BIAS,
        ],
        -1,
    )


def to_rgb(ycocg):
    y, co, cg = ycocg[..., 0], ycocg[..., 1] - CHROMA_BIAS, ycocg[..., 2] - CHROMA_BIAS
    return np.stack([y + co - cg, y + cg, y - co - cg], -1)


def _weight(c):
    return 1.0 / (c[..., :1] + 1.0)


def _inv_weight(c):
    return 1.0 / (1.0 - c[..., :1])


def _fetch(img, x, y):
    h, w = img.shape[:2]
    return bilinear(img, np.minimum(x, w - 1.0), np.minimum(y, h - 1.0))


def _bicubic(img, x, y, c):
    tc1x, tc1y = np.floor(x - 0.5) + 0.5, np.floor(y - 0.5) + 0.5
    ws = []
    for s, tc1 in ((x, tc1x), (y, tc1y)):
        f = s - tc1
        f2, f3 = f * f, f * f * f
        w0 = -c * f3 + 2.0 * c * f2 - c * f
        w1 = (2.0 - c) * f3 - (3.0 - c) * f2 + 1.0
        w2 = -(2.0 - c) * f3 + (3.0 - 2.0 * c) * f2 + c * f
        w3 = c * f3 - c * f2
        w12 = w1 + w2
        ws.append((w0, w12, w3, tc1 - 1.0, tc1 + w2 / w12, tc1 + 2.0))
    (w0x, w12x, w3x, t0x, t12x, t3x), (w0y, w12y, w3y, t0y, t12y, t3y) = ws
    taps = (
        (w12x * w0y, t12x, t0y),
        (w0x * w12y, t0x, t12y),
        (w12x * w12y, t12x, t12y),
        (w3x * w12y, t3x, t0y),  # as shipped: (tc3.x, tc0.y)
        (w12x * w3y, t12x, t3y),
    )
    total = sum(k for k, _, _ in taps)
    return sum(k[..., None] * _fetch(img, tx, ty) for k, tx, ty in taps) / total[..., None]


def _closest_offset(depth, qx, qy):
    h, w = depth.shape
    yi, xi = np.mgrid[0:h, 0:w]
    best = depth.copy()
    ox, oy = np.zeros((h, w), int), np.zeros((h, w), int)
    for cx, cy in ((-qx, -qy), (qx, qy), (qx, -qy), (-qx, qy)):
        px, py = xi + cx, yi + cy
        inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
        d = np.where(inside, depth[np.clip(py, 0, h - 1), np.clip(px, 0, w - 1)], np.inf)
        nearer = d <= best  # COMPARE_DEPTH(s, closest) with reversed Z: step(closest, s)
        best = np.where(nearer, d, best)
        ox, oy = np.where(nearer, cx, ox), np.where(nearer, cy, oy)
    return ox, oy


def _smoothstep(a, b, x):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _filter_weights(frame):
    """The centre's and the 8 neighbours' weights: ``exp(-0.5 / 0.22 |o - taaJitter|^2)``
    normalized (HDRP 12.1.0 HDRenderPipeline.PostProcess.cs:1576-1589)."""
    jx, jy = jitter_unity(frame)
    raw = [np.exp((-0.5 / 0.22) * (jx * jx + jy * jy))]
    raw += [np.exp((-0.5 / 0.22) * ((ox - jx) ** 2 + (oy - jy) ** 2)) for ox, oy in SAMPLE_OFFSETS]
    total = sum(raw)
    return raw[0] / total, np.array(raw[1:]) / total


def _swizzled(weights, sx, sy):
    """``SwizzleFilterWeights``: per pixel, the 8 weights in neighbour order."""
    p1 = [weights[i] * np.ones(sx.shape) for i in range(4)]
    p1[1], p1[2] = np.where(sx, p1[2], p1[1]), np.where(sx, p1[1], p1[2])
    p1[0], p1[3] = np.where(sy, p1[3], p1[0]), np.where(sy, p1[0], p1[3])
    a, b, c, d = (weights[4 + i] * np.ones(sx.shape) for i in range(4))
    both, only_x, only_y = sx & sy, sx & ~sy, ~sx & sy
    p2 = [
        np.where(both, b, np.where(only_x, c, np.where(only_y, d, a))),
        np.where(both, a, np.where(only_x, d, np.where(only_y, c, b))),
        np.where(both, d, np.where(only_x, a, np.where(only_y, b, c))),
        np.where(both, c, np.where(only_x, b, np.where(only_y, a, d))),
    ]
    return p1 + p2


def step(history, samples, frame: int, mv, depth, quality: str = "medium"):
    """One frame of the resolve; ``history`` None on frame 0 (the history is reset to the
    input, ``Copy History``). ``mv``: each sample's motion to the previous frame (pixels);
    ``depth``: view depth (inf sky). Returns ``(output, blend_factor, velocity, discarded)``
    (the velocity read: the nearest diagonal's; ``discarded``: where the history was replaced
    by the current colour, ``offScreen``)."""
    h, w = depth.shape
    wide = quality == "high"
    src = r11g11b10(samples)
    prev = src if history is None else history
    yi, xi = np.mgrid[0:h, 0:w]
    x, y = xi + 0.5, yi + 0.5
    qx, qy = (xi & 1) * 2 - 1, (yi & 1) * 2 - 1
    ox, oy = _closest_offset(depth, qx, qy)
    mvc = mv[np.clip(yi + oy, 0, h - 1), np.clip(xi + ox, 0, w - 1)]
    px, py = x + mvc[..., 0], y + mvc[..., 1]
    hist = to_ycocg(np.clip(_bicubic(prev, px, py, HISTORY_SHARPENING), 0.0, CLAMP_MAX))
    off = (np.abs(2.0 * px / w - 1.0) >= 1.0 - 1.0 / w) | (
        np.abs(2.0 * py / h - 1.0) >= 1.0 - 1.0 / h
    )
    hist = hist * _weight(hist)

    def color_at(cx, cy):  # a pixel's clamped central colour in working space
        return to_ycocg(np.clip(_fetch(src, cx, cy), 0.0, CLAMP_MAX))

    central = color_at(x, y)
    nbs = [
        to_ycocg(_fetch(src, x, y + qy)),
        to_ycocg(_fetch(src, x + qx, y)),
        color_at(x - qx, y),  # QuadReadAcrossX(centralColor)
        color_at(x, y - qy),  # QuadReadAcrossY(centralColor)
    ]
    if wide:
        for cx, cy in ((-qx, qy), (qx, -qy), (qx, qy), (-qx, -qy)):
            nbs.append(to_ycocg(_fetch(src, x + cx, y + cy)))
    nbs = [n * _weight(n) for n in nbs]
    central = central * _weight(central)
    if wide:
        cw, weights = _filter_weights(frame)
        ws = _swizzled(weights, (xi & 1) == 0, (yi & 1) == 0)
        filtered = central * cw + sum(wk[..., None] * n for wk, n in zip(ws, nbs, strict=True))
    else:
        filtered = central
    hist = np.where(off[..., None], filtered, hist)
    c_luma, h_luma = filtered[..., 0], hist[..., 0]
    # VarianceNeighbourhood
    m1 = sum(nbs)
    m2 = sum(n * n for n in nbs)
    avg = m1 / len(nbs)
    m1 = (m1 + central) / (len(nbs) + 1)
    m2 = (m2 + central * central) / (len(nbs) + 1)
    std = np.sqrt(np.abs(m2 - m1 * m1))
    contrast = np.clip(np.abs(c_luma - h_luma) / np.maximum(0.2, np.maximum(c_luma, h_luma)), 0, 1)
    flicker = ANTI_FLICKER
    if wide:
        mv_len = np.hypot(mvc[..., 0] / w, mvc[..., 1] / h) * np.hypot(w, h)
        flicker = ANTI_FLICKER * 0.8 + (ANTI_FLICKER * 2.25 - ANTI_FLICKER * 0.8) * np.clip(
            1.0 - 2.0 * mv_len, 0.0, 1.0
        )
    mult = 1.5 + flicker * _smoothstep(0.05, CONTRAST_FOR_MAX_ANTI_FLICKER, contrast)
    lo, hi = m1 - std * mult[..., None], m1 + std * mult[..., None]
    hist = _direct_clip(hist, lo, hi)
    filtered = _sharpen(filtered, avg)
    with np.errstate(divide="ignore", invalid="ignore"):
        blend = BASE_BLEND / (1.0 + np.maximum(hi[..., 0] - lo[..., 0], 0.0) / h_luma)
    blend = np.maximum(np.clip(np.nan_to_num(blend, nan=0.0), 0.0, 1.0), 0.03)
    final = hist + blend[..., None] * (filtered - hist)
    final = final * _inv_weight(final)
    out = np.clip(to_rgb(final), 0.0, CLAMP_MAX)
    return r11g11b10(out), blend, mvc, off


def _direct_clip(hist, lo, hi):
    centre, extent = 0.5 * (hi + lo), 0.5 * (hi - lo)
    offset = hist - centre
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.abs(offset / extent)
    m = np.fmax(np.fmax(unit[..., 0], unit[..., 1]), unit[..., 2])[..., None]
    with np.errstate(invalid="ignore"):
        clipped = centre + offset / m
    return np.where(m > 1.0, clipped, hist)


def _sharpen(color, avg):
    lin_c = to_rgb(color * _inv_weight(color))
    lin_a = to_rgb(avg * _inv_weight(avg))
    lin_c = np.clip(lin_c + np.maximum(0.0, lin_c - lin_a) * SHARPEN_STRENGTH * 3.0, 0.0, CLAMP_MAX)
    out = to_ycocg(lin_c)
    return out * _weight(out)
