"""The ``izb`` model: exactness against the oracle's rays (pixel centre and the 32 FTIZB
tangent-plane points), the analytic plate shadow, invariance of the answer to the grid and
cascades, list lengths, test counts, and bad parameters."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.reference.exr import read_exr
from raster_oracle.oracle.reference.render import ALL_CHANNELS, ReferenceSettings, render_reference
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from raster_oracle.raster_models.izb import geometry, kernel, lists
from raster_oracle.raster_models.izb import model as izb
from raster_oracle.raster_models.izb.kernel import DeadPairs, PairTester
from raster_oracle.raster_models.izb.lists import Joins, build_lists, late_pairs
from raster_oracle.scenes.geometry.tangent32 import TANGENT_POINTS_32, tangent_offsets
from scipy import ndimage
from test_models_xml import box, ground, quad, write_scene

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests._izb_reference import PAIR_TOLERANCE, join, pair_tests

SMALL = {"width": 160, "height": 90}
MEDIUM = {"width": 320, "height": 180}

#: The issue's requirement: the 1-sample IZB equals the oracle's pixel-centre shadow ray on
#: at least 99.99 % of receivers outside the epsilon band (samples whose answer depends on
#: the 0.001 epsilon: an occluder beyond float32 rounding but within epsilon of the plane).
CENTRE_AGREEMENT = 0.9999

#: 32 samples against the tangent-plane reference, outside the epsilon band: at least this
#: fraction of pixels identical (measured 0.99995 on city and 0.99991 on thin at 320x180);
#: the rest differ by one point of 32, a point within the float32 rounding of the oracle's
#: ray origin (1e-4 at 2000 units on city) of a shadow edge.
TANGENT_IDENTICAL = 0.9995
ONE_POINT = 1.0 / 32.0

#: Ground points within this distance of the plate shadow's edge are not scored against the
#: closed form (float32 G-buffer positions: about 1e-6 at the scene's scale of 10 units).
EDGE_TOLERANCE = 1e-5

#: Plate scene: quad y = 1.5, |x|, |z| <= 1; sun direction (0.55, -1, 0.2).
PLATE_Y = 1.5
PLATE_SHIFT = np.array([0.55, 0.2]) * PLATE_Y


@pytest.fixture(scope="module")
def plate():
    return scenes.load("plate", **SMALL)


@pytest.fixture(scope="module")
def thin():
    return scenes.load("thin", **MEDIUM)


@pytest.fixture(scope="module")
def city():
    return scenes.load("city", **MEDIUM)


def _plate_lit(xz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form visibility of ground points (x, z) under the plate, and a mask of the
    points far enough from the shadow's edge to be scored."""
    u = np.abs(xz - PLATE_SHIFT)
    edge = np.abs(np.max(u, axis=-1) - 1.0)
    return ~np.all(u <= 1.0, axis=-1), edge > EDGE_TOLERANCE


