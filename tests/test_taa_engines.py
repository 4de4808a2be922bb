"""The engine presets of ``taa`` against transcriptions written here from the engines'
shaders, one pixel at a time in the engines' own texture layout (Unity and OpenGL: row 0 at
the bottom, uv y up), independent of the model's vectorized code: a hand-built frame with a
history, a jitter, object motion, ties in depth and HDR radiance. Sources:
playdeadgames/temporal 4795aa0 (TemporalReprojection.shader, IncDepth.cginc,
FrustumJitter.cs), google/filament (taa.mat 63ddbb2, PostProcessManager.cpp 003e500)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from raster_oracle.raster_models.aa.taa import filament, hdrp, inside, ue4
from raster_oracle.raster_models.aa.taa.params import TaaParams, resolve

from raster_oracle import raster_models, scenes

#: float64 transcription against float64 model: rounding only.
TOL = 1e-9
W, H = 7, 5


def _frame(seed):
    rng = np.random.default_rng(seed)
    samples = rng.random((H, W, 3)) * 1.3
    samples[2, 3] = [5.0, 4.5, 6.0]  # an HDR highlight (peak radiance above 4)
    samples = samples.astype(np.float16).astype(np.float64)  # what a half-float target holds
    mv = rng.uniform(-1.6, 1.6, (H, W, 2))
    depth = rng.choice([2.0, 3.0, 3.0, 5.0], size=(H, W))  # ties: the first minimum wins
    return samples, mv, depth


# ------------------------------------------------------------------ Unity texture helpers


def _up(img):
    """An image (rows top to bottom) in Unity's layout (row 0 at the bottom)."""
    return img[::-1]


def _tex2d(tex, u, v):
    """Bilinear ``tex2D`` with TextureWrapMode.Clamp; ``tex`` rows bottom-up, uv y up."""
    h, w = tex.shape[:2]
    fx, fy = u * w - 0.5, v * h - 0.5
    x0, y0 = math.floor(fx), math.floor(fy)
    tx, ty = fx - x0, fy - y0

    def at(i, j):
        return tex[min(max(j, 0), h - 1), min(max(i, 0), w - 1)]

    return (1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x0 + 1, y0)) + ty * (
        (1 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1)
    )


def _srgb8(c):
    c = min(max(c, 0.0), 1.0)
    e = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055
    q = round(255.0 * e) / 255.0
    return q / 12.92 if q <= 0.04045 else ((q + 0.055) / 1.055) ** 2.4


def _halton_seq(prime, index):  # FrustumJitter.HaltonSeq
    r, f, i = 0.0, 1.0, index
    while i > 0:
        f /= prime
        r += f * (i % prime)
        i = int(math.floor(i / prime))
    return r


# ------------------------------------------------------------------ INSIDE


