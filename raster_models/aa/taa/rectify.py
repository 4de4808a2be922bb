"""Neighbourhood rectification of the history: clamp, AABB clip or variance clip against the
current frame's 3x3 (or plus-shaped, or their average: "rounded") neighbourhood, in RGB or
YCoCg.

- ``clamp``: each channel of the history clamped to the neighbourhood's [min, max] (UE4 2014).
- ``clip``: the history moved along the line to the box's centre until it lies in the box
  (INSIDE's ``clip_aabb``, the fast form that clips towards the centre of the AABB).
- ``variance``: the box ``mu +- gamma sigma`` of the neighbourhood's mean and standard
  deviation, then clipped as ``clip`` (Salvi 2016; ``gamma`` 1 by default).

References
----------
B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014 (YCoCg, rounded min/max box).
L. J. F. Pedersen, Temporal Reprojection Anti-Aliasing in INSIDE, GDC 2016.
M. Salvi, An Excursion in Temporal Supersampling, GDC 2016 (variance clipping).
"""

from __future__ import annotations

import numpy as np

from .filters import PLUS, neighbours

__all__ = [
    "COLOR_SPACES",
    "NEIGHBOURHOODS",
    "RECTIFIERS",
    "clip_aabb",
    "from_ycocg",
    "neighbourhood_box",
    "rectify",
    "to_ycocg",
]

RECTIFIERS = ("none", "clamp", "clip", "variance")
COLOR_SPACES = ("rgb", "ycocg")
NEIGHBOURHOODS = ("3x3", "plus", "rounded")
#: Smallest half extent of a box a point is clipped to (avoids 0/0 on flat neighbourhoods).
CLIP_EPS = 1e-6


def to_ycocg(rgb: np.ndarray) -> np.ndarray:
    """YCoCg of linear RGB ``(..., 3)``: Y = R/4 + G/2 + B/4, Co = (R - B)/2,
    Cg = -R/4 + G/2 - B/4."""
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return np.stack(
        [0.25 * r + 0.5 * g + 0.25 * b, 0.5 * r - 0.5 * b, -0.25 * r + 0.5 * g - 0.25 * b], -1
    )


def from_ycocg(ycocg: np.ndarray) -> np.ndarray:
    """Linear RGB of YCoCg (the inverse of :func:`to_ycocg`)."""
    y, co, cg = ycocg[..., 0], ycocg[..., 1], ycocg[..., 2]
    return np.stack([y + co - cg, y + cg, y - co - cg], -1)


def clip_aabb(color: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``color`` moved towards the centre of the box ``[lo, hi]`` until inside it (unchanged
    when inside): ``c + v / max(|v / e|)`` with ``c`` the centre, ``e`` the half extent and
    ``v = color - c`` (``(..., C)`` arrays)."""
    centre = 0.5 * (hi + lo)
    extent = np.maximum(0.5 * (hi - lo), CLIP_EPS)
    v = color - centre
    m = np.max(np.abs(v) / extent, axis=-1, keepdims=True)
    return np.where(m > 1.0, centre + v / np.maximum(m, 1.0), color)


def neighbourhood_box(samples: np.ndarray, *, shape: str, rectifier: str, gamma: float):
    """``(lo, hi)`` of the current frame's neighbourhood (``samples`` ``(H, W, C)`` in the
    rectification's colour space): min/max, or ``mu -+ gamma sigma`` for ``variance``; the
    ``rounded`` shape averages the 3x3 and plus boxes."""
    nb = neighbours(samples)
    sets = {"3x3": [nb], "plus": [nb[PLUS]], "rounded": [nb, nb[PLUS]]}[shape]
    los, his = [], []
    for s in sets:
        if rectifier == "variance":
            mu, sigma = s.mean(axis=0), s.std(axis=0)
            los.append(mu - gamma * sigma)
            his.append(mu + gamma * sigma)
        else:
            los.append(s.min(axis=0))
            his.append(s.max(axis=0))
    return sum(los) / len(los), sum(his) / len(his)


def rectify(history, samples, *, rectifier: str, space: str, shape: str, gamma: float):
    """The history (``(H, W, 3)`` linear RGB) rectified against the current frame's jittered
    samples; returns linear RGB."""
    if rectifier == "none":
        return history
    conv = to_ycocg if space == "ycocg" else (lambda a: a)
    h, s = conv(history), conv(samples)
    lo, hi = neighbourhood_box(s, shape=shape, rectifier=rectifier, gamma=gamma)
    out = np.clip(h, lo, hi) if rectifier == "clamp" else clip_aabb(h, lo, hi)
    return from_ycocg(out) if space == "ycocg" else out
