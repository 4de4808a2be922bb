"""SMAA (issue 27): published texture bytes, closed-form areas of step edges, identities,
energy, presets and modes, and the ranking on ``star`` against no AA."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.raster_models import ModelError, parse_params
from raster_oracle.raster_models import run as run_model
from raster_oracle.raster_models.aa.smaa import PRESETS, textures
from raster_oracle.raster_models.aa.smaa.blending import neighborhood_blend, resolve
from raster_oracle.raster_models.aa.smaa.edges import detect_edges
from raster_oracle.raster_models.aa.smaa.model import color_buffer, smaa_1x
from raster_oracle.raster_models.aa.smaa.params import MODES, SmaaParams, resolved
from raster_oracle.raster_models.aa.smaa.weights import blending_weights
from raster_oracle.raster_models.aa.trace import sample_colors
from raster_oracle.scenes.base.display import (
    exposure_from_reference,
    srgb_decode,
    srgb_encode,
    tonemap,
)

from raster_oracle import scenes

# bilinear weights of the area texture lookups: 8 fractional bits (the model's hardware rule)
SUBTEXEL = 256.0
# a finite line's two cut ends: at most 3% of its energy (measured 1.3-2.6% for k = 2, 4, 8;
# corner rounding, which SMAA applies to one side of each corner, is off here)
LINE_END_LOSS = 0.03
# float32 blends of float32 inputs: a few ulps of values in [0, 1]
FLOAT32_ATOL = 1e-6


def _smaa(img, **kw):
    """Edges, weights and blend of a display image with SMAA's default settings."""
    e = detect_edges(img, threshold=kw.pop("threshold", 0.1))
    w = blending_weights(e, **kw)
    return e, w, neighborhood_blend(img, w, srgb=False)


def test_textures_equal_the_published_bytes():
    area, search = textures.area_texture(), textures.search_texture()
    assert area.shape == (560, 160, 2) and area.dtype == np.uint8
    assert search.shape == (16, 64) and search.dtype == np.uint8
    assert hashlib.sha256(area.tobytes()).hexdigest() == textures.AREA_SHA256
    assert hashlib.sha256(search.tobytes()).hexdigest() == textures.SEARCH_SHA256
    assert textures.AREA_SHA256.startswith("35065cef2a02")
    assert textures.SEARCH_SHA256.startswith("3694eae5e9d4")


def _z_area_by_hand(left: float, right: float) -> tuple[float, float]:
    """Areas (R, G) of pixel ``left`` of a Z step of ``d = left + right + 1`` pixels: the
    revectorised line runs from +0.5 above the edge at its left end to -0.5 at its right
    end; a pixel wholly on one side gets its trapezoid, the middle pixel of an odd ``d``
    two triangles of 1 / (8 d) each."""
    d = left + right + 1.0
    y1, y2 = 0.5 - left / d, 0.5 - (left + 1.0) / d
    if y1 * y2 >= 0.0:
        a = (y1 + y2) / 2.0
        return (-a, 0.0) if a < 0.0 else (0.0, a)
    return (1.0 / (8.0 * d), 1.0 / (8.0 * d))


def _lookup_by_hand(left: int, right: int) -> np.ndarray:
    """The weight SMAA reads for distances (``left``, ``right``): the texture stores the hand
    areas at squared distances as ``int(255 a)``, looked up bilinearly at the square roots."""
    sl, sr = np.sqrt(left), np.sqrt(right)
    out = np.zeros(2)
    for i in (np.floor(sl), np.floor(sl) + 1.0):
        for j in (np.floor(sr), np.floor(sr) + 1.0):
            wx = np.round((1.0 - abs(sl - i)) * SUBTEXEL) / SUBTEXEL
            wy = np.round((1.0 - abs(sr - j)) * SUBTEXEL) / SUBTEXEL
            out += wx * wy * np.trunc(255.0 * np.array(_z_area_by_hand(i * i, j * j))) / 255.0
    return np.round(out * 255.0) / 255.0