def test_point_table_is_a_32_rooks_net():
    pts = TANGENT_POINTS_32
    assert pts.shape == (32, 2)
    assert ((pts >= 0) & (pts < 1)).all()
    # one point in each column and each row of a 32x32 grid, and in each 2x16 / 16x2 box
    for nx in (1, 2, 4, 8, 16, 32):
        cells = np.floor(pts[:, 0] * nx) * (32 // nx) + np.floor(pts[:, 1] * (32 // nx))
        assert len(np.unique(cells)) == 32, nx
    a, b = tangent_offsets()
    assert abs(a.mean()) < 1e-12 and abs(b.mean()) < 1e-12


def test_conservative_rasterization_hand_count():
    from raster_oracle.raster_models.izb.geometry import conservative_fragments

    # x >= 0.5, y >= 0.5, x + y <= 5: texel (i, j) touches it when max(i, .5) + max(j, .5)
    # <= 5 (the hypotenuse passes through the corners (4, 1) and (1, 4)): 5+5+4+3+2 = 19.
    uv = np.array([[[0.5, 0.5], [4.5, 0.5], [0.5, 4.5]]])
    parts = list(conservative_fragments(uv, 8))
    texels = np.concatenate([t for _, t in parts])
    got = {(int(t % 8), int(t // 8)) for t in texels}
    want = {(i, j) for i in range(5) for j in range(5) if max(i, 0.5) + max(j, 0.5) <= 5}
    assert len(want) == 19 and got == want


def test_conservative_rasterization_covers_every_interior_point(monkeypatch):
    monkeypatch.setattr(geometry, "RASTER_CHUNK", 97)  # many chunks, rows split
    rng = np.random.default_rng(3)
    r = 32
    uv = rng.uniform(-4, r + 4, (60, 3, 2))
    uv[:20] = uv[:20, :1] + rng.uniform(-0.3, 0.3, (20, 3, 2))  # sub-texel triangles
    frags = set()
    for t, x in geometry.conservative_fragments(uv, r):
        frags.update(zip(t.tolist(), x.tolist(), strict=True))
    w = rng.dirichlet(np.ones(3), (60, 400))
    pts = np.einsum("tkv,tnk->tnv", uv, w)
    i, j = np.floor(pts[..., 0]).astype(int), np.floor(pts[..., 1]).astype(int)
    inside = (i >= 0) & (i < r) & (j >= 0) & (j < r)
    t_idx = np.broadcast_to(np.arange(60)[:, None], i.shape)
    need = set(zip(t_idx[inside].tolist(), (j * r + i)[inside].tolist(), strict=True))
    assert need and need <= frags
    # and nothing outside a triangle's texel bounding box
    for t, x in frags:
        lo, hi = np.floor(uv[t].min(0)), np.floor(uv[t].max(0))
        assert lo[0] <= x % r <= hi[0] and lo[1] <= x // r <= hi[1]


def test_shadow_volume_equals_ray_triangle_intersection():
    from raster_oracle.raster_models.izb.geometry import shadow_volumes

    rng = np.random.default_rng(5)
    d = np.array([0.3, -1.0, 0.2])
    d /= np.linalg.norm(d)
    tris = rng.uniform(-1, 1, (200, 3, 3))
    # points near each triangle's projection along d, some in front of it, some behind
    bary = rng.uniform(-0.3, 1.0, (200, 3))
    bary /= bary.sum(axis=1, keepdims=True)
    q = np.einsum("tk,tkj->tj", bary, tris) + d * rng.uniform(-0.5, 1.0, (200, 1))
    eps = 1e-3
    keep, planes = shadow_volumes(tris, d, eps)
    assert keep.all()
    v = np.einsum("tkj,tj->tk", planes[:, :, :3], q) + planes[:, :, 3]
    vol = (v[:, :3] >= 0).all(1) & (v[:, 3] > 0)
    # Moller-Trumbore from q towards the light (-d): hit at distance t > eps / |n . d|
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pv = np.cross(-d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    tv = q - v0
    u = np.einsum("ij,ij->i", tv, pv) / det
    qv = np.cross(tv, e1)
    w = (-d @ qv.T) / det
    t = np.einsum("ij,ij->i", e2, qv) / det
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1)[:, None]
    hit = (u >= 0) & (w >= 0) & (u + w <= 1) & (t * np.abs(n @ d) > eps)
    margin = np.minimum(np.minimum(u, w), 1 - u - w)
    clear = (np.abs(margin) > 1e-9) & (np.abs(t * np.abs(n @ d) - eps) > 1e-9)
    assert hit.sum() > 30 and (~hit).sum() > 30
    np.testing.assert_array_equal(vol[clear], hit[clear])


def test_plate_shadow_is_exact(plate):
    g = trace_gbuffer(plate)
    ground = g.receiver & (np.abs(g.position[:, 1]) < 1e-4)
    assert ground.sum() > 1000
    want, scored = _plate_lit(g.position[:, [0, 2]])
    one = rm.run("izb", plate).outputs["visibility"].ravel()
    sel = ground & scored
    assert 0 < (~want[sel]).sum() < sel.sum()  # both shadow and light on the ground
    np.testing.assert_array_equal(one[sel] == 1.0, want[sel])
    # 32 points of the tangent plane: the lit fraction in closed form
    a, b = tangent_offsets()
    q = g.position[:, None, :] + g.dpdx[:, None, :] * a[:, None] + g.dpdy[:, None, :] * b[:, None]
    lit_k, ok_k = _plate_lit(q[..., [0, 2]])
    sel = ground & ok_k.all(axis=1)
    frac = lit_k.mean(axis=1)
    thirty_two = rm.run("izb", plate, samples=32).outputs["visibility"].ravel()
    assert ((frac[sel] > 0) & (frac[sel] < 1)).sum() > 20  # penumbra pixels of the mask
    np.testing.assert_array_equal(thirty_two[sel], frac[sel].astype(np.float32))
    # the oracle's tangent-plane reference is the same closed form
    ref, _ = render_reference(plate, ReferenceSettings(spp=1, channels=("tangent32",)), quiet=True)
    np.testing.assert_array_equal(ref["visibility_tangent32"].ravel()[sel], frac[sel])


@pytest.mark.parametrize("name", ["plate", "city", "thin", "spot"])
def test_one_sample_equals_the_oracle_centre_ray(name):
    s = scenes.load(name, **MEDIUM)
    g = trace_gbuffer(s, with_lit=True)
    r = rm.run("izb", s)
    vis = r.outputs["visibility"].ravel()
    band = r.outputs["epsilon_band"].ravel() > 0
    assert set(np.unique(vis)) <= {0.0, 1.0}
    wrong = (vis == 1.0) != g.lit
    assert not wrong[~g.receiver].any()  # sky lit, back faces dark, as the oracle
    scored = g.receiver & ~band
    assert 1.0 - wrong[scored].sum() / scored.sum() >= CENTRE_AGREEMENT
    assert band.sum() <= 1e-3 * g.receiver.sum()
    assert r.diagnostics["epsilon_band_receivers"] == int(band.sum())


@pytest.mark.parametrize("name", ["city", "thin", "spot"])
def test_32_samples_equal_the_tangent_plane_reference(name):
    s = scenes.load(name, **MEDIUM)
    ch, _ = render_reference(
        s, ReferenceSettings(spp=64, channels=("tangent32", "visibility", "edge")), quiet=True
    )
    ref = ch["visibility_tangent32"].ravel()
    r = rm.run("izb", s, samples=32)
    vis = r.outputs["visibility"].ravel()
    band = r.outputs["epsilon_band"].ravel() > 0
    diff = np.abs(vis - ref)[~band]
    assert (diff == 0).mean() >= TANGENT_IDENTICAL
    assert diff.max() <= ONE_POINT
    # against the supersampled reference: differences beyond noise only at or beside edges
    # (a sub-pixel shadow all 64 samples of a pixel missed leaves it unflagged, its
    # neighbour that caught the shadow is an edge: 2 such pixels on thin, issue 18)
    ss, se = ch["visibility"].ravel(), ch["visibility_stderr"].ravel()
    big = np.abs(vis - ss) > 3 * se + ONE_POINT
    near_edge = ndimage.binary_dilation(ch["edge"] > 0, np.ones((3, 3), bool)).ravel()
    assert big.sum() > 0 and near_edge[big].all()


def test_answer_does_not_depend_on_grid_or_cascades():
    thin = scenes.load("thin", **SMALL)
    base = rm.run("izb", thin, samples=32)
    for kw in ({"resolution": 64}, {"resolution": 700}, {"cascades": 3}):
        other = rm.run("izb", thin, samples=32, **kw)
        np.testing.assert_array_equal(other.outputs["visibility"], base.outputs["visibility"])
    again = rm.run("izb", thin, samples=32)
    for key, img in base.outputs.items():
        assert img.tobytes() == again.outputs[key].tobytes(), key
    assert json.dumps(again.cost, sort_keys=True) == json.dumps(base.cost, sort_keys=True)


def test_removing_shadowed_receivers_saves_tests_only(thin, monkeypatch):
    rounds = rm.run("izb", thin)
    monkeypatch.setattr(izb, "ROUND_TRIANGLES", 1 << 30)  # one round: nothing removed early
    once = rm.run("izb", thin)
    np.testing.assert_array_equal(rounds.outputs["visibility"], once.outputs["visibility"])
    assert rounds.diagnostics["rounds"] > 1 and once.diagnostics["rounds"] == 1
    assert rounds.diagnostics["nodes_removed"] > 0
    assert rounds.cost["sample_triangle_tests"] < once.cost["sample_triangle_tests"]


def test_cascades_lower_the_longest_list_on_city(city):
    one = rm.run("izb", city)
    four = rm.run("izb", city, cascades=4)
    np.testing.assert_array_equal(one.outputs["visibility"], four.outputs["visibility"])
    assert four.cost["list_length_max"] * 4 < one.cost["list_length_max"]
    assert four.cost["built_list_length_max"] < one.cost["built_list_length_max"]
    assert four.cost["grids"] == 4 and four.cost["f_ls"] > one.cost["f_ls"]
    assert set(np.unique(four.outputs["cascade"])) <= {-1.0, 0.0, 1.0, 2.0, 3.0}


def test_cost_record_is_consistent(city):
    r = rm.run("izb", city, samples=32)
    c = r.cost
    assert c["point_tests"] == 32 * c["sample_triangle_tests"]
    assert c["cost_model_avg"] == pytest.approx(c["sample_triangle_tests"])
    assert c["cost_model_max"] == c["f_ls"] * c["list_length_max"]
    assert c["list_length_max"] <= c["built_list_length_max"]
    assert sum(c["texels_by_list_length"].values()) > 0
    assert c["nodes"] >= r.diagnostics["receivers"]
    heads = 4 * 512 * 512
    assert c["memory_bytes_by_buffer"]["list_heads"] == heads
    assert c["memory_bytes"] == heads + 8 * c["nodes"] + 4 * city.width * city.height
    hist = c["texels_by_list_length"]
    assert list(hist)[0] == "1" and all(v >= 0 for v in hist.values())
    json.dumps(r.to_json())


@pytest.mark.parametrize("name", ["city", "thin"])
def test_32_samples_cost_under_twice_one_sample_in_frustum_tests(name):
    """The seed's "32 spp under 2x the cost of 1 spp", in test counts, at the 1080p ratio of
    pixels to grid texels (1920x1080 on 512^2: 7.9; here 320x180 on 96^2: 6.3): the
    frustum-triangle tests (one per fragment and node) stay under 2x; the point tests, 32
    per frustum test, do not (the claim rests on testing the 32 points at once)."""
    s = scenes.load(name, **MEDIUM)
    one = rm.run("izb", s, resolution=96).cost
    many = rm.run("izb", s, resolution=96, samples=32).cost
    ratio = many["sample_triangle_tests"] / one["sample_triangle_tests"]
    assert 1.0 < ratio < 2.0
    assert many["point_tests"] / one["point_tests"] > 2.0


def test_reference_tangent_channel_is_opt_in():
    assert "tangent32" not in ALL_CHANNELS
    assert "tangent32" not in ReferenceSettings().validate().channels
    assert ReferenceSettings(channels=("tangent32", "id")).validate().channels == (
        "id",
        "tangent32",
    )


def test_cli_reference_writes_the_tangent_channel(tmp_path):
    out = tmp_path / "ref"
    argv = ["reference", "plate", "--width", "48", "--height", "27", "--spp", "4"]
    argv += ["--channels", "visibility,tangent32", "--no-cache", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    ch = read_exr(out / "reference.exr")
    assert "visibility_tangent32" in ch and "visibility" in ch
    assert 0.0 < ch["visibility_tangent32"].mean() < 1.0


def test_cli_model_izb(tmp_path):
    out = tmp_path / "m"
    argv = ["model", "izb", "plate", "--width", "48", "--height", "27", "--set", "samples=32"]
    assert main([*argv, "--out", str(out)]) == 0
    rec = json.loads((out / "model.json").read_text())
    assert rec["params"]["samples"] == 32 and rec["cost"]["f_ls"] > 0
    assert set(read_exr(out / "output.exr")) >= {"visibility", "cascade", "epsilon_band"}


@pytest.mark.parametrize(
    ("pair", "message"),
    [
        ("samples=16", "samples must be 1 or 32"),
        ("samples=0", "samples must be an integer in"),
        ("resolution=0", "resolution must be an integer in"),
        ("cascades=9", "cascades must be an integer in"),
        ("epsilon=nan", "epsilon must be a finite number"),
        ("epsilon=-1", "epsilon must be a number in"),
        ("light_up=sideways", "light_up must be one of"),
        ("bias=0.1", "unknown parameter 'bias'"),
    ],
)
def test_bad_parameters_exit_2(tmp_path, capsys, pair, message):
    out = tmp_path / "m"
    argv = ["model", "izb", "plate", "--width", "48", "--height", "27", "--set", pair]
    rc = main([*argv, "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not out.exists()
    assert len(err) == 1 and message in err[0]


def test_point_light_is_refused(tmp_path, capsys):
    out = tmp_path / "m"
    rc = main(["model", "izb", "point", "--width", "48", "--height", "27", "--out", str(out)])
    assert rc == 2 and not out.exists()
    assert "directional or spot light" in capsys.readouterr().err


SPOT_XML = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="3,8,8" target="3,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="160"/><integer name="height" value="90"/>
      <rfilter type="box"/></film>
  </sensor>
  <emitter type="spot">
    <transform name="to_world"><lookat origin="0,4,0" target="3,0,0" up="0,0,1"/></transform>
    <rgb name="intensity" value="50"/>
    <float name="cutoff_angle" value="35"/>
  </emitter>
  <shape type="rectangle" id="ground">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="50"/></transform>
  </shape>
  <shape type="cube" id="beam">
    <transform name="to_world">
      <scale x="10" y="0.2" z="0.2"/><translate x="0" y="2" z="0.4"/>
    </transform>
  </shape>
</scene>
"""


def test_spot_light_occluder_crossing_the_light_plane(tmp_path):
    """A beam from behind the spot light to in front of it: no finite projection, so it is
    rasterized over the whole perspective grid; its shadow is still exact."""
    path = tmp_path / "spot.xml"
    path.write_text(SPOT_XML)
    s = scenes.load(str(path))
    g = trace_gbuffer(s, with_lit=True)
    r = rm.run("izb", s)
    assert r.diagnostics["projection"] == "perspective"
    assert r.diagnostics["triangle_grids_crossing_light_plane"] > 0
    vis = r.outputs["visibility"].ravel()
    band = r.outputs["epsilon_band"].ravel() > 0
    scored = g.receiver & ~band
    assert (~g.lit[scored]).sum() > 50  # the beam's shadow on the ground
    assert ((vis[scored] == 1.0) == g.lit[scored]).mean() >= CENTRE_AGREEMENT
    # 32 points, some outside the cone: the tangent-plane reference again
    r32 = rm.run("izb", s, samples=32)
    ref, _ = render_reference(s, ReferenceSettings(spp=1, channels=("tangent32",)), quiet=True)
    band = r32.outputs["epsilon_band"] > 0
    diff = np.abs(r32.outputs["visibility"] - ref["visibility_tangent32"])[~band]
    assert (diff == 0).mean() >= TANGENT_IDENTICAL and diff.max() <= ONE_POINT
    partial_cone = (ref["visibility_tangent32"] > 0) & ~g.receiver.reshape(s.height, s.width)
    assert partial_cone.sum() > 0  # pixels whose centre is outside the cone, partly lit


def _xml_scene(tmp_path, name, **kw):
    shapes = kw.pop("shapes", [ground(40.0), box((-1, 0, 2), (1, 2, 4))])
    kw = {"origin": (0, 3, -6), "target": (0, 0, 4), **kw}
    return scenes.load(str(write_scene(tmp_path, name=name, shapes=shapes, **kw)))


def test_all_sky_frame_does_no_work(tmp_path):
    s = _xml_scene(tmp_path, "sky", origin=(0, 2, 0), target=(0, 10, 0.01), up=(0, 0, 1))
    for samples in (1, 32):
        r = rm.run("izb", s, samples=samples, cascades=2)
        assert (r.outputs["visibility"] == 1.0).all()
        assert (r.outputs["cascade"] == -1).all()
        assert r.diagnostics["receivers"] == 0 and r.cost["nodes"] == 0
        assert r.cost["sample_triangle_tests"] == 0 and r.cost["f_ls"] == 0
        assert all(np.isfinite(v) for v in r.cost.values() if not isinstance(v, dict))


def test_scene_far_from_the_origin(tmp_path):
    """1e5 units from the origin float32 G-buffer positions are 8 mm apart, more than the
    epsilon: the ground (y = 0) and plate (y = 1.5) are exact in y, so there is no acne and
    the shadow lands where it does at the origin, up to that quantization."""
    vis = {}
    for offset in (0.0, 1e5):
        o = np.array([offset, 0.0, offset])
        s = _xml_scene(
            tmp_path,
            f"offset{int(offset)}",
            origin=o + (0, 6, 7),
            target=o + (0.8, 0, 0),
            sun=(0.55, -1.0, 0.2),
            shapes=[quad(o, (15, 0, 0), (0, 0, -15)), quad(o + (0, 1.5, 0), (1, 0, 0), (0, 0, -1))],
        )
        vis[offset] = rm.run("izb", s).outputs["visibility"]
    assert (vis[0.0] == 0).sum() > 100  # the plate's shadow
    assert (vis[0.0] != vis[1e5]).mean() < 0.01


#: Epsilon of :func:`_random_pairs` (world units): wide enough that every class of pair
#: occurs, the epsilon band included.
PAIR_EPSILON = 0.05


def _random_pairs(rng, n_tri=64, n_recv=3000, n_pairs=1 << 16):
    """Shadow volumes of random triangles over random receivers (points, derivatives)
    around them, and random (triangle, receiver) pairs: every class of pair occurs."""
    from raster_oracle.raster_models.izb.geometry import shadow_volumes

    tris = rng.uniform(-1.0, 1.0, (n_tri, 3, 3)) + [0.0, 2.0, 0.0]
    keep, planes = shadow_volumes(tris, (0.3, -1.0, 0.1), PAIR_EPSILON)
    pts = rng.uniform(-1.5, 1.5, (n_recv, 3)) + [0.0, 1.5, 0.0]
    recv = {
        "p": pts,
        "dpdx": rng.normal(0.0, 0.2, (n_recv, 3)),
        "dpdy": rng.normal(0.0, 0.2, (n_recv, 3)),
    }
    recv["a"], recv["b"] = tangent_offsets()
    tri = rng.integers(0, int(keep.sum()), n_pairs)
    r = rng.integers(0, n_recv, n_pairs)
    return planes, recv, tri, r


def _one_node_joins(recv, tri, r):
    """Each pair ``(tri[i], r[i])`` as a fragment whose list is one node, its own receiver
    (a copy of ``r[i]``'s row): the join's arguments, the rows and an empty state."""
    n = len(tri)
    rows = {k: v[r] if k in ("p", "dpdx", "dpdy") else v for k, v in recv.items()}
    return rows, (tri, np.arange(n), np.ones(n, dtype=np.int64))


@pytest.mark.parametrize("samples", [1, 32])
def test_drjit_pair_tests_equal_the_numpy_reference(monkeypatch, samples):
    """The Dr.Jit join against the NumPy reference, pair by pair: the same flags and masks
    (:data:`PAIR_TOLERANCE`: exact), the same state and the same dead pairs, in one launch or
    many."""
    planes, recv, tri, r = _random_pairs(np.random.default_rng(7))
    if samples == 1:
        recv = {"p": recv["p"]}
    hit, near = pair_tests(planes, recv, PAIR_EPSILON, tri, r)
    rows, args = _one_node_joins(recv, tri, r)
    keys = ("mask", "band") if samples == 32 else ("shadowed", "band")
    ref_state = {k: np.zeros(len(tri), dtype=hit.dtype) for k in keys}
    ref_dead = join(planes, rows, PAIR_EPSILON, *args, np.arange(len(tri)), ref_state, chunk=5000)
    for chunk in (kernel.DRJIT_PAIR_CHUNK, 4099):  # one launch, many launches
        monkeypatch.setattr(kernel, "DRJIT_PAIR_CHUNK", chunk)
        state = {k: np.zeros(len(tri), dtype=hit.dtype) for k in keys}
        tester = PairTester(planes, rows, node_recv=np.arange(len(tri)), epsilon=PAIR_EPSILON)
        dead = tester.join(*args, None, state, dead=True)
        for x, y in zip((hit, near), (state[keys[0]], state["band"]), strict=True):
            assert x.dtype == y.dtype
            np.testing.assert_allclose(x, y, rtol=0, atol=PAIR_TOLERANCE)
        for k in keys:
            np.testing.assert_array_equal(state[k], ref_state[k])
        for k in ("frag", "recv", "result"):
            np.testing.assert_array_equal(getattr(dead, k), getattr(ref_dead, k))
    assert hit.any() and near.any() and (~hit.astype(bool)).any()
    assert 0 < len(ref_dead.frag) < len(tri)
    if samples == 32:
        partial = (hit != 0) & (hit != 0xFFFFFFFF)
        assert (hit == 0xFFFFFFFF).any() and partial.any()  # bounds and point-by-point paths


def test_late_pairs_by_hand():
    """Fragments 0-2 in round 0 of a batch, 3-4 in round 1, a pair each: a receiver
    shadowed in round 0 (its pair in round 1 is late), one shadowed only in round 1, one
    32-sample receiver whose mask two pairs of round 0 and one of round 1 fill (bits set
    before the batch count), the same receiver filled in round 0."""
    rnd = np.array([0, 0, 0, 1, 1])
    flags = DeadPairs(np.array([0, 1, 3, 4]), np.array([7, 8, 7, 9]), np.ones(4, np.uint32))
    assert late_pairs(flags, rnd, np.zeros(10, dtype=bool)).tolist() == [0, 0, 0, 1, 0]
    before = np.zeros(10, dtype=np.uint32)
    before[2] = 0xF0000000
    frag, recv = np.array([0, 2, 3]), np.array([2, 2, 2])
    parts = np.array([0x0000FFFF, 0x00FF0000, 0x0F000000], np.uint32)
    assert late_pairs(DeadPairs(frag, recv, parts), rnd, before).tolist() == [0] * 5
    parts[1] = 0x0FFF0000  # full after round 0: the pair of round 1 is late
    assert late_pairs(DeadPairs(frag, recv, parts), rnd, before).tolist() == [0, 0, 0, 1, 0]
    whole = np.full(3, 0xFFFFFFFF, np.uint32)
    assert late_pairs(DeadPairs(frag, recv, whole), rnd, before).tolist() == [0, 0, 0, 1, 0]


def test_joins_refuse_a_receiver_shadowed_before_the_traversal():
    """The joins take receivers not fully shadowed at the start (the counters could not tell
    when one such would have left the lists; the frame's receivers exclude such pixels)."""
    lists = build_lists([(np.array([0, 0, 1]), np.array([0, 1, 2]))])
    tester = PairTester(
        np.zeros((1, 4, 4)), {"p": np.zeros((3, 3))}, node_recv=lists.node_recv, epsilon=0.0
    )
    state = {"shadowed": np.array([False, True, False]), "band": np.zeros(3, dtype=bool)}
    with pytest.raises(ValueError, match="fully shadowed before the traversal"):
        Joins(lists, tester, state)


@pytest.mark.parametrize("samples", [1, 32])
def test_batches_of_rounds_do_not_change_the_model(monkeypatch, samples):
    """The whole model with one join per round, per few rounds (the default), per frame,
    and with the NumPy reference join: the same bytes and counters, though a larger batch
    tests receivers shadowed early in it again."""
    loaded = scenes.load("thin", width=96, height=54)
    tested = []
    drjit_join = PairTester.join

    def counted(self, frag_tri, lo, n, *rest, dead):
        tested.append(int(n.sum()))
        return drjit_join(self, frag_tri, lo, n, *rest, dead=dead)

    def reference(self, frag_tri, lo, n, node_id, state, *, dead):
        tested.append(int(n.sum()))
        node_recv = self.node_recv if node_id is None else self.node_recv[node_id]
        out = join(self.planes, self.recv, self.epsilon, frag_tri, lo, n, node_recv, state)
        return out if dead else None

    monkeypatch.setattr(PairTester, "join", counted)
    monkeypatch.setattr(kernel, "DRJIT_PAIR_CHUNK", 4099)  # many launches per join
    # the pairs counted here are the technique's: no triangle grown for the epsilon band
    # (its pairs are tested, not counted: tests/test_izb_band.py)
    monkeypatch.setattr(izb, "_hit_reach", lambda smp, *a: [(0.0, 0.0)] * len(a[2].boxes))
    results = {}
    for batch in (1, lists.BATCH_PAIRS, 1 << 40):
        monkeypatch.setattr(lists, "BATCH_PAIRS", batch)
        tested.clear()
        results[batch] = (rm.run("izb", loaded, samples=samples, resolution=64), sum(tested))
    monkeypatch.setattr(PairTester, "join", reference)
    tested.clear()
    results["numpy"] = (rm.run("izb", loaded, samples=samples, resolution=64), sum(tested))
    base, n_tests = results[1]
    assert base.diagnostics["rounds"] > 2 and base.diagnostics["nodes_removed"] > 0
    assert n_tests == base.cost["sample_triangle_tests"]  # one join per round: no late test
    assert results[1 << 40][1] > n_tests  # one join: receivers shadowed early tested again
    for res, _ in results.values():
        assert res.cost == base.cost
        assert res.diagnostics["nodes_removed"] == base.diagnostics["nodes_removed"]
        for key in base.outputs:
            assert res.outputs[key].tobytes() == base.outputs[key].tobytes(), key


def test_occluder_triangles_are_kept_in_the_scene_memo():
    """The tessellated occluders are a per-scene memo (geometry only): shared by a camera
    frame made with ``dataclasses.replace``, never written into the scene's ``__dict__``."""
    from dataclasses import replace

    s = scenes.load("plate", width=48, height=27)
    first = rm.run("izb", s)
    tris = s.memo[geometry.MEMO_KEY]
    assert tris.shape[1:] == (3, 3) and len(tris) == first.diagnostics["triangles"]
    assert not any(k.startswith("_izb") for k in vars(s))
    moved = replace(s, light_index=s.light_index)
    assert moved.memo is s.memo
    again = rm.run("izb", moved)
    assert s.memo[geometry.MEMO_KEY] is tris
    np.testing.assert_array_equal(first.outputs["visibility"], again.outputs["visibility"])


@pytest.mark.parametrize("samples", [1, 32])
def test_izb_needs_a_vectorized_variant(plate, monkeypatch, samples):
    monkeypatch.setattr(izb, "vectorized", lambda: False)
    with pytest.raises(rm.ModelError, match="needs a vectorized Mitsuba variant"):
        rm.run("izb", plate, samples=samples)
