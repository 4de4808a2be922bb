"""The history blend: the weight ``alpha`` of the current frame in
``out = history + alpha (current - history)``.

- ``constant``: ``alpha`` itself (HDRP: 1 - taaBaseBlendFactor 0.875 = 0.125; Filament
  ``feedback`` 0.12).
- ``ue4``: UE4's ``BlendFinal`` (PostProcessTemporalCommon.usf): ``lerp(alpha, 0.2,
  saturate(|v| / 40))`` for a velocity ``v`` in pixels, raised to at least
  ``saturate(0.01 L_h / |L_c - L_h|)`` (the luma-contrast term: a history close to the
  current frame in relative luma takes more of it, damping flicker), ``L = Luma4 = R + 2G +
  B``; the two colours are then weighed by ``1 / (L + 4)`` (``WeightedLerpFactors`` with
  ``HdrWeight4``, exposure 1), so bright samples do not dominate.
- ``inside``: Playdead's feedback ``k = lerp(k_min, k_max, (1 - d)^2)``,
  ``d = |L_c - L_h| / max(L_c, L_h, 0.2)`` with Unity's linear ``Luminance`` (0.2125, 0.7154,
  0.0721) and ``k_min, k_max = 0.88, 0.97``; ``alpha = 1 - k``.

References
----------
B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014.
L. J. F. Pedersen, Temporal Reprojection Anti-Aliasing in INSIDE, GDC 2016
(Playdead/TemporalReprojectionAntialiasing, MIT).
"""

from __future__ import annotations

import numpy as np

__all__ = ["BLENDS", "INSIDE_FEEDBACK", "blend", "luma4", "unity_luminance"]

BLENDS = ("constant", "ue4", "inside")
#: INSIDE's feedback range (TemporalReprojection.cs feedbackMin, feedbackMax).
INSIDE_FEEDBACK = (0.88, 0.97)
_UNITY_LUMA = np.array([0.2125, 0.7154, 0.0721])


def luma4(rgb: np.ndarray) -> np.ndarray:
    """UE4's ``Luma4``: ``R + 2 G + B`` (four times the YCoCg Y)."""
    return rgb[..., 0] + 2.0 * rgb[..., 1] + rgb[..., 2]


def unity_luminance(rgb: np.ndarray) -> np.ndarray:
    """Unity's linear-space ``Luminance``."""
    return rgb @ _UNITY_LUMA


def blend(history, current, *, kind: str, alpha, speed_px=0.0, feedback=INSIDE_FEEDBACK):
    """``(out, weight)``: the blended colour (``(H, W, 3)``) and the current frame's effective
    weight per pixel. ``alpha`` is the base current-frame weight (scalar or ``(H, W)``; 1
    where the history was rejected), ``speed_px`` the pixel's velocity length (``ue4``)."""
    alpha = np.broadcast_to(np.asarray(alpha, dtype=np.float64), current.shape[:2])
    if kind == "constant":
        w = alpha
    elif kind == "inside":
        lc, lh = unity_luminance(current), unity_luminance(history)
        d = np.abs(lc - lh) / np.maximum(np.maximum(lc, lh), 0.2)
        k = feedback[0] + (feedback[1] - feedback[0]) * (1.0 - d) ** 2
        w = np.where(alpha >= 1.0, 1.0, 1.0 - k)
    else:
        lc, lh = luma4(current), luma4(history)
        b = alpha + (0.2 - alpha) * np.clip(np.asarray(speed_px) / 40.0, 0.0, 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            contrast = np.clip(0.01 * lh / np.abs(lc - lh), 0.0, 1.0)
        b = np.maximum(b, np.nan_to_num(contrast, nan=1.0, posinf=1.0))
        b = np.where(alpha >= 1.0, 1.0, b)
        wh, wc = (1.0 - b) / (lh + 4.0), b / (lc + 4.0)
        w = wc / (wh + wc)
    w = np.asarray(w, dtype=np.float64)
    return history + w[..., None] * (current - history), w