def _inside_pixel(src, prev, vel_tex, depth_tex, sample, px, py):
    """TemporalReprojection.shader ``frag`` for pixel (px, py) of Unity's layout."""
    luminance = (0.0396819152, 0.458021790, 0.00609653955)
    du, dv = 1.0 / W, 1.0 / H
    uv = ((px + 0.5) / W, (py + 0.5) / H)
    # find_closest_fragment_3x3 (point-sampled depth texture, clamped)
    order = [(-1, -1), (0, -1), (1, -1), (-1, 0), (0, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]

    def texel(t, i, j):
        return t[min(max(py + j, 0), H - 1), min(max(px + i, 0), W - 1)]

    dmin = order[0]
    for o in order[1:]:
        if texel(depth_tex, *dmin) > texel(depth_tex, *o):
            dmin = o
    ss_vel = texel(vel_tex, *dmin)
    jitter_uv = (sample[0] / W, sample[1] / H)
    texel0 = _tex2d(src, uv[0] - jitter_uv[0], uv[1] - jitter_uv[1])  # UNJITTER_COLORSAMPLES
    texel1 = _tex2d(prev, uv[0] - ss_vel[0], uv[1] - ss_vel[1])
    taps = {
        (i, j): _tex2d(src, uv[0] + i * du, uv[1] + j * dv) for i in (-1, 0, 1) for j in (-1, 0, 1)
    }
    plus = [taps[k] for k in ((0, -1), (-1, 0), (0, 0), (1, 0), (0, 1))]
    cmin = 0.5 * (np.min(list(taps.values()), axis=0) + np.min(plus, axis=0))
    cmax = 0.5 * (np.max(list(taps.values()), axis=0) + np.max(plus, axis=0))
    # clip_aabb, USE_OPTIMIZATIONS
    p_clip = 0.5 * (cmax + cmin)
    e_clip = 0.5 * (cmax - cmin) + 0.00000001
    v_clip = texel1 - p_clip
    ma_unit = max(abs(v_clip[c] / e_clip[c]) for c in range(3))
    if ma_unit > 1.0:
        texel1 = p_clip + v_clip / ma_unit
    lum0 = sum(luminance[c] * texel0[c] for c in range(3))
    lum1 = sum(luminance[c] * texel1[c] for c in range(3))
    unbiased_diff = abs(lum0 - lum1) / max(lum0, max(lum1, 0.2))
    k_feedback = 0.88 + (0.97 - 0.88) * (1.0 - unbiased_diff) ** 2
    color = texel0 + k_feedback * (texel1 - texel0)  # lerp(texel0, texel1, k)
    return np.clip(color, 0.0, 1.0), np.array([_srgb8(c) for c in color]), k_feedback


def _inside_transcription(samples, history, mv, depth, frame):
    if frame == 0:
        sample = (0.0, 0.0)  # FrustumJitter: activeIndex -2 -> unjittered
    else:
        i = (frame - 1) % 16  # activeIndex, Sample(pattern, i) = Halton(i + 1) - 0.5
        sample = (_halton_seq(2, i + 1) - 0.5, _halton_seq(3, i + 1) - 0.5)
    src = _up(samples)
    if history is None:
        prev = np.vectorize(_srgb8)(src)  # bootstrap: Graphics.Blit(source, history)
        mv = np.zeros_like(mv)
    else:
        prev = _up(history)
    # the velocity buffer holds ss_txc - previous uv (Unity uv, y up)
    vel_tex = _up(np.stack([-mv[..., 0] / W, mv[..., 1] / H], -1))
    depth_tex = _up(depth)
    out = np.zeros((H, W, 3))
    store = np.zeros((H, W, 3))
    k = np.zeros((H, W))
    for py in range(H):
        for px in range(W):
            o, s, kk = _inside_pixel(src, prev, vel_tex, depth_tex, sample, px, py)
            out[H - 1 - py, px], store[H - 1 - py, px], k[H - 1 - py, px] = o, s, kk
    return out, store, k


@pytest.mark.parametrize("frame", [0, 3])
def test_inside_resolve_is_the_shaders_on_a_hand_built_frame(frame):
    samples, mv, depth = _frame(1)
    history = None
    if frame:
        history = np.vectorize(_srgb8)(np.random.default_rng(2).random((H, W, 3)) * 1.2)
    jit = inside.jitter(frame)
    out, store, k = inside.step(history, samples, jit, mv, depth)
    t_out, t_store, t_k = _inside_transcription(samples, history, mv, depth, frame)
    assert np.max(np.abs(out - t_out)) <= TOL
    assert np.max(np.abs(store - t_store)) <= TOL
    assert np.max(np.abs(k - t_k)) <= TOL
    # the history is 8-bit: radiance above 1 is clipped, every value is one of 256 codes
    assert store.max() <= 1.0 and out.max() <= 1.0
    assert samples.max() > 4.0


def test_inside_jitter_is_frustum_jitters_halton_x16_after_an_unjittered_frame():
    assert np.all(inside.jitter(0) == 0)
    # frame 1: Halton(1) - 0.5 = (0, -1/6) in Unity's y-up pixels, +1/6 in y-down
    np.testing.assert_allclose(inside.jitter(1), [0.0, 1 / 6], atol=1e-15)
    np.testing.assert_allclose(inside.jitter(2), [-0.25, -(2 / 3 - 0.5)], atol=1e-15)
    np.testing.assert_allclose(inside.jitter(17), inside.jitter(1), atol=0)


# ------------------------------------------------------------------ Filament


def _gl_catmull_rom(tex, u, v):
    """taa.mat ``sampleTextureCatmullRom`` (tex rows bottom-up, bilinear, clamp to edge)."""
    size = np.array([W, H], dtype=np.float64)
    sample_pos = np.array([u, v]) * size
    tex_pos1 = np.floor(sample_pos - 0.5) + 0.5
    f = sample_pos - tex_pos1
    f2, f3 = f * f, f * f * f
    w0 = f2 - 0.5 * (f3 + f)
    w1 = 1.5 * f3 - 2.5 * f2 + 1.0
    w3 = 0.5 * (f3 - f2)
    w2 = 1.0 - w0 - w1 - w3
    w12 = w1 + w2
    tex_pos0 = (tex_pos1 - 1.0) / size
    tex_pos3 = (tex_pos1 + 2.0) / size
    tex_pos12 = (tex_pos1 + w2 / w12) / size
    k = [w12[0] * w0[1], w0[0] * w12[1], w12[0] * w12[1], w3[0] * w12[1], w12[0] * w3[1]]
    s = [
        _tex2d(tex, tex_pos12[0], tex_pos0[1]),
        _tex2d(tex, tex_pos0[0], tex_pos12[1]),
        _tex2d(tex, tex_pos12[0], tex_pos12[1]),
        _tex2d(tex, tex_pos3[0], tex_pos12[1]),
        _tex2d(tex, tex_pos12[0], tex_pos3[1]),
    ]
    result = sum(ki * si for ki, si in zip(k, s, strict=True)) * (1.0 / sum(k))
    return np.maximum(result, 0.0)


def _filament_weights(jitter):
    offsets = [(-1, -1), (0, -1), (1, -1), (-1, 0), (0, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]
    w = [math.exp(-2.29 * ((ox - jitter[0]) ** 2 + (oy - jitter[1]) ** 2)) for ox, oy in offsets]
    return offsets, [x / sum(w) for x in w]


def _filament_transcription(samples, history, hist_x, hist_y, frame):
    i = frame % 16 + 409  # halton(i, b): i += 409; JitterSequence: - 0.5
    jitter = (_halton_seq(2, i) - 0.5, _halton_seq(3, i) - 0.5)
    offsets, weights = _filament_weights(jitter)
    color = _up(samples.astype(np.float16).astype(np.float64))
    hist_tex = color if history is None else _up(history)
    out = np.zeros((H, W, 3))
    for py in range(H):
        for px in range(W):
            row = H - 1 - py  # y-down row of this GL pixel
            zw = (hist_x[row, px] / W, 1.0 - hist_y[row, px] / H)
            hist = _gl_catmull_rom(hist_tex, *zw)

            s = [color[np.clip(py + b, 0, H - 1), np.clip(px + a, 0, W - 1)] for a, b in offsets]
            filtered = np.maximum(sum(wi * si for wi, si in zip(weights, s, strict=True)), 0.0)
            boxmin = np.minimum(s[4], np.minimum(np.minimum(s[1], s[3]), np.minimum(s[5], s[7])))
            boxmax = np.maximum(s[4], np.maximum(np.maximum(s[1], s[3]), np.maximum(s[5], s[7])))
            box9min = np.minimum(boxmin, np.minimum(np.minimum(s[0], s[2]), np.minimum(s[6], s[8])))
            box9max = np.maximum(boxmax, np.maximum(np.maximum(s[0], s[2]), np.maximum(s[6], s[8])))
            boxmin, boxmax = (boxmin + box9min) * 0.5, (boxmax + box9max) * 0.5
            r = filtered - hist  # clipToBox ACCURATE
            ir = 1.0 / (0.0001 + r)
            imin = np.minimum((boxmax - hist) * ir, (boxmin - hist) * ir)
            hist = hist + r * min(max(max(imin), 0.0), 1.0)
            filtered = filtered * (1.0 / (1.0 + max(filtered)))
            hist = hist * (1.0 / (1.0 + max(hist)))
            result = hist * (1.0 - 0.12) + filtered * 0.12  # mix(history, filtered, alpha)
            result = result * (1.0 / max(1.0 / 65504.0, 1.0 - max(result)))
            out[row, px] = result.astype(np.float16).astype(np.float64)  # RGB16F target
    return out


@pytest.mark.parametrize("frame", [0, 5])
def test_filament_resolve_is_the_materials_on_a_hand_built_frame(frame):
    samples, mv, _ = _frame(3)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64) + 0.5
    history = None
    hist_x, hist_y = x, y  # the first frame reprojects with the current projection
    if frame:
        history = np.random.default_rng(4).random((H, W, 3)) * 3.0
        history = history.astype(np.float16).astype(np.float64)
        hist_x, hist_y = x + mv[..., 0], y + mv[..., 1]
    out, alpha = filament.step(history, samples, frame, hist_x, hist_y)
    expect = _filament_transcription(samples, history, hist_x, hist_y, frame)
    # half-float output: a rounding boundary crossed by 1e-16 would show as one half ulp
    assert np.max(np.abs(out - expect)) <= TOL
    assert np.all(alpha == 0.12)


def test_filament_jitter_starts_at_halton_index_409_and_moves_the_image():
    i = 409
    j = filament.jitter_gl(0)
    np.testing.assert_allclose(j, [_halton_seq(2, i) - 0.5, _halton_seq(3, i) - 0.5])
    np.testing.assert_allclose(filament.jitter_gl(16), j, atol=0)
    # pixel c sees the point at c - jitter (y up): y-down offset (-jx, +jy)
    np.testing.assert_allclose(filament.jitter(0), [-j[0], j[1]])
    w = filament.filter_weights(3)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)


