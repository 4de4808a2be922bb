"""Anti-aliasing models, closed-form checks: sample positions, exact MSAA coverage of an
analytic triangle, the straight-edge coverage floors, SSAA against the oracle, resolve
filters, cost records, bad parameters."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.reference.cache import ReferenceCache
from raster_oracle.oracle.reference.render import ReferenceSettings
from raster_oracle.oracle.reference.store import get_reference
from raster_oracle.oracle.scoring.score import COVERAGE_FLOOR_RMS
from raster_oracle.raster_models.aa import resolve, samples
from raster_oracle.scenes.catalogue.builtin import BuiltinScene
from raster_oracle.scenes.catalogue.factories import mesh, sensor, sun

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests._geometry import polygon_coverage

W, H = 48, 27
SMALL = {"width": W, "height": H}
#: float32 shading against float64 sums.
FLOAT_TOL = 1e-5
#: Sample positions closer than this (pixels) to a triangle edge would make the exact count
#: depend on float32 rounding of the ray (about 1e-5 px here) or on a rasterizer's tie rule;
#: the test triangle keeps every sample farther.
EDGE_CLEARANCE = 2e-4


@pytest.fixture(scope="module")
def star():
    return scenes.load("star", **SMALL)


def _triangle_scene(verts):
    def factory(width, height):
        v = np.asarray(verts, float)
        return {
            "type": "scene",
            "camera": sensor(
                width, height, origin=(0, 0, -10), target=(0, 0, 0), fov=40, near=0.1, far=100
            ),
            "sun": sun((0.2, -0.3, 1.0)),
            "tri": mesh((v, np.array([[0, 1, 2]], np.uint32)), 0.7),
        }

    return scenes.load(BuiltinScene("aa-triangle", factory, "one triangle"), **SMALL)


def test_standard_positions():
    for n in samples.STANDARD_COUNTS:
        p = samples.positions(n)
        assert p.shape == (n, 2) and (p >= 0).all() and (p < 1).all()
        assert len({tuple(q) for q in p}) == n
    # 4x: D3D's (-2,-6) (6,-2) (-6,2) (2,6) sixteenths from the centre, y down
    d3d = np.array([(-2, -6), (6, -2), (-6, 2), (2, 6)]) / 16 + 0.5
    assert np.array_equal(samples.positions(4), d3d)
    assert np.allclose(samples.positions(16).mean(axis=0), (0.46875, 0.46875))
    assert np.allclose(samples.positions(8).mean(axis=0), (0.5, 0.5))
    grid = samples.positions(6, "ordered-grid")
    assert sorted(map(tuple, grid)) == sorted(
        (x, y) for x in (1 / 6, 0.5, 5 / 6) for y in (0.25, 0.75)
    )
    with pytest.raises(rm.ModelError, match="standard pattern"):
        samples.positions(3)


@pytest.mark.parametrize("n", [1, 2, 4, 8, 16])
def test_msaa_coverage_is_the_exact_sample_count(n):
    """Coverage x N = sample positions inside the projected triangle (edge functions in
    float64), at every pixel."""
    verts = np.array([(-2.1, -1.3, 0.0), (2.45, -0.9, 0.0), (0.3, 1.7, 0.0)])
    scene = _triangle_scene(verts)
    film = scene.camera.project(verts)
    offs = samples.positions(n)
    yy, xx = np.mgrid[0:H, 0:W]
    sx = xx[..., None] + offs[:, 0]
    sy = yy[..., None] + offs[:, 1]
    inside = np.ones(sx.shape, bool)
    sign = None
    for i in range(3):
        (px, py), (qx, qy) = film[i], film[(i + 1) % 3]
        e = (qx - px) * (sy - py) - (qy - py) * (sx - px)
        dist = np.abs(e) / math.hypot(qx - px, qy - py)
        assert dist.min() > EDGE_CLEARANCE
        s = np.sign(e)
        sign = s if sign is None else sign
        inside &= s == sign
    expected = inside.sum(axis=2)
    r = rm.run("msaa", scene, samples=n)
    got = np.rint(r.outputs["coverage"] * n).astype(int)
    assert np.array_equal(got, expected)
    assert expected.sum() > 50 and ((expected > 0) & (expected < n)).sum() >= (n > 1) * 20
    # and the shaded colour is the triangle's colour weighted by the same count
    lit = r.outputs["color"][expected == n].mean(axis=0)
    assert np.allclose(r.outputs["color"], lit * (expected / n)[..., None], rtol=FLOAT_TOL)


#: Squares of the straight-edge test: side in world units, grid cell, count per row/column.
_SQUARE, _CELL, _COLS, _ROWS = 0.33, 0.45, 16, 9


def _squares(seed: int = 5):
    """Non-overlapping squares at uniformly random rotations and jittered grid positions:
    their edges are straight edges with uniform angles and offsets (the floor table's
    Crofton measure), each crossing several pixels."""
    rng = np.random.default_rng(seed)
    quads = []
    for i in range(_COLS):
        for j in range(_ROWS):
            cx = (i - (_COLS - 1) / 2) * _CELL + rng.uniform(-0.03, 0.03)
            cy = (j - (_ROWS - 1) / 2) * _CELL + rng.uniform(-0.03, 0.03)
            t = rng.uniform(0, math.pi / 2)
            c, s = math.cos(t), math.sin(t)
            h = _SQUARE / 2
            corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h]]) @ np.array([[c, s], [-s, c]])
            quads.append(np.column_stack([corners + (cx, cy), np.zeros(4)]))
    return quads


def _squares_scene(width, height):
    from raster_oracle.scenes.catalogue.aa_scenes import ortho_camera
    from raster_oracle.scenes.geometry import meshes

    squares = meshes.merge([meshes.quad(q) for q in _squares()])
    return {
        "type": "scene",
        "camera": ortho_camera(width, height, _COLS * _CELL / 2),
        "sun": sun((0.0, 0.0, 1.0)),
        "squares": mesh(squares, 0.5),
    }


#: Relative tolerance on the straight-edge RMS: ~3000 edge pixels from 576 independent
#: edges give a relative standard error of 0.75 / sqrt(576) = 3 % at worst; 2.5 of them.
FLOOR_RTOL = 0.08


def test_straight_edge_coverage_error_reproduces_the_floor_table():
    """MSAA coverage on pixels crossed by one square edge (no corner in or next to the
    pixel) against the exact area: the RMS is the floor table's, for every N."""
    w, h = 320, 180
    scene = scenes.load(BuiltinScene("aa-squares", _squares_scene, "squares"), width=w, height=h)
    exact = np.zeros((h, w))
    near_corner = np.zeros((h, w), bool)
    touched = np.zeros((h, w), int)
    for q in _squares():
        film = scene.camera.project(q)
        cov = polygon_coverage(film, w, h)
        exact += cov
        touched += cov > 0
        for fx, fy in film:
            x0, y0 = int(math.floor(fx)), int(math.floor(fy))
            near_corner[max(y0 - 1, 0) : y0 + 2, max(x0 - 1, 0) : x0 + 2] = True
    single = (exact > 0) & (exact < 1) & ~near_corner & (touched == 1)
    assert single.sum() > 2500
    for n in samples.STANDARD_COUNTS:
        cov = rm.run("msaa", scene, samples=n).outputs["coverage"]
        rms = float(np.sqrt(np.mean((cov - exact)[single] ** 2)))
        assert rms == pytest.approx(COVERAGE_FLOOR_RMS[n], rel=FLOOR_RTOL), n


