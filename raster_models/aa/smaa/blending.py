"""SMAA's third pass and its temporal resolve (``SMAANeighborhoodBlendingPS`` and
``SMAAResolvePS`` of ``SMAA.hlsl``).

Neighbourhood blending reads four weights around the pixel (its own B and R, the right
neighbour's A, the lower neighbour's G), keeps the stronger direction, and mixes the pixel
with its neighbours by two bilinear fetches offset by those weights. The colour read is an
sRGB read by default (``srgb=True``, the header's step 5: texels decoded to linear before the
filter, the result encoded on write), so the mix happens in linear light; pixels with no
weight are passed through unchanged (an 8-bit sRGB read and write round-trips exactly).

The resolve blends the current frame with the previous one fetched at the reprojected
position, the previous weighted down where the velocities (packed into alpha by the blending
pass as ``sqrt(5 |v|)``) differ: ``weight = 0.5 * saturate(1 - sqrt(|a_c^2 - a_p^2| / 5) * 30)``.
"""

from __future__ import annotations

import numpy as np

from ....scenes.base.display import srgb_decode, srgb_encode
from ._sampling import SUBTEXEL_BITS, Fetches, bilinear, bilinear_taps

__all__ = ["REPROJECTION_WEIGHT_SCALE", "neighborhood_blend", "resolve", "to_unorm8"]

#: ``SMAA_REPROJECTION_WEIGHT_SCALE`` (SMAA.hlsl default).
REPROJECTION_WEIGHT_SCALE = 30.0
# SMAANeighborhoodBlendingPS: weights summing below this leave the pixel alone
_NO_BLEND = 1e-5


def to_unorm8(x) -> np.ndarray:
    """A float written to an 8-bit UNORM channel: clamped to [0, 1], rounded to k/255."""
    v = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return (np.round(v * 255.0) / 255.0).astype(np.float32)


def neighborhood_blend(
    color: np.ndarray,
    weights: np.ndarray,
    *,
    srgb: bool = True,
    extra: dict | None = None,
    match: dict | None = None,
    velocity: np.ndarray | None = None,
    subtexel_bits: int = SUBTEXEL_BITS,
    unorm8: bool = False,
    fetches: Fetches | None = None,
) -> dict:
    """Blend ``color`` ((H, W, 3) gamma-encoded display values) with the blend texture
    ``weights`` ((H, W, 4), :func:`.weights.blending_weights`).

    ``extra``: name -> (H, W) or (H, W, C) linear arrays blended with the same fetches (the
    coverage mask); ``match``: name -> ((H, W) ids of the image, (H, W) ids to match): the
    filter weight the blend gives to texels whose id equals the pixel's id to match (the
    front-most shape's coverage); ``velocity``: (H, W, 2) in texture-coordinate units,
    blended the same way
    and packed as ``alpha = sqrt(5 |v|)`` (``SMAA_REPROJECTION``); ``unorm8``: the target
    is RGBA8 (sRGB view when ``srgb``): the written colour and alpha are rounded to 1/255
    (``color`` should then hold multiples of 1/255, the 8-bit input).

    Returns a dict: ``color`` (H, W, 3) float32, ``blended`` (H, W) bool, ``alpha`` (H, W)
    float32 (zeros without ``velocity``), ``linear`` (H, W, 3) float32 (the shader's output
    before the write's encoding, in the blending space) and each ``extra`` by name.
    """
    c = np.asarray(color, np.float32)
    wts = np.asarray(weights, np.float64)
    h, w = c.shape[:2]
    right = wts[:, np.minimum(np.arange(w) + 1, w - 1), 3]
    below = wts[np.minimum(np.arange(h) + 1, h - 1), :, 1]
    a = np.stack([right, below, wts[..., 2], wts[..., 0]], axis=-1)  # a.x a.y a.z a.w
    blended = a.sum(axis=-1) >= _NO_BLEND
    jy, jx = np.nonzero(blended)
    a = a[jy, jx]
    horiz = np.maximum(a[:, 0], a[:, 2]) > np.maximum(a[:, 1], a[:, 3])
    off = np.where(horiz[:, None], a * [1, 0, 1, 0], a * [0, 1, 0, 1])
    bw = np.where(horiz[:, None], a[:, [0, 2]], a[:, [1, 3]])
    bw = bw / bw.sum(axis=1, keepdims=True)
    xc, yc = jx + 0.5, jy + 0.5
    p1 = (xc + off[:, 0], yc + off[:, 1])
    p2 = (xc - off[:, 2], yc - off[:, 3])

    def mix(tex):
        t = np.asarray(tex, np.float64)
        s1, s2 = bilinear(t, *p1, bits=subtexel_bits), bilinear(t, *p2, bits=subtexel_bits)
        if t.ndim == 3:
            return bw[:, :1] * s1 + bw[:, 1:] * s2
        return bw[:, 0] * s1 + bw[:, 1] * s2

    out = c.copy()
    lin = srgb_decode(c) if srgb else c
    mixed = mix(lin).astype(np.float32)
    shader = np.array(lin, np.float32, copy=True)
    shader[jy, jx] = mixed
    written = srgb_encode(mixed) if srgb else mixed
    out[jy, jx] = (to_unorm8(written) if unorm8 else written).astype(np.float32)
    res = {
        "color": out,
        "blended": blended,
        "alpha": np.zeros((h, w), np.float32),
        "linear": shader,
    }
    for name, arr in (extra or {}).items():
        e = np.asarray(arr, np.float32).copy()
        e[jy, jx] = mix(arr).astype(np.float32)
        res[name] = e
    for name, (ids, target) in (match or {}).items():
        m = (np.asarray(ids) == np.asarray(target)).astype(np.float32)
        t = np.asarray(target)[jy, jx]
        got = np.zeros(len(jx))
        for k, p in enumerate((p1, p2)):
            taps, tw = bilinear_taps(ids.shape, *p, bits=subtexel_bits)
            for (tj, ti), wt in zip(taps, tw, strict=True):
                got += bw[:, k] * wt * (ids[tj, ti] == t)
        m[jy, jx] = got
        res[name] = m
    if velocity is not None:
        v = np.asarray(velocity, np.float64).copy()
        v[jy, jx] = mix(velocity)
        alpha = np.sqrt(5.0 * np.hypot(v[..., 0], v[..., 1]))
        res["alpha"] = (to_unorm8(alpha) if unorm8 else alpha).astype(np.float32)
    if fetches is not None:
        taps = h * w + len(jx)  # one colour fetch per pixel, two where it blends
        fetches.add("blend:weights", 3 * h * w)
        fetches.add("blend:color", taps)
        if velocity is not None:
            fetches.add("blend:velocity", taps)
    return res