# ------------------------------------------------------------------ the model


def test_engine_presets_run_the_transcription_and_parts_run_the_pipeline():
    assert resolve(TaaParams(preset="inside"))["engine"] == "inside"
    assert resolve(TaaParams(preset="filament"))["engine"] == "filament"
    assert resolve(TaaParams(preset="filament", alpha=0.2))["engine"] == "none"
    assert resolve(TaaParams(preset="ue4"))["engine"] == "ue4"
    assert resolve(TaaParams(preset="custom"))["engine"] == "none"


def test_filament_reprojects_by_camera_only_and_inside_by_object_motion():
    s = scenes.load("slide", width=48, height=27)  # a still camera, a sliding panel
    fil = raster_models.run("taa", s.with_frame(2), preset="filament")
    ins = raster_models.run("taa", s.with_frame(2), preset="inside")
    assert np.abs(fil.outputs["velocity_x"]).max() < 1e-6
    assert np.abs(ins.outputs["velocity_x"]).max() > 0.5


# ------------------------------------------------------------------ HDRP


def _hd_fetch(tex, uv):
    """``Fetch4``: uv clamped to ``1 - 1/size`` (ClampAndScaleForBilinearWithCustomScale),
    then a bilinear linear-clamp fetch (D3D layout: row 0 at the top, uv y down)."""
    u = min(uv[0], 1.0 - 1.0 / W)
    v = min(uv[1], 1.0 - 1.0 / H)
    return _tex2d(tex, u, v)


def _ycocg(c):  # Color.hlsl RGBToYCoCg with YCOCG_CHROMA_BIAS
    b = 128.0 / 255.0
    return np.array(
        [
            0.25 * c[0] + 0.5 * c[1] + 0.25 * c[2],
            0.5 * c[0] - 0.5 * c[2] + b,
            -0.25 * c[0] + 0.5 * c[1] - 0.25 * c[2] + b,
        ]
    )


def _rgb(c):
    b = 128.0 / 255.0
    y, co, cg = c[0], c[1] - b, c[2] - b
    return np.array([y + co - cg, y + cg, y - co - cg])