def test_msaa_equals_ssaa_where_shading_is_constant(star):
    """Flat spokes under a sun without shadows: shading at the centre or at each sample is
    the same value, so MSAA N and SSAA N at the same positions agree."""
    for n in (2, 4, 8, 16):
        m = rm.run("msaa", star, samples=n).outputs["color"]
        s = rm.run("ssaa", star, samples=n).outputs["color"]
        assert np.allclose(m, s, atol=FLOAT_TOL * max(1.0, float(s.max()))), n


#: Median |difference| / reference stderr over edge pixels allowed for 64-sample SSAA
#: (measured 0.41 at 48 x 27, against 12.4 for the 1x image): the grid's quadrature error
#: plus the reference's noise stay well below 2 reference standard errors.
EDGE_MEDIAN_Z = 2.0


def test_ssaa_converges_to_the_reference(star):
    """The reference is the box-filtered average of the same shading: interior pixels agree
    exactly, and the edge error falls as the ordered grid refines."""
    settings = ReferenceSettings(spp=256, seed=0, channels=("color", "coverage", "edge", "id"))
    ref = get_reference(star, settings, cache=ReferenceCache(), quiet=True).channels()
    color = np.stack([ref[f"color.{c}"] for c in "RGB"], -1)
    se = np.stack([ref[f"color_stderr.{c}"] for c in "RGB"], -1)
    interior = (ref["edge"] < 0.5) & ((ref["coverage"] == 0) | (ref["coverage"] == 1))
    errs = []
    for n in (1, 4, 16, 64):
        r = rm.run("ssaa", star, samples=n, pattern="ordered-grid").outputs["color"]
        assert np.allclose(r[interior], color[interior], rtol=FLOAT_TOL, atol=1e-7)
        errs.append(float(np.abs(r - color)[~interior].mean()))
    assert errs[0] > errs[1] > errs[2] > errs[3]
    # 64 ordered-grid samples: within a few reference standard errors on average
    r64 = rm.run("ssaa", star, samples=64, pattern="ordered-grid").outputs["color"]
    z = np.abs(r64 - color)[~interior] / np.maximum(se[~interior], 1e-6)
    assert np.median(z) < EDGE_MEDIAN_Z


