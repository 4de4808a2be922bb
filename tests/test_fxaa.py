"""FXAA 3.11 port: identities and results derived by hand from the shader's arithmetic."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa.fxaa_filter import FXAA_PRESETS, fxaa, fxaa_luma
from raster_oracle.raster_models.errors import ModelError

#: float32 arithmetic in the port against exact fractions in the derivations.
TOL = 1e-5

#: Sub-pixel blend of a straight step edge (derivation in ``test_step_edge``).
SUBPIX_H = 0.75 * (7.0 / 27.0) ** 2


def test_constant_image_is_identity():
    img = np.full((9, 13, 3), 0.3, np.float32)
    img[..., 2] = 0.7
    out = fxaa(img)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, img)


def test_step_edge():
    """Vertical step, black (x < 6) | white (x >= 6): only the two edge columns change.

    FXAA 3.11 arithmetic, luma L = sqrt(dot(rgb, (0.299, 0.587, 0.114))): black 0, white 1.

    Pixel x = 5 (last black column): M = N = S = W = NW = SW = 0, E = NE = SE = 1.
    range = 1 >= max(0.0833, 0.166 * 1): no early exit.
    edgeHorz = |-2W + NW + SW| + 2|-2M + N + S| + |-2E + NE + SE| = 0 + 0 + 0 = 0,
    edgeVert = |-2S + SW + SE| + 2|-2M + W + E| + |-2N + NW + NE| = 1 + 2 + 1 = 4,
    so horzSpan is false (vertical edge), N := W = 0, S := E = 1.
    subpixA = 2 (N + S + W + E) + (NW + SW + NE + SE) = 2 + 2 = 4,
    subpixB = 4/12 - M = 1/3, subpixC = |subpixB| / range = 1/3,
    subpixF = (3 - 2C) C^2 = 7/27, subpixH = 0.75 * subpixF^2 = 0.0504115.
    gradientN = 0, gradientS = 1: pairN false, lengthSign = +1 (toward x = 6).
    posB is on the boundary x = 6.0; every edge-end tap reads (0 + 1)/2 = 0.5 (clamped
    addressing keeps it so past the border), minus lumaNN/2 = (S + M)/2 = 0.5 gives 0, never
    >= gradient/4 = 0.25: the search runs out on both sides, dstN = dstP, pixelOffset =
    0.5 - dst/(2 dst) = 0, so the final offset is subpixH toward x = 6:
    out = (1 - subpixH) * 0 + subpixH * 1 = 0.0504115.
    Pixel x = 6 mirrors it (pairN true, lengthSign = -1; lumaMM = 1 - 0.5 > 0 and the end
    lumas are 0, not < 0, so goodSpan is false and again only subpixH applies):
    out = 1 - 0.0504115. Every other pixel has range 0: unchanged.
    """
    img = np.zeros((16, 12, 3), np.float32)
    img[:, 6:] = 1.0
    out = fxaa(img)
    expected = img[..., 0].copy()
    expected[:, 5] = SUBPIX_H
    expected[:, 6] = 1.0 - SUBPIX_H
    for c in range(3):
        np.testing.assert_allclose(out[..., c], expected, atol=TOL)
    # The same edge turned horizontal takes the horzSpan branch to the same numbers.
    out_t = fxaa(np.ascontiguousarray(img.transpose(1, 0, 2)))
    np.testing.assert_allclose(out_t, out.transpose(1, 0, 2), atol=TOL)


def test_coloured_step_blends_linearly():
    """Any two colours whose luma contrast passes the thresholds: subpixC is always 1/3.

    With M = N = S = W = NW = SW = La and E = NE = SE = Lb:
    subpixB = (2 (3 La + Lb) + 2 La + 2 Lb)/12 - La = (Lb - La)/3 and range = |Lb - La|,
    so the dark-side pixel becomes (1 - subpixH) a + subpixH b in linear RGB (the fetch is
    bilinear in linear values, as from an sRGB-format texture).
    """
    a = np.array([0.8, 0.6, 0.05], np.float32)
    b = np.array([0.05, 0.1, 0.9], np.float32)
    img = np.empty((10, 10, 3), np.float32)
    img[:, :5] = a
    img[:, 5:] = b
    out = fxaa(img)
    np.testing.assert_allclose(out[4, 4], (1 - SUBPIX_H) * a + SUBPIX_H * b, atol=TOL)
    np.testing.assert_allclose(out[4, 5], (1 - SUBPIX_H) * b + SUBPIX_H * a, atol=TOL)
    np.testing.assert_array_equal(out[:, :4], img[:, :4])


def test_edge_end_search_preset_12_and_39():
    """A horizontal edge that ends: white block rows y >= 8, columns x < 6, black elsewhere.

    Pixel (x, 8), white, below the edge, x in {2, 4}: N = NW = NE = 0, M = S = W = E = SW = SE
    = 1. edgeHorz = 1 + 2 + 1 = 4 > edgeVert = 0: horizontal span, search along x.
    subpixB = 8/12 - 1 = -1/3, subpixH = 0.0504 as for the step. gradientN = -1: pairN,
    lengthSign = -1, posB.y = 8.0 (between rows 7 and 8), lumaNN = N + M = 1.
    The tap at (x', 8.0) reads r(x')/2 with r the bilinear row-8 luma (1 for x' <= 5.5,
    0 for x' >= 6.5); minus 0.5: 0 until the block ends, -0.5 past it (done: >= 0.25).
    Toward -x the clamped image never ends: dstN = sum of the preset's steps (12: 20.5,
    39: 26.5). Toward +x from the centre cx = x + 0.5, preset 12 (1, 1.5, 2, 4, 12):
      x = 2: taps 3.5, 5.0 read 0, 7.0 reads -0.5: dstP = 1 + 1.5 + 2 = 4.5;
      x = 4: taps 5.5 reads 0, 7.0 reads -0.5: dstP = 1 + 1.5 = 2.5.
    Preset 39 (1, 1, 1, 1, 1, 1.5, ...), x = 2: taps 3.5, 4.5, 5.5, 6.5: dstP = 4.
    lumaMM = M - lumaNN/2 = 0.5 >= 0 and lumaEndP < 0: goodSpanP; dstP < dstN picks it:
    pixelOffset = 0.5 - dstP / (dstP + dstN), larger than subpixH, moves the fetch up
    into the black row: out = 1 - pixelOffset.
      preset 12: x = 2: 1 - (0.5 - 4.5/25) = 17/25; x = 4: 1 - (0.5 - 2.5/23) = 14/23.
      preset 39: x = 2: 1 - (0.5 - 4/30.5).
    """
    img = np.zeros((16, 24, 3), np.float32)
    img[8:, :6] = 1.0
    out12 = fxaa(img)
    assert out12[8, 2, 0] == pytest.approx(17 / 25, abs=TOL)
    assert out12[8, 4, 0] == pytest.approx(14 / 23, abs=TOL)
    out39 = fxaa(img, preset=39)
    assert out39[8, 2, 0] == pytest.approx(1 - (0.5 - 4 / 30.5), abs=TOL)
    assert sum(FXAA_PRESETS[12]) == 20.5 and sum(FXAA_PRESETS[39]) == 26.5


def test_contrast_thresholds():
    """Early exit: range < max(edge_threshold_min, edge_threshold * rangeMax)."""
    dark = np.zeros((8, 8, 3), np.float32)
    dark[:, 4:] = 0.005  # luma sqrt(0.005) = 0.0707 < 0.0833: below the absolute minimum
    np.testing.assert_array_equal(fxaa(dark), dark)
    assert fxaa_luma(dark)[0, 7] == pytest.approx(np.sqrt(0.005), rel=1e-6)
    changed = fxaa(dark, edge_threshold_min=0.05)
    assert changed[0, 3, 0] == pytest.approx(SUBPIX_H * 0.005, rel=1e-4)
    bright = np.full((8, 8, 3), 0.81, np.float32)
    bright[:, 4:] = 0.64  # lumas 0.9 and 0.8: range 0.1 < 0.166 * 0.9 = 0.149
    np.testing.assert_array_equal(fxaa(bright), bright)
    assert not np.array_equal(fxaa(bright, edge_threshold=0.1), bright)


def test_subpix_zero_keeps_straight_edges():
    """subpix = 0 removes the sub-pixel term; an endless straight edge then has offset 0."""
    img = np.zeros((12, 12, 3), np.float32)
    img[:, 6:] = 1.0
    np.testing.assert_allclose(fxaa(img, subpix=0.0), img, atol=TOL)


def test_output_stays_in_the_neighbourhood_range():
    """The fetch moves at most half a pixel across the edge: each output lies between the
    pixel's own value and one 4-neighbour's, hence inside the 3x3 min/max."""
    rng = np.random.default_rng(7)
    img = (rng.random((24, 20, 3)) ** 2).astype(np.float32)
    out = fxaa(img)
    pad = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode="edge")
    win = np.stack([pad[dy : dy + 24, dx : dx + 20] for dy in range(3) for dx in range(3)])
    assert (out >= win.min(axis=0) - TOL).all() and (out <= win.max(axis=0) + TOL).all()
    assert not np.array_equal(out, img)
    np.testing.assert_array_equal(fxaa(img), out)  # deterministic


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"preset": 7}, "preset must be one of"),
        ({"subpix": 1.5}, "subpix must be a number in"),
        ({"edge_threshold": 0.0}, "edge_threshold must be a number in"),
        ({"edge_threshold_min": float("nan")}, "edge_threshold_min must be"),
    ],
)
def test_bad_parameters(kwargs, match):
    with pytest.raises(ModelError, match=match):
        fxaa(np.zeros((4, 4, 3), np.float32), **kwargs)


def test_bad_images():
    with pytest.raises(ModelError, match=r"\(H, W, 3\)"):
        fxaa(np.zeros((4, 4), np.float32))
    bad = np.zeros((4, 4, 3), np.float32)
    bad[1, 1, 1] = np.inf
    with pytest.raises(ModelError, match="NaN or inf"):
        fxaa(bad)


def _fxaa_pixel_scalar(luma, rgb, x, y, steps, subpix=0.75, thr=0.166, thr_min=0.0833):
    """FXAA 3.11 ``FxaaPixelShader`` transcribed line by line for one pixel (test oracle for
    the vectorized port; float32 scalars as on the GPU, positions in pixels, rcpFrame = 1).

    float32 matters: FXAA's two edge measures are often equal in exact arithmetic (with the
    usual signs both expand to the same sum), so the shader's rounding picks the branch.
    """
    h, w = luma.shape
    f32 = np.float32

    def tex_off(dx, dy):
        return f32(luma[min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)])

    def tex_top(img, px, py):
        u, v = f32(px) - f32(0.5), f32(py) - f32(0.5)
        x0, y0 = int(np.floor(u)), int(np.floor(v))
        fx, fy = u - f32(x0), v - f32(y0)

        def at(i, j):
            return img[min(max(j, 0), h - 1), min(max(i, 0), w - 1)]

        top = at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx
        bot = at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx
        return top * (1 - fy) + bot * fy

    luma_m = tex_off(0, 0)
    luma_s, luma_e, luma_n, luma_w = tex_off(0, 1), tex_off(1, 0), tex_off(0, -1), tex_off(-1, 0)
    range_max = max(luma_n, luma_w, luma_e, luma_s, luma_m)
    range_min = min(luma_n, luma_w, luma_e, luma_s, luma_m)
    rng = range_max - range_min
    if rng < max(thr_min, range_max * thr):
        return rgb[y, x].astype(np.float64)
    luma_nw, luma_se, luma_ne, luma_sw = (
        tex_off(-1, -1),
        tex_off(1, 1),
        tex_off(1, -1),
        tex_off(-1, 1),
    )
    luma_ns, luma_we = luma_n + luma_s, luma_w + luma_e
    # the shader's own grouping of every sum (float32 rounding depends on it)
    luma_nese, luma_nwne = luma_ne + luma_se, luma_nw + luma_ne
    luma_nwsw, luma_swse = luma_nw + luma_sw, luma_sw + luma_se
    edge_horz4 = abs(-2.0 * luma_m + luma_ns) * 2.0 + abs(-2.0 * luma_e + luma_nese)
    edge_vert4 = abs(-2.0 * luma_m + luma_we) * 2.0 + abs(-2.0 * luma_n + luma_nwne)
    edge_horz = abs(-2.0 * luma_w + luma_nwsw) + edge_horz4
    edge_vert = abs(-2.0 * luma_s + luma_swse) + edge_vert4
    horz_span = edge_horz >= edge_vert
    subpix_a = (luma_ns + luma_we) * 2.0 + (luma_nwsw + luma_nese)
    length_sign = 1.0
    if not horz_span:
        luma_n, luma_s = luma_w, luma_e
    subpix_b = subpix_a * (1.0 / 12.0) - luma_m
    gradient_n, gradient_s = luma_n - luma_m, luma_s - luma_m
    luma_nn, luma_ss = luma_n + luma_m, luma_s + luma_m
    pair_n = abs(gradient_n) >= abs(gradient_s)
    gradient = max(abs(gradient_n), abs(gradient_s))
    if pair_n:
        length_sign = -length_sign
    subpix_c = min(max(abs(subpix_b) * (1.0 / rng), 0.0), 1.0)
    pos_m = [f32(x + 0.5), f32(y + 0.5)]
    pos_b = list(pos_m)
    off = (1.0, 0.0) if horz_span else (0.0, 1.0)
    if horz_span:
        pos_b[1] += length_sign * 0.5
    else:
        pos_b[0] += length_sign * 0.5
    pos_n = [pos_b[0] - off[0] * steps[0], pos_b[1] - off[1] * steps[0]]
    pos_p = [pos_b[0] + off[0] * steps[0], pos_b[1] + off[1] * steps[0]]
    if not pair_n:
        luma_nn = luma_ss
    gradient_scaled = gradient / 4
    luma_mlt_zero = luma_m - luma_nn * 0.5 < 0
    end_n = tex_top(luma, *pos_n) - luma_nn * 0.5
    end_p = tex_top(luma, *pos_p) - luma_nn * 0.5
    done_n, done_p = abs(end_n) >= gradient_scaled, abs(end_p) >= gradient_scaled
    for k in range(1, len(steps)):
        if not done_n:
            pos_n = [pos_n[0] - off[0] * steps[k], pos_n[1] - off[1] * steps[k]]
        if not done_p:
            pos_p = [pos_p[0] + off[0] * steps[k], pos_p[1] + off[1] * steps[k]]
        if (done_n and done_p) or k == len(steps) - 1:
            break
        if not done_n:
            end_n = tex_top(luma, *pos_n) - luma_nn * 0.5
        if not done_p:
            end_p = tex_top(luma, *pos_p) - luma_nn * 0.5
        done_n, done_p = abs(end_n) >= gradient_scaled, abs(end_p) >= gradient_scaled
    axis = 0 if horz_span else 1
    dst_n = pos_m[axis] - pos_n[axis]
    dst_p = pos_p[axis] - pos_m[axis]
    good_span = ((end_n < 0) != luma_mlt_zero) if dst_n < dst_p else ((end_p < 0) != luma_mlt_zero)
    pixel_offset = min(dst_n, dst_p) * -(1.0 / (dst_n + dst_p)) + 0.5
    subpix_h = ((-2 * subpix_c + 3) * subpix_c * subpix_c) ** 2 * subpix
    offset = max(pixel_offset if good_span else 0.0, subpix_h)
    if horz_span:
        pos_m[1] += offset * length_sign
    else:
        pos_m[0] += offset * length_sign
    return tex_top(rgb, *pos_m)


@pytest.mark.parametrize("preset", [12, 39, 10])
def test_matches_line_by_line_transcription(preset):
    """The vectorized port equals a per-pixel transcription of the shader (a loop over
    pixels, float64) on shapes with edge ends, corners, diagonals and noise."""
    rng = np.random.default_rng(preset)
    h, w = 20, 26
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.zeros((h, w, 3), np.float32)
    img[(xx - 3) * 0.4 > (yy - 2)] = (0.9, 0.7, 0.2)  # shallow diagonal
    img[5:11, 14:22] = (0.1, 0.2, 0.9)  # a box: edges that end
    img[14:, :] += (rng.random((h - 14, w, 1)) * 0.5).astype(np.float32)  # noise
    img[2, 20] = 1.0  # a lone bright pixel
    # a little noise everywhere: on two-level images the edge-end test sits exactly on its
    # threshold (0.5 (0.5 L + L) - 0.5 L = L / 4), where any reordering of float32
    # operations may flip it
    img += (rng.random((h, w, 1)) * 0.03).astype(np.float32)
    out = fxaa(img, preset=preset)
    luma = fxaa_luma(img)
    expected = np.array(
        [
            [_fxaa_pixel_scalar(luma, img, x, y, FXAA_PRESETS[preset]) for x in range(w)]
            for y in range(h)
        ]
    )
    changed = np.abs(expected - img).max(axis=-1) > 0
    assert changed.sum() > 40
    np.testing.assert_allclose(out, expected, atol=2e-5)