def _r11g11b10_value(v, bits):
    if not v > 0:
        return 0.0
    e = max(math.floor(math.log2(v)), -14)
    ulp = 2.0 ** (e - bits)
    return min(round(v / ulp) * ulp, (2 - 2.0**-bits) * 2.0**15)


def _r11g11b10(img):
    out = np.zeros_like(img)
    for idx in np.ndindex(img.shape[:2]):
        out[idx] = [_r11g11b10_value(img[idx][c], (6, 6, 5)[c]) for c in range(3)]
    return out


def _hd_bicubic(prev, prev_uv):
    """HistoryBicubic5Tap, sharpening 0.35 (RGB, before the clamp)."""
    size = (W, H)
    c = 0.35
    sample_pos = np.array(prev_uv) * size
    tc1 = np.floor(sample_pos - 0.5) + 0.5
    f = sample_pos - tc1
    f2, f3 = f * f, f * f * f
    w0 = -c * f3 + 2.0 * c * f2 - c * f
    w1 = (2.0 - c) * f3 - (3.0 - c) * f2 + 1.0
    w2 = -(2.0 - c) * f3 + (3.0 - 2.0 * c) * f2 + c * f
    w3 = c * f3 - c * f2
    w12 = w1 + w2
    tc0, tc3, tc12 = (tc1 - 1.0) / size, (tc1 + 2.0) / size, (tc1 + w2 / w12) / size
    s = [
        _hd_fetch(prev, (tc12[0], tc0[1])),
        _hd_fetch(prev, (tc0[0], tc12[1])),
        _hd_fetch(prev, (tc12[0], tc12[1])),
        _hd_fetch(prev, (tc3[0], tc0[1])),
        _hd_fetch(prev, (tc12[0], tc3[1])),
    ]
    cw = [w12[0] * w0[1], w0[0] * w12[1], w12[0] * w12[1], w3[0] * w12[1], w12[0] * w3[1]]
    history = sum(si * ci for si, ci in zip(s, cw, strict=True)) * (1.0 / sum(cw))
    return history


def _hd_high_weights(frame, px, py):
    """PrepareTAAPassData's Blackman-Harris weights + SwizzleFilterWeights: the raw weights and
    the 8 per neighbour. HDRP 12.1.0 (needle-mirror tag 12.1.0/Unity-2021.2.0b16)
    HDRenderPipeline.PostProcess.cs:1534-1545 (TAASampleOffsets), :1578-1579 (x = offset.x -
    taaJitter.x, y likewise), :1599-1600 (weights 1-4, then 5-8)."""
    i = (frame + 1) % 8 + 1  # HDCamera.Update: ++taaFrameIndex before the jitter is built
    jit = (_halton_seq(2, i) - 0.5, _halton_seq(3, i) - 0.5)
    offs = [(0, 0), (0, 1), (1, 0), (-1, 0), (0, -1), (-1, 1), (1, -1), (1, 1), (-1, -1)]
    raw = [math.exp((-0.5 / 0.22) * ((o[0] - jit[0]) ** 2 + (o[1] - jit[1]) ** 2)) for o in offs]
    fp1 = [raw[k] / sum(raw) for k in range(1, 5)]
    fp2 = [raw[k] / sum(raw) for k in range(5, 9)]
    sw = ((px & 1) == 0, (py & 1) == 0)
    if sw[0]:
        fp1[1], fp1[2] = fp1[2], fp1[1]
    if sw[1]:
        fp1[0], fp1[3] = fp1[3], fp1[0]
    x_, y_, z_, w_ = fp2
    if all(sw):
        fp2 = [y_, x_, w_, z_]
    elif sw[0] and not sw[1]:
        fp2 = [z_, w_, x_, y_]
    elif not sw[0] and sw[1]:
        fp2 = [w_, z_, y_, x_]
    return raw, fp1 + fp2