def resolve(
    current: np.ndarray,
    previous: np.ndarray,
    *,
    alpha_current: np.ndarray,
    alpha_previous: np.ndarray,
    velocity: np.ndarray | None = None,
    weight_scale: float = REPROJECTION_WEIGHT_SCALE,
    srgb: bool = False,
    unorm8: bool = False,
    fetches: Fetches | None = None,
) -> np.ndarray:
    """``SMAAResolvePS`` with ``SMAA_REPROJECTION``: (H, W, C) float32.

    ``current``, ``previous``: (H, W, C) frames as stored (gamma-encoded); ``srgb``: the
    first three channels are read through an sRGB view (the demo's ``previousRT`` targets
    are ``R8G8B8A8_UNORM_SRGB``: decoded, mixed in linear light, encoded on write; without
    it they are mixed as stored); ``unorm8``: the written colour is rounded to 1/255;
    ``alpha_*``: their packed velocity lengths; ``velocity``: (H, W, 2) current velocity
    (``SMAA_DECODE_VELOCITY``: current minus previous position) in texture-coordinate
    units (None: a static camera, zero everywhere).
    """
    cur = np.asarray(current, np.float32)
    h, w = cur.shape[:2]
    jy, jx = np.mgrid[0:h, 0:w]
    if velocity is not None:
        # previous frame fetched (point) at texcoord - velocity
        v = np.asarray(velocity, np.float64)
        jx = np.floor(jx + 0.5 - v[..., 0] * w).astype(np.intp)
        jy = np.floor(jy + 0.5 - v[..., 1] * h).astype(np.intp)
    jx, jy = np.clip(jx, 0, w - 1), np.clip(jy, 0, h - 1)
    prev = np.asarray(previous, np.float32)[jy, jx]
    ap = np.asarray(alpha_previous, np.float32)[jy, jx]
    ac = np.asarray(alpha_current, np.float32)
    delta = np.abs(ac * ac - ap * ap) / np.float32(5.0)
    weight = np.float32(0.5) * np.clip(1.0 - np.sqrt(delta) * np.float32(weight_scale), 0.0, 1.0)
    if fetches is not None:
        fetches.add("resolve:color", 2 * h * w)
        if velocity is not None:
            fetches.add("resolve:velocity", h * w)
    if srgb:
        cur, prev = cur.copy(), prev.copy()
        cur[..., :3], prev[..., :3] = srgb_decode(cur[..., :3]), srgb_decode(prev[..., :3])
    out = (cur + (prev - cur) * weight[..., None]).astype(np.float32)
    if srgb:
        out[..., :3] = srgb_encode(out[..., :3])
    if unorm8:
        out[..., :3] = to_unorm8(out[..., :3])
    return out