@pytest.mark.parametrize("k", [1, 2, 4, 8])
def test_step_edge_of_slope_1_over_k_gets_the_hand_areas(k):
    h, w = 24, 8 * k + 16
    y, x = np.mgrid[0:h, 0:w]
    img = np.repeat(np.where(y < x // k + 4, 1.0, 0.0).astype(np.float32)[..., None], 3, -1)
    _, wts, _ = _smaa(img, max_search_steps=16, max_search_steps_diag=None, corner_rounding=None)
    seg = 3  # the fourth step: row 7, columns 3k .. 4k - 1, its top edge horizontal
    got = wts[seg + 4, seg * k : seg * k + k, :2]
    want = np.array([_lookup_by_hand(i, k - 1 - i) for i in range(k)])
    np.testing.assert_array_equal(got, want.astype(np.float32))
    # the texels hit exactly: k = 1 two triangles of 1/8, k = 2 trapezoids of 1/4
    bytes_ = (got * 255).round().tolist()
    if k == 1:
        assert bytes_ == [[31, 31]]  # int(255 / 8)
    if k == 2:
        assert bytes_ == [[0, 63], [63, 0]]  # int(255 / 4)


@pytest.mark.parametrize("sub", range(7))
def test_subsample_index_reads_its_band_of_the_construction(sub):
    # a slope-1/2 step: distances (0, 1) and (1, 0), texels hit exactly; the step is the Z
    # pattern 6 (crossing edges up at its left end, down at its right), built for the
    # sub-sample offset of band `sub` (T2x: 1, 2; 4x: 3..6)
    y, x = np.mgrid[0:24, 0:32]
    img = np.repeat(np.where(y < x // 2 + 4, 1.0, 0.0).astype(np.float32)[..., None], 3, -1)
    e = detect_edges(img, threshold=0.1)
    w = blending_weights(
        e, max_search_steps_diag=None, corner_rounding=None, subsample_indices=(0, sub, 0, 0)
    )
    offset = textures.SUBSAMPLE_OFFSETS_ORTHO[sub]
    want = [np.trunc(255.0 * np.ravel(textures.area_ortho(6, s, 1 - s, offset))) for s in (0, 1)]
    np.testing.assert_array_equal((w[7, 6:8, :2] * 255.0).round(), want)


def test_local_contrast_adaptation_drops_an_edge_beside_a_stronger_one():
    # columns 0.0 | 0.12 | x: the 0.12 step passes the 0.1 threshold; it is dropped when the
    # next step is more than twice as strong (|0.12 - 1| > 2 x 0.12), kept when it is not
    for right, kept in ((1.0, False), (0.24, True)):
        img = np.zeros((4, 6, 3), np.float32)
        img[:, 2] = 0.12
        img[:, 3:] = right
        e = detect_edges(img, threshold=0.1)
        assert bool(e[1, 2, 0]) is kept
        assert e[1, 3, 0] == 1.0  # the second step is an edge either way (0.88 or 0.12)


def test_colour_edges_see_chroma_that_luma_does_not():
    # red 0.7152 and green 0.2126 have one Rec. 709 luma (0.7152 x 0.2126)
    img = np.zeros((4, 6, 3), np.float32)
    img[:, :3, 0] = 0.7152
    img[:, 3:, 1] = 0.2126
    assert not detect_edges(img, method="luma").any()
    assert detect_edges(img, method="color")[:, 3, 0].all()


def test_depth_edges_and_predication():
    depth = np.full((4, 6), 0.5, np.float32)
    depth[:, 3:] = 0.52  # a 0.02 step: above the depth threshold 0.1 x 0.1
    assert detect_edges(None, method="depth", depth=depth)[:, 3, 0].all()
    # a 0.15 luma step: predication doubles the threshold (0.2: no edge) and lowers it by 40 %
    # where the depth buffer has an edge (0.12: edge)
    img = np.zeros((4, 6, 3), np.float32)
    img[:, 3:] = 0.15
    pred = {"threshold": 0.01, "scale": 2.0, "strength": 0.4}
    flat = np.full((4, 6), 0.5, np.float32)
    assert detect_edges(img, threshold=0.1)[:, 3, 0].all()
    assert not detect_edges(img, threshold=0.1, depth=flat, predication=pred).any()
    assert detect_edges(img, threshold=0.1, depth=depth, predication=pred)[:, 3, 0].all()


def test_constant_and_low_contrast_images_pass_unchanged():
    rng = np.random.default_rng(7)
    const = np.full((20, 30, 3), 0.37, np.float32)
    _, w, out = _smaa(const)
    assert not w.any() and out["color"].tobytes() == const.tobytes()
    # every neighbour difference below the 0.1 luma threshold: no edge anywhere
    soft = (0.5 + 0.04 * rng.random((20, 30, 3))).astype(np.float32)
    e, w, out = _smaa(soft)
    assert not e.any() and out["color"].tobytes() == soft.tobytes()


@pytest.mark.parametrize("k", [2, 4, 8])
@pytest.mark.parametrize("diag", [None, 8])
def test_one_pixel_line_keeps_its_energy(k, diag):
    # every step of the line's two edges is a Z pattern whose two halves move the same area
    # in and out; only the line's two ends (where the last step is cut) change the sum
    y, x = np.mgrid[0:40, 0:64]
    img = np.zeros((40, 64, 3), np.float32)
    img[(y == x // k + 8) & (x > 4) & (x < 60)] = 1.0
    _, w, out = _smaa(img, max_search_steps=16, max_search_steps_diag=diag, corner_rounding=None)
    assert w.any() and not np.array_equal(out["color"], img)
    assert out["color"].sum() == pytest.approx(img.sum(), rel=LINE_END_LOSS)


def test_presets_and_overrides():
    assert PRESETS["low"]["corner_rounding"] == 100 and PRESETS["low"]["max_search_steps"] == 4
    assert resolved(SmaaParams(preset="ultra"))["threshold"] == 0.05
    cfg = resolved(SmaaParams(preset="high", threshold=0.2, max_search_steps_diag=0))
    assert cfg["threshold"] == 0.2 and cfg["max_search_steps_diag"] == 0
    assert cfg["depth_threshold"] == pytest.approx(0.02)
    assert parse_params("smaa", ["preset=medium", "mode=4x"]) == {"preset": "medium", "mode": "4x"}
    with pytest.raises(ModelError, match="preset"):
        parse_params("smaa", ["preset=extreme"])


def test_static_resolve_is_the_average():
    rng = np.random.default_rng(1)
    a, b = rng.random((2, 6, 5, 3)).astype(np.float32)
    zero = np.zeros((6, 5), np.float32)
    out = resolve(a, b, alpha_current=zero, alpha_previous=zero)
    np.testing.assert_allclose(out, (a + b) / 2, atol=FLOAT32_ATOL)
    # different velocities weight the previous frame down (scale 30): 0.5 * (1 - 30 x)
    ap = np.full((6, 5), 0.1, np.float32)
    out = resolve(a, b, alpha_current=zero, alpha_previous=ap)
    weight = 0.5 * max(0.0, 1.0 - np.sqrt(0.01 / 5.0) * 30.0)
    np.testing.assert_allclose(out, a + (b - a) * weight, atol=FLOAT32_ATOL)


def test_resolve_reprojects_with_the_velocity():
    # a velocity of one pixel to the right (texture units): the previous frame is fetched
    # one pixel to the left; equal packed velocities keep the weight at 0.5
    rng = np.random.default_rng(2)
    a, b = rng.random((2, 4, 6, 3)).astype(np.float32)
    alpha = np.zeros((4, 6), np.float32)
    vel = np.zeros((4, 6, 2))
    vel[..., 0] = 1.0 / 6
    out = resolve(a, b, alpha_current=alpha, alpha_previous=alpha, velocity=vel)
    shifted = b[:, np.maximum(np.arange(6) - 1, 0)]
    np.testing.assert_allclose(out, a + (shifted - a) * 0.5, atol=FLOAT32_ATOL)


@pytest.mark.parametrize("source", ["rgba8-srgb", "float"])
def test_t2x_on_a_static_camera_is_the_average_of_its_two_smaa_frames(source):
    # 8-bit input (the default): each frame written to an RGBA8 sRGB target and the two
    # averaged in linear light through the sRGB views, rounded to 1/255; float input: the
    # frames averaged as stored (gamma)
    scene = scenes.load("star", width=48, height=27)
    res = run_model("smaa", scene, mode="t2x", input=source)
    frames = []
    for offset in ((0.75, 0.75), (0.25, 0.25)):
        col, _ = sample_colors(scene, np.array([offset]))
        frames.append(col["color"].reshape(27, 48, 3))
    exposure = exposure_from_reference((frames[0] + frames[1]) / 2)
    cfg = resolved(SmaaParams(input=source))
    out = [
        smaa_1x(color_buffer(tonemap(f, exposure=exposure), cfg), cfg, idx)["color"]
        for f, idx in zip(frames, ((1, 1, 1, 0), (2, 2, 2, 0)), strict=True)
    ]
    # frame 0 is the demo's S0 (jitter (0.25, -0.25) y up, indices (1, 1, 1, 0)); the still
    # scene's previous frame is S1
    if source == "float":
        want = out[0] + (out[1] - out[0]) * np.float32(0.5)
    else:
        assert np.array_equal(np.round(out[0] * 255) / 255, out[0])  # an RGBA8 target
        cur, prev = srgb_decode(out[0]), srgb_decode(out[1])
        want = srgb_encode(cur + (prev - cur) * np.float32(0.5))
        want = np.round(np.clip(want.astype(np.float64), 0, 1) * 255) / 255
    np.testing.assert_allclose(res.outputs["color_display"], want, atol=FLOAT32_ATOL)
    assert not np.array_equal(out[0], out[1])  # the jittered frames differ
    assert res.diagnostics["current_frame_set"] == 0


def test_t2x_frame_0_is_the_demos_first_jitter():
    # the header's S0, jitter (0.25, -0.25) with y up, is (0.5 + 0.25, 0.5 + 0.25) from the
    # pixel's upper-left corner with y down; the demo renders it first (frameIndex 0)
    jx, jy = 0.25, -0.25
    assert T2X_DEMO[0] == ((0.5 + jx, 0.5 - jy), (1, 1, 1, 0))
    assert [tuple(map(tuple, f[0])) for f in MODES["t2x"]] == [tuple(f) for f in T2X_DEMO]
    for k in (0, 1, 2, 3):
        scene = scenes.load("star", width=16, height=9).with_frame(k, n_frames=4)
        res = run_model("smaa", scene, mode="t2x")
        assert res.diagnostics["current_frame_set"] == k % 2
        assert res.diagnostics["sample_positions"][k % 2] == [list(T2X_DEMO[k % 2][0])]


def _score(tmp_path, name, args):
    size = ["--width", "160", "--height", "90", "--spp", "16", "--quiet"]
    out = tmp_path / name
    assert main(["score", "star", *size, "--technique", *args, "--out", str(out)]) == 0
    return json.loads((out / "metrics.json").read_text())


@pytest.mark.slow
def test_every_preset_beats_no_aa_on_star(tmp_path):
    base = _score(tmp_path, "noaa", ["noaa"])
    for preset in ("low", "medium", "high", "ultra"):
        m = _score(tmp_path, preset, ["smaa", "--set", f"preset={preset}"])
        assert m["flip_mean"] < base["flip_mean"], preset
        assert m["coverage_edge_rmse"] < base["coverage_edge_rmse"], preset


def test_modes_run_and_report_costs(tmp_path):
    out = tmp_path / "m"
    assert main(["model", "smaa", "star", "--width", "48", "--height", "27", "--set", "mode=4x",
                 "--out", str(out)]) == 0  # fmt: skip
    rec = json.loads((out / "model.json").read_text())
    cost = rec["cost"]
    assert cost["samples"] == 2 and cost["smaa_passes"] == 8
    assert cost["framebuffer_bytes_by_buffer"]["smaa_edges"] == 48 * 27 * 2
    assert cost["framebuffer_bytes_by_buffer"]["smaa_weights"] == 48 * 27 * 4
    assert cost["framebuffer_bytes_by_buffer"]["smaa_velocity"] == 48 * 27 * 4  # RG16F
    assert cost["texture_fetches_per_pixel"] > 0
    assert "still scene" in rec["diagnostics"]["velocity"]


#: SMAA.hlsl @SUBSAMPLE_INDICES (iryoku/smaa 71c806a, lines 220-221) in the demo's order: S0
#: jitter (0.25, -0.25) y up = (0.75, 0.75) from the pixel's upper-left corner, then S1.
T2X_DEMO = (((0.75, 0.75), (1, 1, 1, 0)), ((0.25, 0.25), (2, 2, 2, 0)))


@pytest.mark.parametrize("k", [1, 2])
def test_t2x_on_a_moving_sequence_reprojects_the_previous_frame_by_its_velocity(k):
    # slide's frame k: the current frame (the demo's sub-sample set k mod 2: its frameIndex
    # starts at 0 and steps after each frame) and frame k - 1 (the other set), each SMAA 1x
    # on its 8-bit buffer with its own velocity buffer (current minus previous position,
    # texture units, RG16F), resolved with the previous frame fetched at texcoord - velocity
    from raster_oracle.scenes.geometry.motion import film_motion

    w, h = 48, 27
    scene = scenes.load("slide", width=w, height=h).with_frame(k, n_frames=8)
    res = run_model("smaa", scene, mode="t2x")
    assert "film motion" in res.diagnostics["velocity"]
    assert res.diagnostics["current_frame_set"] == k % 2
    cur, prev = T2X_DEMO[k % 2], T2X_DEMO[(k + 1) % 2]
    frames = [(scene.previous(), *prev), (scene, *cur)]
    cols, vels = [], []
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    for sc, off, _ in frames:
        col, _ = sample_colors(sc, np.array([off]))
        cols.append(col["color"].reshape(h, w, 3))
        m = film_motion(sc, x + off[0], y + off[1], disocclusion=False)
        v = -np.stack([m["motion_x"].reshape(h, w) / w, m["motion_y"].reshape(h, w) / h], -1)
        vels.append(v.astype(np.float16).astype(np.float64))
    assert np.abs(vels[1]).max() > 0.5 / w  # something moves by more than half a pixel
    exposure = exposure_from_reference((cols[0] + cols[1]) / 2)
    cfg = resolved(SmaaParams(mode="t2x"))
    outs = [
        smaa_1x(color_buffer(tonemap(c, exposure=exposure), cfg), cfg, idx, velocity=v)
        for c, (_, _, idx), v in zip(cols, frames, vels, strict=True)
    ]
    want = resolve(
        outs[1]["color"],
        outs[0]["color"],
        alpha_current=outs[1]["alpha"],
        alpha_previous=outs[0]["alpha"],
        velocity=vels[1],
        srgb=True,
        unorm8=True,
    )
    np.testing.assert_array_equal(res.outputs["color_display"], want)
    # the blending pass packed the velocity into alpha (sqrt(5 |v|), 8-bit)
    assert outs[1]["alpha"].max() > 0 and np.array_equal(
        np.round(outs[1]["alpha"] * 255) / 255, outs[1]["alpha"].astype(np.float64)
    )