def _hdrp_pixel(src, prev, mv_tex, depth, px, py, frame, high):
    size = (W, H)
    uv = ((px + 0.5) / W, (py + 0.5) / H)
    quad = (float(px & 1) * 2.0 - 1.0, float(py & 1) * 2.0 - 1.0)  # GetQuadOffset

    def load_depth(i, j):  # out-of-bounds loads read 0 (reversed Z: the far plane)
        return depth[j, i] if 0 <= i < W and 0 <= j < H else math.inf

    # GetClosestFragmentOffset (COMPARE_DEPTH(a, b) = step(b, a) on reversed Z)
    q = (int(quad[0]), int(quad[1]))
    closest = (0, 0, load_depth(px, py))
    for o in ((-q[0], -q[1]), q, (q[0], -q[1]), (-q[0], q[1])):
        s = load_depth(px + o[0], py + o[1])
        if s <= closest[2]:  # nearer or equal in view depth
            closest = (o[0], o[1], s)
    mx = min(max(px + closest[0], 0), W - 1)
    my = min(max(py + closest[1], 0), H - 1)
    motion = (-mv_tex[my, mx, 0] / W, -mv_tex[my, mx, 1] / H)  # uv: current - previous
    prev_uv = (uv[0] - motion[0], uv[1] - motion[1])
    history = _hd_bicubic(prev, prev_uv)
    history = _ycocg(np.clip(history, 0, 65472.0))
    off_screen = any(abs(prev_uv[k] * 2 - 1) >= (1.0 - 1.0 / size[k]) for k in range(2))
    history = history * (1.0 / (history[0] + 1.0))

    def central_of(i, j):  # the colour a pixel (or its quad partner) computes for itself
        return _ycocg(np.clip(_hd_fetch(src, ((i + 0.5) / W, (j + 0.5) / H)), 0, 65472.0))

    color = central_of(px, py)
    nb = [
        _ycocg(_hd_fetch(src, (uv[0], uv[1] + quad[1] / H))),
        _ycocg(_hd_fetch(src, (uv[0] + quad[0] / W, uv[1]))),
        central_of(px - q[0], py),
        central_of(px, py - q[1]),
    ]
    if high:
        for o in ((-q[0], q[1]), (q[0], -q[1]), q, (-q[0], -q[1])):
            nb.append(_ycocg(_hd_fetch(src, (uv[0] + o[0] / W, uv[1] + o[1] / H))))
    nb = [n * (1.0 / (n[0] + 1.0)) for n in nb]
    central = color * (1.0 / (color[0] + 1.0))
    filtered = central
    if high:
        raw, fp = _hd_high_weights(frame, px, py)
        filtered = central * (raw[0] / sum(raw)) + sum(n * k for n, k in zip(nb, fp, strict=True))
    if off_screen:
        history = filtered
    color_luma, history_luma = filtered[0], history[0]
    m1 = sum(nb)
    m2 = sum(n * n for n in nb)
    avg = m1 / len(nb)
    m1 = (m1 + central) / (len(nb) + 1)
    m2 = (m2 + central * central) / (len(nb) + 1)
    std = np.sqrt(np.abs(m2 - m1 * m1))
    contrast = min(max(abs(color_luma - history_luma) / max(0.2, color_luma, history_luma), 0), 1)
    anti_flicker = 1.75  # lerp(0, 3.5, 0.5)
    if high:
        mv_px = math.hypot(*motion) * math.hypot(W, H)
        anti_flicker = anti_flicker * 0.8 + (anti_flicker * 2.25 - anti_flicker * 0.8) * min(
            max(1.0 - 2.0 * mv_px, 0.0), 1.0
        )
    t = min(max((contrast - 0.05) / (0.475 - 0.05), 0.0), 1.0)
    mult = 1.5 + anti_flicker * t * t * (3 - 2 * t)
    lo, hi = m1 - std * mult, m1 + std * mult
    # DirectClipToAABB
    center, extents = 0.5 * (hi + lo), 0.5 * (hi - lo)
    offset = history - center
    units = [abs(offset[k] / extents[k]) if extents[k] != 0 else math.inf for k in range(3)]
    units = [u for u, o, e in zip(units, offset, extents, strict=True) if not (o == 0 and e == 0)]
    max_unit = max(units) if units else 0.0
    if max_unit > 1.0:
        history = center + offset / max_unit
    # SharpenColor, strength 0.5
    lin_c = _rgb(filtered * (1.0 / (1.0 - filtered[0])))
    lin_a = _rgb(avg * (1.0 / (1.0 - avg[0])))
    lin_c = np.clip(lin_c + np.maximum(0, lin_c - lin_a) * 0.5 * 3, 0, 65472.0)
    sharpened = _ycocg(lin_c)
    filtered = sharpened * (1.0 / (sharpened[0] + 1.0))
    luma_contrast = max(hi[0] - lo[0], 0) / history_luma if history_luma else math.inf
    blend = max(min(max(0.125 * (1.0 / (1.0 + luma_contrast)), 0.0), 1.0), 0.03)
    final = history + blend * (filtered - history)
    final = final * (1.0 / (1.0 - final[0]))
    return np.clip(_rgb(final), 0, 65472.0), blend, off_screen


def _hdrp_transcription(samples, history, mv, depth, frame, high):
    src = _r11g11b10(samples)
    prev = src if history is None else history
    out = np.zeros((H, W, 3))
    blend = np.zeros((H, W))
    off = np.zeros((H, W), bool)
    for py in range(H):
        for px in range(W):
            out[py, px], blend[py, px], off[py, px] = _hdrp_pixel(
                src, prev, mv, depth, px, py, frame, high
            )
    return _r11g11b10(out), blend, off


@pytest.mark.parametrize("quality", ["medium", "high"])
@pytest.mark.parametrize("frame", [0, 6])
def test_hdrp_resolve_is_the_shaders_on_a_hand_built_frame(frame, quality):
    samples, mv, depth = _frame(5)
    history = None
    if frame:
        history = _r11g11b10(np.random.default_rng(6).random((H, W, 3)) * 2.0)
    else:
        mv = np.zeros_like(mv)
    # a jittered frame (the central filter's weights depend on the jitter's sign and the
    # diagonals' order) with an HDR highlight
    assert np.abs(hdrp.jitter_unity(frame)).min() > 0.1 and samples.max() > 4.0
    out, blend, _, off = hdrp.step(history, samples, frame, mv, depth, quality)
    expect, t_blend, t_off = _hdrp_transcription(
        samples, history, mv, depth, frame, quality == "high"
    )
    assert np.array_equal(off, t_off)
    if not frame:  # no motion: the outer ring of pixel centres reads as off screen
        assert off[0].all() and off[-1].all() and off[:, 0].all() and not off[1:-1, 1:-1].any()
    assert np.max(np.abs(out - expect)) <= TOL
    assert np.max(np.abs(blend - t_blend)) <= TOL
    assert blend.min() >= 0.03


