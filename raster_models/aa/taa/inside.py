"""Playdead INSIDE's TAA as its repository ships it (``preset=inside``).

Pinned source: github.com/playdeadgames/temporal, commit 4795aa0007d4 (2017-03-31), MIT.
``TemporalReprojection.cs`` defaults (lines 34-45): ``MinMax3x3Rounded``,
``unjitterColorSamples`` on, ``unjitterNeighborhood``/``unjitterReprojection``/``useYCoCg``
off, ``useClipping``/``useDilation``/``useOptimizations`` on, ``feedbackMin`` 0.88,
``feedbackMax`` 0.97. ``TemporalReprojection.shader`` with those keywords, per pixel ``c``:

- current colour (line 216): one bilinear fetch of the jittered frame at ``c - j``
  (``_JitterUV``: the frame's jitter, ``FrustumJitter.activeSample``);
- neighbourhood (lines 229-258): min/max of the 3x3 texels at ``c`` averaged with those of
  the plus-shaped 5 ("rounded");
- history (line 220): one bilinear fetch of the previous output at ``c - v`` with ``v`` the
  velocity of the 3x3 neighbour of nearest depth (``IncDepth.cginc``
  ``find_closest_fragment_3x3`` lines 37-68: first strict minimum, rows in Unity's y-up
  order), ``TextureWrapMode.Clamp`` (``EffectBase.cs`` line 75);
- clip (lines 122-137, ``USE_OPTIMIZATIONS``): towards the box centre, half extent
  ``+ FLT_EPS`` (1e-8, line 37);
- feedback (lines 305-319): ``d = |L0 - L1| / max(L0, L1, 0.2)`` with Unity's
  ``Luminance`` in a linear-space project (``UnityCG.cginc`` ``unity_ColorSpaceLuminance``
  (0.0396819152, 0.458021790, 0.00609653955)), ``k = lerp(0.88, 0.97, (1 - d)^2)``,
  ``out = lerp(current, history, k)``;
- output (lines 392-394): ``saturate``; the history target is ``RenderTextureFormat.ARGB32``
  with ``RenderTextureReadWrite.Default`` (``TemporalReprojection.cs`` lines 90-92,
  ``EffectBase.cs`` line 73): 8-bit sRGB in a linear-space project, so radiance above 1 is
  clipped and every frame's history is rounded to 255 sRGB steps;
- frame 0 (``TemporalReprojection.cs`` lines 122-127): the history is the current frame
  blitted into that 8-bit target, and ``FrustumJitter`` (lines 301-307) renders it
  unjittered; frame ``k >= 1`` uses ``Halton_2_3_X16`` point ``(k - 1) mod 16``:
  ``(h2(i + 1) - 0.5, h3(i + 1) - 0.5)`` in Unity's y-up pixels (``FrustumJitter.cs`` lines
  128-137, 310-319; the projection's frustum moves by the offset, ``Extensions.cs`` lines
  107-120, so the sample of pixel ``c`` lies at ``c + (x, -y)`` in y-down pixels).

Not reproduced (docs/models.md gives their effect): the ``PDsrand4 / 510`` dither added
before the 8-bit write (line 392: driven by ``_SinTime``, at most half an 8-bit step), the
motion blur ``useMotionBlur`` mixes into the displayed image where the velocity exceeds 2
px a frame (lines 363-382: not anti-aliasing, and it draws ``_SinTime`` noise too), the
RGHalf rounding of the velocity buffer.
"""

from __future__ import annotations

import numpy as np

from .filters import bilinear, neighbours
from .hardware import half_float, srgb8_store
from .jitter import halton

__all__ = ["FEEDBACK", "LUMINANCE", "N_SAMPLES", "closest_velocity", "jitter", "step"]