def test_noaa_is_the_centre_sample(star):
    n = rm.run("noaa", star)
    s = rm.run("ssaa", star, samples=1)
    assert np.array_equal(n.outputs["color"], s.outputs["color"])
    assert set(np.unique(n.outputs["coverage"])) <= {0.0, 1.0}
    assert n.cost["samples"] == 1


def test_filter_kernels_closed_form():
    f = resolve.filter_weight
    assert f("catmull-rom", np.array([0.0, 1.0, 2.0])) == pytest.approx([1.0, 0.0, 0.0])
    # Mitchell-Netravali B = C = 1/3: f(0) = (6 - 2B)/6 = 8/9, f(1) = B/6 = 1/18
    assert f("mitchell", np.array([0.0, 1.0, 2.0])) == pytest.approx([8 / 9, 1 / 18, 0.0])
    assert f("triangle", np.array([0.0, 0.5, 1.0])) == pytest.approx([1.0, 0.5, 0.0])
    assert f("gaussian", np.array([2.0]))[0] == pytest.approx(0.0, abs=1e-12)
    assert f("blackman-harris", np.array([0.0]))[0] == pytest.approx(1.0, abs=1e-4)
    assert f("blackman-harris", np.array([2.0]))[0] == pytest.approx(6e-5, abs=1e-4)


@pytest.mark.parametrize("name", resolve.FILTERS)
def test_resolve_of_constant_samples_is_the_constant(name):
    offs = samples.positions(8)
    c = np.full((6 * 5, 8, 3), 0.37, np.float32)
    out = resolve.resolve(c, offs, 6, 5, name, inverse_luminance=True)
    assert np.allclose(out, 0.37, rtol=1e-6)


def test_box_resolve_with_inverse_luminance_by_hand():
    """Two samples, luminance 0 and 3 (grey 3): weights 1 and 1/4, so
    (1 * 0 + 0.25 * 3) / 1.25 = 0.6 instead of the plain mean 1.5."""
    offs = samples.positions(2)
    c = np.array([[[0.0] * 3, [3.0] * 3]], np.float32)
    assert resolve.resolve(c, offs, 1, 1, "box")[0, 0] == pytest.approx([1.5] * 3)
    out = resolve.resolve(c, offs, 1, 1, "box", inverse_luminance=True)
    assert out[0, 0] == pytest.approx([0.6] * 3, rel=1e-6)