def test_hdrp_jitter_cycles_eight_halton_points_from_index_two():
    # the first frame's taaFrameIndex is already 1: Halton(2) = (1/4, 2/3), y up
    np.testing.assert_allclose(hdrp.jitter(0), [-0.25, -(2 / 3 - 0.5)], atol=1e-15)
    np.testing.assert_allclose(hdrp.jitter(7), [0.0, -(1 / 3 - 0.5)], atol=1e-15)
    np.testing.assert_allclose(hdrp.jitter(8), hdrp.jitter(0), atol=0)


# ------------------------------------------------------------ UE4 4.18/4.19/4.20


def _ue_catmull_rom(x):
    ax = abs(x)
    if ax > 1.0:
        return ((-0.5 * ax + 2.5) * ax - 4.0) * ax + 2.0
    return (1.5 * ax - 2.5) * ax * ax + 1.0


def _ue_halton(index, base):  # TemporalHalton / Halton in SceneVisibility
    result, fraction, i = 0.0, 1.0 / base, index
    while i > 0:
        result += (i % base) * fraction
        i //= base
        fraction /= base
    return result


def _ue_bicubic(tex, uv):
    """Common.ush Texture2DSampleBicubic (D3D layout: row 0 at the top), bilinear clamp."""
    size = np.array([W, H], dtype=np.float64)
    p = np.array(uv) * size
    tc = np.floor(p - 0.5) + 0.5
    f = p - tc
    f2, f3 = f * f, f * f * f
    w0 = f2 - 0.5 * (f3 + f)
    w1 = 1.5 * f3 - 2.5 * f2 + 1
    w3 = 0.5 * (f3 - f2)
    w2 = 1 - w0 - w1 - w3
    weight = [w0, w1 + w2, w3]
    sample = [(tc - 1) / size, (tc + w2 / weight[1]) / size, (tc + 2) / size]
    taps = [(1, 0), (0, 1), (1, 1), (2, 1), (1, 2)]
    out = sum(
        _tex2d(tex, sample[i][0], sample[j][1]) * weight[i][0] * weight[j][1] for i, j in taps
    )
    return out / sum(weight[i][0] * weight[j][1] for i, j in taps)