#: ``feedbackMin``, ``feedbackMax`` (TemporalReprojection.cs lines 44-45).
FEEDBACK = (0.88, 0.97)
#: Unity's linear-space ``unity_ColorSpaceLuminance`` (UnityCG.cginc).
LUMINANCE = np.array([0.0396819152, 0.458021790, 0.00609653955])
#: ``FrustumJitter.pattern`` Halton_2_3_X16 (FrustumJitter.cs line 243).
N_SAMPLES = 16
#: ``FLT_EPS`` of the non-mobile path (TemporalReprojection.shader line 37).
FLT_EPS = 1e-8
#: 3x3 neighbours in find_closest_fragment_3x3's order (IncDepth.cginc lines 43-53): Unity's
#: ``uv - dv`` row is the row below in y-down pixels.
CLOSEST_ORDER = np.array([(dx, dy) for dy in (1, 0, -1) for dx in (-1, 0, 1)])


def jitter(frame: int) -> np.ndarray:
    """The sample's offset from the pixel centre (y-down pixels) in frame ``frame``."""
    if frame <= 0:
        return np.zeros(2)
    i = (frame - 1) % N_SAMPLES + 1
    return np.array([halton(i, 2) - 0.5, -(halton(i, 3) - 0.5)])


def closest_velocity(mv: np.ndarray, depth: np.ndarray) -> np.ndarray:
    h, w = depth.shape
    pad_d = np.pad(depth, 1, mode="edge")
    pad_v = np.pad(mv, ((1, 1), (1, 1), (0, 0)), mode="edge")
    best_d = None
    best_v = None
    for dx, dy in CLOSEST_ORDER:
        d = pad_d[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        v = pad_v[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        if best_d is None:
            best_d, best_v = d, v
            continue
        nearer = best_d > d
        best_d = np.where(nearer, d, best_d)
        best_v = np.where(nearer[..., None], v, best_v)
    return best_v


def _clip_towards_centre(lo, hi, q):
    p = 0.5 * (hi + lo)
    e = 0.5 * (hi - lo) + FLT_EPS
    v = q - p
    m = np.max(np.abs(v / e), axis=-1, keepdims=True)
    return np.where(m > 1.0, p + v / np.where(m > 1.0, m, 1.0), q)


def step(history, samples, jit, mv, depth):
    """One frame of the resolve.

    ``history``: the previous frame's 8-bit history as read back (linear, ``(H, W, 3)``), or
    None on frame 0; ``samples``: the jittered frame (linear radiance); ``jit``: this frame's
    jitter (y-down pixels); ``mv``: each sample's motion to the previous frame (pixels,
    ``(H, W, 2)``); ``depth``: view depth (inf where the sky is seen).

    Returns ``(output, new_history, feedback)``: the displayed colour, the stored 8-bit
    history (decoded) and the history's weight ``k`` per pixel.
    """
    h, w = depth.shape
    src = half_float(samples)  # the HDR camera target (ARGBHalf)
    if history is None:
        history = srgb8_store(src)  # Graphics.Blit(source, history) on the first frame
        mv = np.zeros_like(mv)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    texel0 = bilinear(src, x - jit[0], y - jit[1])
    vel = closest_velocity(mv, depth)
    texel1 = bilinear(history, x + vel[..., 0], y + vel[..., 1])
    nb = neighbours(src)
    plus = nb[[1, 3, 4, 5, 7]]
    lo = 0.5 * (nb.min(axis=0) + plus.min(axis=0))
    hi = 0.5 * (nb.max(axis=0) + plus.max(axis=0))
    texel1 = _clip_towards_centre(lo, hi, texel1)
    lum0, lum1 = texel0 @ LUMINANCE, texel1 @ LUMINANCE
    diff = np.abs(lum0 - lum1) / np.maximum(lum0, np.maximum(lum1, 0.2))
    k = FEEDBACK[0] + (FEEDBACK[1] - FEEDBACK[0]) * (1.0 - diff) ** 2
    out = texel0 + k[..., None] * (texel1 - texel0)
    return np.clip(out, 0.0, 1.0), srgb8_store(out), k