def test_cost_records(star):
    m = rm.run("msaa", star, samples=8)
    c = m.cost
    assert c["framebuffer_bytes"] == W * H * 8 * (4 + 4)
    assert c["framebuffer_bytes_by_buffer"] == {
        "color": W * H * 32,
        "depth": W * H * 32,
        "normal": 0,
        "aggregates": 0,
    }
    hist = c["shading_events_histogram"]
    assert sum(hist) == W * H
    ev = m.outputs["shading_events"]
    assert c["shading_events_mean"] == pytest.approx(float(ev.mean()))
    assert sum(i * h for i, h in enumerate(hist)) == int(ev.sum())
    assert c["samples_tested"] == W * H * 8 and c["geometry_passes"] == 1
    # per-pixel bytes restated at 1280 x 736 (the seed slides' resolution): 57.5 MiB
    assert c["framebuffer_bytes"] // (W * H) * 1280 * 736 == 60_293_120
    a = rm.run("acaa", star, samples=8)
    assert a.cost["framebuffer_bytes_by_buffer"]["color"] == W * H * 16  # one float32 RGBA
    assert a.cost["framebuffer_bytes_by_buffer"]["depth"] == W * H * 8 * 4
    g = rm.run("agaa", star, samples=8, aggregates=2)
    b = g.cost["framebuffer_bytes_by_buffer"]
    assert b == {"color": 0, "depth": W * H * 32, "normal": W * H * 32, "aggregates": W * H * 40}
    assert g.cost["shading_events_mean"] <= 2.0


def test_same_inputs_same_bytes(star):
    a = rm.run("agaa", star)
    b = rm.run("agaa", star)
    for k in a.outputs:
        assert a.outputs[k].tobytes() == b.outputs[k].tobytes()


def test_fxaa_model_changes_only_edges(star):
    base = rm.run("noaa", star).outputs["color"]
    r = rm.run("fxaa", star)
    changed = r.outputs["fxaa_changed"] > 0
    assert changed.any() and not changed.all()
    assert np.array_equal(r.outputs["color"][~changed], base[~changed])
    # FXAA blends neighbours: every output lies within the 3x3 neighbourhood's range
    pad = np.pad(base, ((1, 1), (1, 1), (0, 0)), mode="edge")
    stack = np.stack([pad[dy : dy + H, dx : dx + W] for dy in range(3) for dx in range(3)])
    assert (r.outputs["color"] >= stack.min(0) - 1e-6).all()
    assert (r.outputs["color"] <= stack.max(0) + 1e-6).all()


@pytest.mark.parametrize(
    ("technique", "pairs", "message"),
    [
        ("msaa", ["samples=3"], "samples must be one of 1, 2, 4, 8, 16"),
        ("msaa", ["samples=0"], "samples must be an integer in [1, 16]"),
        ("msaa", ["resolve=lanczos"], "resolve must be one of box"),
        ("msaa", ["centroid=maybe"], "centroid must be a boolean"),
        ("msaa", ["shadows=izb2"], "shadows must be one of exact"),
        ("ssaa", ["samples=6"], "with pattern=standard"),
        ("ssaa", ["pattern=rotated"], "pattern must be one of standard, ordered-grid"),
        ("acaa", ["accumulation=rgba16"], "accumulation must be one of float32, rgba8"),
        ("acaa", ["depth_format=D16"], "depth_format must be one of D24, D32F"),
        ("agaa", ["aggregates=3"], "aggregates must be an integer in [1, 2]"),
        ("agaa", ["threshold=nan"], "threshold must be a finite number"),
        ("agaa", ["normal_format=rgb8"], "normal_format must be one of"),
        ("fxaa", ["preset=16"], "preset must be one of"),
        ("fxaa", ["subpix=1.5"], "subpix must be a number in [0, 1]"),
        ("msaa", ["sample=8"], "unknown parameter 'sample'"),
    ],
)
def test_bad_parameters_raise_and_exit_2(tmp_path, capsys, technique, pairs, message):
    with pytest.raises(rm.ModelError, match=message.replace("[", r"\[").replace("]", r"\]")):
        rm.parse_params(technique, pairs)
    out = tmp_path / "m"
    args = ["model", technique, "star", "--width", "16", "--height", "9", "--out", str(out)]
    for p in pairs:
        args += ["--set", p]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists() or not any(out.iterdir())