def _ue4_pixel(src, hist, velocity_tex, depth_tex, px, py, frame, camera_prev, version, cut):
    def rgb_to_ycocg(c):
        return np.array([c[0] + 2 * c[1] + c[2], 2 * c[0] - 2 * c[2], -c[0] + 2 * c[1] - c[2]])

    def point(tex, i, j):  # SampleLevel with a point clamp sampler at integer offsets
        return tex[min(max(py + j, 0), H - 1), min(max(px + i, 0), W - 1)]

    # ScreenPos: NDC of the pixel centre, y up
    screen = np.array([(px + 0.5) / W * 2 - 1, 1 - (py + 0.5) / H * 2])
    index = (frame + 1) % 8  # OnFrameRenderingSetup increments first
    u1, u2 = _ue_halton(index + 1, 2), _ue_halton(index + 1, 3)
    sigma = 0.47
    in_window = math.exp(-0.5 * (0.5 / sigma) ** 2)
    r = sigma * math.sqrt(-2.0 * math.log((1.0 - u1) * in_window + u1))
    jitter = (r * math.cos(2 * math.pi * u2), r * math.sin(2 * math.pi * u2))
    # device depth stand-in: larger = nearer (inverted Z)
    device = -depth_tex
    pos_z = point(device, 0, 0)
    depths = [
        point(device, -2, -2),
        point(device, 2, -2),
        point(device, -2, 2),
        point(device, 2, 2),
    ]
    depth_offset = [2.0, 2.0]
    xx = 2.0
    if depths[0] > depths[1]:
        xx = -2.0
    if depths[2] > depths[3]:
        depth_offset[0] = -2.0
    dxy, dzw = max(depths[0], depths[1]), max(depths[2], depths[3])
    if dxy > dzw:
        depth_offset[1] = -2.0
        depth_offset[0] = xx
    velocity_offset = (0, 0)
    if max(dxy, dzw) > pos_z:
        velocity_offset = (int(depth_offset[0]), int(depth_offset[1]))
        pos_z = max(dxy, dzw)
    cam = camera_prev(-pos_z, px, py)  # the centre's point at that depth, previous frame
    back_n = screen - np.array([cam[0] / W * 2 - 1, 1 - cam[1] / H * 2])
    vel_n = point(velocity_tex, *velocity_offset)
    if vel_n[0] > 0.0:  # DynamicN
        back_n = vel_n[1:]
    back_temp = back_n * np.array([W, H])
    velocity = math.sqrt(back_temp @ back_temp)
    back_n = screen - back_n
    off_screen = max(abs(back_n[0]), abs(back_n[1])) >= 1.0
    back_n = np.clip(back_n, [-1 + 1.0 / W, -1 + 1.0 / H], [1 - 1.0 / W, 1 - 1.0 / H])
    history_uv = ((back_n[0] + 1) / 2, (1 - back_n[1]) / 2)
    offsets = [(-1, -1), (0, -1), (1, -1), (-1, 0), (0, 0), (1, 0), (-1, 1), (0, 1), (1, 1)]
    neighbors = [rgb_to_ycocg(point(src, *o)) for o in offsets]
    if version in ("4.18", "4.20"):  # r.TemporalAACatmullRom 0: normal distribution
        raw = [
            math.exp(-2.29 * ((o[0] - jitter[0]) ** 2 + (o[1] - jitter[1]) ** 2)) for o in offsets
        ]
    else:
        raw = [
            _ue_catmull_rom(o[0] - jitter[0]) * _ue_catmull_rom(o[1] - jitter[1]) for o in offsets
        ]
    plus_idx = [1, 3, 4, 5, 7]
    plus_w = [raw[i] / sum(raw[k] for k in plus_idx) for i in plus_idx]
    tone = version != "4.19-high"  # MainFastTemporalAA: AA_TONE 0, AA_DYNAMIC_ANTIGHOST 0
    filtered, total = np.zeros(3), 0.0
    for i, wgt in zip(plus_idx, plus_w, strict=True):
        sw = wgt * (1.0 / (neighbors[i][0] + 4.0)) if tone else wgt
        total += sw
        filtered = filtered + neighbors[i] * sw
    if tone:
        filtered = filtered / total
    test = np.abs(screen) + np.array([2.0 / W, 2.0 / H])
    if max(test) >= 1.0:
        filtered = neighbors[4]
    nmin = np.min([neighbors[i] for i in plus_idx], axis=0)
    nmax = np.max([neighbors[i] for i in plus_idx], axis=0)
    hc = _ue_bicubic(hist, history_uv)
    history_color, history_a = rgb_to_ycocg(hc[:3]), hc[3]
    dynamic = any(
        point(velocity_tex, *o)[0] > 0 for o in [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)]
    )
    ghost = not dynamic and history_a > 0 and tone
    ignore = off_screen  # 4.20.3: IgnoreHistory = OffScreen || TAA_CAMERA_CUT || anti-ghost
    if version == "4.20":
        ignore = off_screen or cut or ghost
    elif ghost:  # 4.18/4.19: HistoryColor = Filtered before the luma and the clamp
        history_color = filtered
    luma_min, luma_max, luma_history = nmin[0], nmax[0], history_color[0]
    history_color = np.clip(history_color, nmin, nmax)

    def saturate_div(a, b):
        if b == 0:
            return 1.0 if a > 0 else 0.0
        return min(max(a / b, 0.0), 1.0)

    blend = 0.04 + (0.2 - 0.04) * min(max(velocity / 40, 0.0), 1.0)
    if version in ("4.19", "4.19-high"):  # the anti-flicker block (#if 0 in 4.18.3, 4.20.3)
        blend += 0.8 * saturate_div(0.02 * luma_history, abs(filtered[0] - luma_history))
        blend *= (luma_min + 0.5) / (luma_max + 0.5)
    blend = max(blend, saturate_div(0.01 * luma_history, abs(filtered[0] - luma_history)))
    if cut:  # BlendFinal = 1.0 under TAA_CAMERA_CUT
        blend = 1.0
    if ignore:
        history_color = filtered
    blend_a = (1.0 - blend) * (1.0 / (history_color[0] + 4.0))
    blend_b = blend * (1.0 / (filtered[0] + 4.0))
    rcp = 1.0 / (blend_a + blend_b)
    out = history_color * (blend_a * rcp) + filtered * (blend_b * rcp)
    y, co, cg = out * 0.25
    rgb = np.maximum(np.array([y + co - cg, y + cg, y - co - cg]), 0.0)
    alpha = 1.0 if point(velocity_tex, 0, 0)[0] > 0 and tone else 0.0
    return np.append(rgb, alpha), blend, ignore or ghost


def _camera(z, px, py):
    """A hand-built camera reprojection: a pan plus a depth-dependent parallax."""
    return (px + 0.5 + 0.7 - 1.2 / z, py + 0.5 - 0.4 + 0.9 / z)


def _ue4_transcription(samples, history, mv, depth, dynamic, frame, version):
    src = samples.astype(np.float16).astype(np.float64)
    cut = history is None and version == "4.20"  # 4.20: no history is a camera cut
    if history is None:
        history = np.concatenate([src, np.zeros((H, W, 1))], -1)
    # the velocity buffer: x > 0 flags a dynamic object (encoded), then BackN in ScreenPos
    vel = np.zeros((H, W, 3))
    vel[..., 0] = dynamic
    vel[..., 1] = -2.0 * mv[..., 0] / W
    vel[..., 2] = 2.0 * mv[..., 1] / H
    out = np.zeros((H, W, 4))
    blend = np.zeros((H, W))
    dropped = np.zeros((H, W), bool)
    for py in range(H):
        for px in range(W):
            out[py, px], blend[py, px], dropped[py, px] = _ue4_pixel(
                src, history, vel, depth, px, py, frame, _camera, version, cut
            )
    return out.astype(np.float16).astype(np.float64), blend, dropped


