"""The FXAA 3.11 filter, quality path, ported to NumPy (vectorized over pixels); the
``fxaa`` technique that runs it on the one-sample image is :mod:`.fxaa`.

The port follows ``FxaaPixelShader`` of FXAA 3.11 (``FXAA_PC 1``, ``FXAA_GREEN_AS_LUMA 0``)
operation for operation, in float32 like the shader: the 3x3 luma neighbourhood and the early
exit on local contrast, the horizontal/vertical edge decision, the choice of the steeper
neighbour pair, the sub-pixel term, the edge-end search (``FXAA_QUALITY__PS`` steps of the
preset's table, run for every pixel at once as a fixed number of vectorized iterations), and
the final re-fetch of the colour at the offset position. Sums are grouped as in the shader:
FXAA's horizontal and vertical edge measures are often equal in exact arithmetic (with the
usual signs both expand to the same sum), so float32 rounding picks the branch, as it does on
a GPU (whose fused multiply-adds may round such ties the other way).

Texture fetches are modelled as a GPU samples a clamp-to-edge texture: integer-offset taps
read texels, the edge-end taps and the final colour tap are bilinear (exact weights; hardware
uses 8-bit fractions, a difference below 1/256 of a texel). The colour target is modelled as
an sRGB-format (or float) texture, so the fetch returns linear data and filtering is linear,
and luma is stored "in a perceptual space" as FXAA 3.11 requires: the header's recipe for a
linear target, ``luma = sqrt(dot(rgb, (0.299, 0.587, 0.114)))`` (gamma 2.0), with the dot
product clipped to ``[0, 1]`` as an 8-bit luma channel would store it. With
``encoding="gamma"`` the colour target is modelled as a UNORM (non-sRGB) texture holding
gamma-encoded LDR values, FXAA 3.11's other documented set-up (and the one engines ship: the
tone-mapping pass writes gamma-encoded colour with ``luma = dot(rgb, (0.299, 0.587,
0.114))`` of those encoded values in alpha): fetches and filtering act on the encoded values
and the luma is the dot product itself, clipped to ``[0, 1]``.

Preset: 12 by default, FXAA 3.11's own default (``FXAA_QUALITY__PRESET 12``: 5 steps,
1.0, 1.5, 2.0, 4.0, 12.0 texels, "slightly faster than FXAA 3.9 and higher edge quality"), the
one shipped integrations use unless told otherwise; 39 ("no dither, very expensive": 12 steps,
five of them 1 texel) is the most exact search and is available, as is every other preset of
the 3.11 table.

References
----------
T. Lottes, FXAA (whitepaper), NVIDIA, 2009; FXAA 3.11 source (``Fxaa3_11.h``), NVIDIA, 2011.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ModelError

__all__ = ["ENCODINGS", "FXAA_PRESETS", "fxaa", "fxaa_luma"]

#: Edge-search step table of every FXAA 3.11 quality preset (``FXAA_QUALITY__P0..P11``).
FXAA_PRESETS: dict[int, tuple[float, ...]] = {
    10: (1.5, 3.0, 12.0),
    11: (1.0, 1.5, 3.0, 12.0),
    12: (1.0, 1.5, 2.0, 4.0, 12.0),
    13: (1.0, 1.5, 2.0, 2.0, 4.0, 12.0),
    14: (1.0, 1.5, 2.0, 2.0, 2.0, 4.0, 12.0),
    15: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 12.0),
    20: (1.5, 2.0, 8.0),
    21: (1.0, 1.5, 2.0, 8.0),
    22: (1.0, 1.5, 2.0, 2.0, 8.0),
    23: (1.0, 1.5, 2.0, 2.0, 2.0, 8.0),
    24: (1.0, 1.5, 2.0, 2.0, 2.0, 3.0, 8.0),
    25: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    26: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    27: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    28: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    29: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    39: (1.0, 1.0, 1.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
}

#: Luma weights of FXAA 3.11's documented luma pass (Rec. 601).
LUMA_WEIGHTS = (0.299, 0.587, 0.114)

_F = np.float32


def _check_unit(name: str, value: float, *, low_open: bool) -> float:
    v = float(value)
    ok = math.isfinite(v) and (0.0 < v if low_open else 0.0 <= v) and v <= 1.0
    if not ok:
        interval = "(0, 1]" if low_open else "[0, 1]"
        raise ModelError(f"fxaa {name} must be a number in {interval}, got {value!r}")
    return v


#: Colour encodings :func:`fxaa` accepts (see the module docstring).
ENCODINGS = ("linear", "gamma")


def fxaa_luma(rgb_linear: np.ndarray, *, encoding: str = "linear") -> np.ndarray:
    """FXAA's luma: ``sqrt(clip(dot(rgb, (0.299, 0.587, 0.114)), 0, 1))`` of a linear image
    (``encoding="linear"``), ``clip(dot(rgb, ...), 0, 1)`` of a gamma-encoded one
    (``encoding="gamma"``: FXAA 3.11's luma of gamma-space colour, already perceptual).

    Parameters
    ----------
    rgb_linear : (H, W, 3) array
        Display-referred (tone-mapped) colour so that 1 is white: linear for ``"linear"``,
        gamma-encoded for ``"gamma"``.

    Returns
    -------
    (H, W) float32 array in ``[0, 1]``, perceptually encoded.
    """
    rgb = np.asarray(rgb_linear, dtype=_F)
    w = np.asarray(LUMA_WEIGHTS, dtype=_F)
    y = rgb[..., 0] * w[0] + rgb[..., 1] * w[1] + rgb[..., 2] * w[2]
    y = np.clip(y, _F(0.0), _F(1.0))
    if encoding == "gamma":
        return y.astype(_F)
    return np.sqrt(y).astype(_F)


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear clamp-to-edge fetch of ``img`` (H, W[, C]) at pixel coordinates (centre +0.5)."""
    h, w = img.shape[:2]
    u = x - _F(0.5)
    v = y - _F(0.5)
    x0f = np.floor(u)
    y0f = np.floor(v)
    fx = (u - x0f).astype(_F)
    fy = (v - y0f).astype(_F)
    x0 = np.clip(x0f.astype(np.int64), 0, w - 1)
    x1 = np.clip(x0f.astype(np.int64) + 1, 0, w - 1)
    y0 = np.clip(y0f.astype(np.int64), 0, h - 1)
    y1 = np.clip(y0f.astype(np.int64) + 1, 0, h - 1)
    if img.ndim == 3:
        fx = fx[:, None]
        fy = fy[:, None]
    top = img[y0, x0] * (_F(1.0) - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (_F(1.0) - fx) + img[y1, x1] * fx
    return (top * (_F(1.0) - fy) + bottom * fy).astype(_F)


def _neighbourhood(luma: np.ndarray, q_thr, q_thr_min):
    """Step 1 of ``FxaaPixelShader``: the 3x3 luma taps (clamp to edge) and the early exit
    on local contrast. Returns ``(taps, luma_range, early_exit)``, ``taps`` a function of
    the integer offset ``(dx, dy)`` (y down) giving the whole ``(H, W)`` tap image."""
    h, w = luma.shape
    lp = np.pad(luma, 1, mode="edge")  # clamp-to-edge taps

    def tap(dx: int, dy: int) -> np.ndarray:
        return lp[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]

    luma_m = luma
    luma_s, luma_e, luma_n, luma_w = tap(0, 1), tap(1, 0), tap(0, -1), tap(-1, 0)
    range_max = np.maximum(
        np.maximum(luma_n, luma_w), np.maximum(luma_e, np.maximum(luma_s, luma_m))
    )
    range_min = np.minimum(
        np.minimum(luma_n, luma_w), np.minimum(luma_e, np.minimum(luma_s, luma_m))
    )
    luma_range = range_max - range_min
    early_exit = luma_range < np.maximum(q_thr_min, range_max * q_thr)
    return tap, luma_range, early_exit


def _edge(t: dict) -> dict:
    """Step 2: the horizontal/vertical edge decision, the sub-pixel term and the steeper
    neighbour pair, on the taps ``t`` (``m, s, e, n, w, nw, se, ne, sw`` and ``range``: 1-D
    arrays over the pixels past the early exit), with the shader's grouping of sums."""
    two = _F(2.0)
    l_m, l_n, l_s, l_w, l_e = t["m"], t["n"], t["s"], t["w"], t["e"]
    l_nw, l_se, l_ne, l_sw, rng = t["nw"], t["se"], t["ne"], t["sw"], t["range"]
    luma_ns = l_n + l_s
    luma_we = l_w + l_e
    with np.errstate(divide="ignore"):
        subpix_rcp_range = np.where(rng > 0, _F(1.0) / np.where(rng > 0, rng, _F(1.0)), _F(0.0))
    subpix_nswe = luma_ns + luma_we
    edge_horz1 = -two * l_m + luma_ns
    edge_vert1 = -two * l_m + luma_we
    luma_nese = l_ne + l_se
    luma_nwne = l_nw + l_ne
    edge_horz2 = -two * l_e + luma_nese
    edge_vert2 = -two * l_n + luma_nwne
    luma_nwsw = l_nw + l_sw
    luma_swse = l_sw + l_se
    edge_horz4 = np.abs(edge_horz1) * two + np.abs(edge_horz2)
    edge_vert4 = np.abs(edge_vert1) * two + np.abs(edge_vert2)
    edge_horz3 = -two * l_w + luma_nwsw
    edge_vert3 = -two * l_s + luma_swse
    edge_horz = np.abs(edge_horz3) + edge_horz4
    edge_vert = np.abs(edge_vert3) + edge_vert4
    subpix_nwswnese = luma_nwsw + luma_nese
    horz_span = edge_horz >= edge_vert
    subpix_a = subpix_nswe * two + subpix_nwswnese
    # For a vertical edge the "north/south" pair is west/east; the search runs along the edge.
    l_n = np.where(horz_span, l_n, l_w)
    l_s = np.where(horz_span, l_s, l_e)
    subpix_b = subpix_a * _F(1.0 / 12.0) - l_m
    gradient_n = l_n - l_m
    gradient_s = l_s - l_m
    luma_nn = l_n + l_m
    luma_ss = l_s + l_m
    pair_n = np.abs(gradient_n) >= np.abs(gradient_s)
    gradient = np.maximum(np.abs(gradient_n), np.abs(gradient_s))
    subpix_c = np.clip(np.abs(subpix_b) * subpix_rcp_range, _F(0.0), _F(1.0))
    subpix_d = _F(-2.0) * subpix_c + _F(3.0)
    subpix_e = subpix_c * subpix_c
    luma_nn = np.where(pair_n, luma_nn, luma_ss)
    return {
        "horz_span": horz_span,
        "length_sign": np.where(pair_n, _F(-1.0), _F(1.0)).astype(_F),  # rcpFrame = 1 pixel
        "gradient_scaled": gradient * _F(1.0 / 4.0),
        "half_nn": luma_nn * _F(0.5),
        "luma_mlt_zero": (l_m - luma_nn * _F(0.5)) < 0,
        "subpix_f": subpix_d * subpix_e,
    }


def _end_search(luma, steps, edge: dict, pos_b, off):
    """Step 3: the edge-end search along the edge from ``posB``, ``FXAA_QUALITY__PS`` steps
    of the preset (every pixel at once, a fixed number of vectorized rounds). Returns
    ``(dst_n, dst_p, luma_end_n, luma_end_p)``: the distances (texels) of ``posN``/``posP``
    from ``posM`` and the lumas found there, relative to the edge's mean luma."""
    pos_b_x, pos_b_y = pos_b
    off_x, off_y = off
    half_nn, gradient_scaled = edge["half_nn"], edge["gradient_scaled"]
    dst_n = np.full(len(pos_b_x), steps[0], dtype=_F)
    dst_p = np.full(len(pos_b_x), steps[0], dtype=_F)

    def end_luma(dist: np.ndarray, sign: float) -> np.ndarray:
        x = pos_b_x + _F(sign) * off_x * dist
        y = pos_b_y + _F(sign) * off_y * dist
        return _bilinear(luma, x, y) - half_nn

    luma_end_n = end_luma(dst_n, -1.0)
    luma_end_p = end_luma(dst_p, 1.0)
    for k in range(1, len(steps)):
        done_n = np.abs(luma_end_n) >= gradient_scaled
        done_p = np.abs(luma_end_p) >= gradient_scaled
        dst_n = np.where(done_n, dst_n, dst_n + _F(steps[k]))
        dst_p = np.where(done_p, dst_p, dst_p + _F(steps[k]))
        if k < len(steps) - 1:  # the shader reads no luma after its last step
            if (~done_n).any():
                luma_end_n = np.where(done_n, luma_end_n, end_luma(dst_n, -1.0))
            if (~done_p).any():
                luma_end_p = np.where(done_p, luma_end_p, end_luma(dst_p, 1.0))
    return dst_n, dst_p, luma_end_n, luma_end_p


def _pixel_offset(edge: dict, search, q_subpix) -> np.ndarray:
    """Step 4: the offset across the edge (texels): the span's end-distance offset where
    the span is good, at least the sub-pixel offset."""
    dst_n, dst_p, luma_end_n, luma_end_p = search
    luma_mlt_zero = edge["luma_mlt_zero"]
    good_span_n = (luma_end_n < 0) != luma_mlt_zero
    good_span_p = (luma_end_p < 0) != luma_mlt_zero
    span_length = dst_p + dst_n
    span_length_rcp = _F(1.0) / span_length
    direction_n = dst_n < dst_p
    dst = np.minimum(dst_n, dst_p)
    good_span = np.where(direction_n, good_span_n, good_span_p)
    subpix_g = edge["subpix_f"] * edge["subpix_f"]
    pixel_offset = dst * (-span_length_rcp) + _F(0.5)
    subpix_h = subpix_g * q_subpix
    pixel_offset_good = np.where(good_span, pixel_offset, _F(0.0))
    return np.maximum(pixel_offset_good, subpix_h)


def fxaa(
    rgb_linear: np.ndarray,
    *,
    subpix: float = 0.75,
    edge_threshold: float = 0.166,
    edge_threshold_min: float = 0.0833,
    preset: int = 12,
    encoding: str = "linear",
) -> np.ndarray:
    """Apply FXAA 3.11 (quality path) to a display-referred image.

    Parameters
    ----------
    rgb_linear : (H, W, 3) array
        Linear radiance of the 1-sample image, display-referred (FXAA runs after tone
        mapping: the thresholds are fractions of a [0, 1] luma). Finite values.
    subpix : float
        ``fxaaQualitySubpix``, amount of sub-pixel aliasing removal in ``[0, 1]``;
        0.75: FXAA 3.11 default.
    edge_threshold : float
        ``fxaaQualityEdgeThreshold``, minimum local contrast relative to the local maximum
        luma, in ``(0, 1]``; 0.166: FXAA 3.11 default.
    edge_threshold_min : float
        ``fxaaQualityEdgeThresholdMin``, minimum absolute local contrast (skips dark areas),
        in ``[0, 1]``; 0.0833: FXAA 3.11 default.
    preset : int
        ``FXAA_QUALITY__PRESET``, one of :data:`FXAA_PRESETS`; 12: FXAA 3.11 default.
    encoding : ``"linear"`` or ``"gamma"``
        How the image is stored (:data:`ENCODINGS`, module docstring): ``"linear"``, an
        sRGB-format target read as linear values, luma ``sqrt(dot)``; ``"gamma"``,
        gamma-encoded LDR values filtered as stored, luma ``dot``. Values outside [0, 1]
        only occur if the caller skipped tone mapping: FXAA's thresholds assume [0, 1].

    Returns
    -------
    (H, W, 3) float32 array
        The image after FXAA, in the input's encoding. Pixels below the contrast threshold
        are returned unchanged (bit for bit).

    Notes
    -----
    Where the shader would divide by a zero luma range (only with ``edge_threshold_min=0``
    on a flat area) the sub-pixel term is 0, as ``saturate(NaN)`` is 0 on GPUs.
    """
    rgb = np.asarray(rgb_linear)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] < 1 or rgb.shape[1] < 1:
        raise ModelError(f"fxaa needs an (H, W, 3) image, got shape {rgb.shape}")
    rgb = rgb.astype(_F, copy=False)
    if not np.isfinite(rgb).all():
        raise ModelError("fxaa input image has NaN or inf values")
    if preset not in FXAA_PRESETS:
        raise ModelError(f"fxaa preset must be one of {sorted(FXAA_PRESETS)}, got {preset!r}")
    if encoding not in ENCODINGS:
        raise ModelError(f"fxaa encoding must be one of {', '.join(ENCODINGS)}, got {encoding!r}")
    q_subpix = _F(_check_unit("subpix", subpix, low_open=False))
    q_thr = _F(_check_unit("edge_threshold", edge_threshold, low_open=True))
    q_thr_min = _F(_check_unit("edge_threshold_min", edge_threshold_min, low_open=False))
    luma = fxaa_luma(rgb, encoding=encoding)
    tap, luma_range, early_exit = _neighbourhood(luma, q_thr, q_thr_min)
    out = rgb.copy()
    iy, ix = np.nonzero(~early_exit)
    if iy.size == 0:
        return out
    offsets = {"m": (0, 0), "s": (0, 1), "e": (1, 0), "n": (0, -1), "w": (-1, 0)}
    offsets.update(nw=(-1, -1), se=(1, 1), ne=(1, -1), sw=(-1, 1))
    taps = {key: tap(dx, dy)[iy, ix] for key, (dx, dy) in offsets.items()}
    taps["range"] = luma_range[iy, ix]
    edge = _edge(taps)
    horz_span, length_sign = edge["horz_span"], edge["length_sign"]
    # posB: half a pixel across the edge, toward the steeper neighbour; offNP along the edge.
    cx = ix.astype(_F) + _F(0.5)
    cy = iy.astype(_F) + _F(0.5)
    pos_b = (
        np.where(horz_span, cx, cx + length_sign * _F(0.5)),
        np.where(horz_span, cy + length_sign * _F(0.5), cy),
    )
    off = (
        np.where(horz_span, _F(1.0), _F(0.0)).astype(_F),
        np.where(horz_span, _F(0.0), _F(1.0)).astype(_F),
    )
    search = _end_search(luma, FXAA_PRESETS[preset], edge, pos_b, off)
    shift = _pixel_offset(edge, search, q_subpix) * length_sign
    px = np.where(horz_span, cx, cx + shift).astype(_F)
    py = np.where(horz_span, cy + shift, cy).astype(_F)
    out[iy, ix] = _bilinear(rgb, px, py)
    return out