def test_model_writes_aa_channels(tmp_path):
    out = tmp_path / "m"
    args = ["model", "acaa", "decal", "--width", "32", "--height", "18", "--out", str(out)]
    assert main(args) == 0
    from raster_oracle.oracle.reference.exr import read_exr

    ch = read_exr(out / "output.exr")
    assert {"color.R", "color.G", "color.B", "coverage", "shading_events", "ties"} <= set(ch)
    rec = json.loads((out / "model.json").read_text())
    assert rec["cost"]["samples"] == 8 and rec["technique"] == "acaa"


def test_every_aa_technique_is_registered_with_its_outputs(star):
    for name in ("noaa", "ssaa", "msaa", "acaa", "agaa", "fxaa", "smaa"):
        tech = rm.TECHNIQUES[name]
        assert tech.family == "aa" and set(tech.lights) == {"directional", "spot", "point"}
        for prm in rm.list_techniques()[list(rm.TECHNIQUES).index(name)]["params"]:
            assert prm["source"] and prm["help"], (name, prm["name"])
        r = rm.run(name, star)
        assert set(rm.AA_OUTPUT_CHANNELS) <= set(r.outputs)
        assert r.outputs["color"].shape == (H, W, 3) and r.outputs["color"].dtype == np.float32
        assert np.isfinite(r.outputs["color"]).all() and (r.outputs["color"] >= 0).all()
    assert rm.TECHNIQUES["csm"].family == "shadow"


#: Pixels whose colour may change when a default shadow map replaces exact rays on
#: ``plate``: its shadow boundary and acne-free lit areas only (a few percent of the image).
SHADOW_MAP_DIFF_FRACTION = 0.05


def test_shadow_technique_option():
    """Visibility from a shadow map instead of exact rays: only shadowed shading points
    change, and only downwards or to a partial value; a technique the light does not
    support is refused before any work (exit 2)."""
    plate = scenes.load("plate", **SMALL)
    exact = rm.run("msaa", plate, samples=4).outputs["color"]
    sm = rm.run("msaa", plate, samples=4, shadows="shadow-map").outputs["color"]
    differ = np.abs(sm - exact).max(axis=2) > 1e-6
    assert differ.sum() < SHADOW_MAP_DIFF_FRACTION * W * H
    lit_max = exact.max(axis=(0, 1))
    assert (sm <= lit_max + 1e-6).all()
    assert (
        main(
            [
                "model",
                "agaa",
                "point",
                "--width",
                "16",
                "--height",
                "9",
                "--set",
                "shadows=csm",
                "--out",
                "/nonexistent/never",
            ]
        )
        == 2
    )


@pytest.mark.parametrize("inverse_luminance", [False, True])
def test_box_resolve_per_fragment_equals_per_sample(inverse_luminance):
    """MSAA's box resolve sums fragments (colour x samples owned); averaging the sample
    array gives the same image."""
    from raster_oracle.raster_models.aa import msaa

    s = scenes.load("thin", **SMALL)
    offs = samples.positions(8)
    ms = msaa.multisample(s, offs, centroid=False, shadows="exact")
    per_sample = resolve.resolve(
        msaa.sample_colors(ms["frags"], ms["rgb"]),
        offs,
        W,
        H,
        "box",
        inverse_luminance=inverse_luminance,
    )
    per_fragment = msaa.resolve_fragments(
        ms["frags"], ms["rgb"], offs, W, H, "box", inverse_luminance
    )
    assert np.allclose(per_fragment, per_sample, rtol=FLOAT_TOL, atol=1e-7)
    assert (ms["frags"].per_pixel(W * H) > 1).sum() > 50