@pytest.mark.parametrize("version", ["4.19", "4.19-high", "4.18", "4.20"])
@pytest.mark.parametrize("frame", [0, 4])
def test_ue4_resolve_is_the_shaders_on_a_hand_built_frame(frame, version):
    samples, mv, depth = _frame(7)
    rng = np.random.default_rng(8)
    dynamic = rng.random((H, W)) < 0.3
    depth = depth.copy()
    depth[0, 0] = np.inf  # sky
    history = None
    if frame:
        history = np.concatenate([rng.random((H, W, 3)) * 2.0, (rng.random((H, W, 1)) < 0.4)], -1)
        history = history.astype(np.float16).astype(np.float64)

    def camera_prev(z):
        yy, xx = np.mgrid[0:H, 0:W]
        return _camera(z, xx, yy)

    out, blend, _, discarded = ue4.step(
        history, samples, frame, mv, depth, dynamic, camera_prev, version
    )
    expect, t_blend, t_dropped = _ue4_transcription(
        samples, history, mv, depth, dynamic, frame, version
    )
    assert np.array_equal(discarded, t_dropped)
    assert np.max(np.abs(out - expect)) <= TOL
    assert np.max(np.abs(blend - t_blend)) <= TOL


def test_ue4_jitter_is_the_windowed_gaussian_from_sample_index_one():
    s = ue4.sample_xy(0)  # index 1: Halton(2) = (0.25, 2/3)
    r = 0.47 * math.sqrt(-2 * math.log(0.75 * math.exp(-0.5 * (0.5 / 0.47) ** 2) + 0.25))
    np.testing.assert_allclose(s, [r * math.cos(4 * math.pi / 3), r * math.sin(4 * math.pi / 3)])
    np.testing.assert_allclose(ue4.jitter(0), -s)
    np.testing.assert_allclose(ue4.sample_xy(8), s, atol=0)
    assert ue4.plus_weights(3).sum() == pytest.approx(1.0, abs=1e-15)


# ------------------------------------------------------------------ HDR as shipped

#: The hdr-edge scene with its sun raised to 20 (strip radiance 0.9 * 20 * 0.98 / pi = 5.6).
HDR_IRRADIANCE = 20.0


def _bright_hdr_edge():
    spec = scenes.BUILTIN_SCENES["hdr-edge"]

    def factory(width, height):
        scene = spec.factory(width, height)
        scene["sun"]["irradiance"]["value"] = [HDR_IRRADIANCE] * 3
        return scene

    return dataclasses.replace(spec, name="hdr-edge-bright", factory=factory)


def test_hdr_scene_inside_clips_at_one_and_the_tone_weighted_engines_keep_the_peaks():
    s = scenes.load(_bright_hdr_edge(), width=48, height=27, camera_path="static", n_frames=6)
    current = raster_models.run("noaa", s).outputs["color"]
    peak = float(current.max())
    assert peak > 4.0  # an HDR scene
    bright = current.max(axis=-1) > 4.0
    pad = np.pad(bright, 1)
    interior = np.logical_and.reduce(
        [
            pad[1 + dy : 1 + dy + bright.shape[0], 1 + dx : 1 + dx + bright.shape[1]]
            for dy in (-1, 0, 1)
            for dx in (-1, 0, 1)
        ]
    )
    assert interior.sum() >= 10
    out = {
        p: raster_models.run("taa", s.with_frame(5), preset=p).outputs["color"]
        for p in ("inside", "filament", "hdrp", "ue4")
    }
    # INSIDE: saturate() before the 8-bit history, so the strips read 1 at most
    assert out["inside"].max() <= 1.0
    assert np.all(np.abs(out["inside"][interior] - 1.0) < 1e-6)
    for p in ("filament", "hdrp", "ue4"):
        o = out[p]
        assert np.isfinite(o).all() and o.min() >= 0
        # the tone weighting is undone at the end: a still camera keeps the radiance of
        # the strips' interiors (within the buffers' rounding and the filters' reach)
        assert o.max() > 4.0
        assert np.min(o[interior].max(axis=-1)) > 0.95 * peak


def test_camera_reprojection_of_filament_and_ue4_is_the_film_motion_of_still_geometry():
    from raster_oracle.scenes.geometry.motion import film_motion

    s = scenes.load("star", width=48, height=27, camera_path="subpixel-pan", n_frames=4)
    frame = s.with_frame(2)
    fil = raster_models.run("taa", frame, preset="filament")
    y, x = np.mgrid[0:27, 0:48].astype(np.float64) + 0.5
    m = film_motion(frame, x, y, disocclusion=False)
    truth_x = m["motion_x"].reshape(27, 48)
    truth_y = m["motion_y"].reshape(27, 48)
    # the camera pans over still geometry: where the pixel centre and its jittered sample see
    # the same flat surface at the same depth, Filament's depth + camera reprojection is the
    # centre's film motion
    depth = m["depth"].reshape(27, 48)
    flat = np.abs(np.diff(depth, axis=1, prepend=depth[:, :1])) < 1e-6
    flat &= np.abs(np.diff(depth, axis=0, prepend=depth[:1])) < 1e-6
    assert flat.sum() > 100 and np.abs(truth_x).max() > 0.01
    np.testing.assert_allclose(fil.outputs["velocity_x"][flat], truth_x[flat], atol=1e-4)
    np.testing.assert_allclose(fil.outputs["velocity_y"][flat], truth_y[flat], atol=1e-4)
    ue = raster_models.run("taa", frame, preset="ue4")
    np.testing.assert_allclose(ue.outputs["velocity_x"][flat], truth_x[flat], atol=1e-4)
