"""raster_models' public API: registry, parameter records and parsing, errors, the result."""

from __future__ import annotations

import json

import numpy as np
import pytest

from raster_oracle import raster_models as rm
from raster_oracle import scenes

#: Small but real: every test scene is shaded at 64x36 with 128^2 maps.
SMALL = {"width": 64, "height": 36}
SMALL_MAP = 128


@pytest.fixture(scope="module")
def plate():
    return scenes.load("plate", **SMALL)


def test_registry_names_and_records():
    records = rm.list_techniques()
    assert [r["name"] for r in records] == list(rm.TECHNIQUES)
    assert list(rm.TECHNIQUES)[:3] == list(SHADOW_MAP_FAMILY)
    assert set(rm.TECHNIQUES) >= {"izb", "coherent-shadow-map", "msaa", "acaa", "agaa", "fxaa"}
    for rec in records:
        assert rec["description"] and rec["references"]
        names = [p["name"] for p in rec["params"]]
        assert len(names) == len(set(names))
        for p in rec["params"]:
            assert set(p) >= {"name", "default", "type", "choices", "source", "help"}
            assert p["source"] and p["help"], p["name"]
            assert p["type"] in ("bool", "int", "float", "str", "floats")
            if p["type"] == "str" and p["name"] != "light_matrix":  # light_matrix: a path
                assert p["default"] in p["choices"]
        json.dumps(rec)  # plain JSON
    sdsm = {p["name"]: p for p in records[2]["params"]}
    for name in ("partitions", "resolution", "filter", "pcf_size", "latency", "scheme"):
        assert name in sdsm
    assert "Intel" in sdsm["partitions"]["source"]
    assert sdsm["max_scale"]["default"] == "inf"


def test_parse_params_types():
    got = rm.parse_params(
        "csm",
        [
            "partitions=3",
            "split_lambda=0.8",
            "fit=stable",
            "split=manual",
            "splits=0.1,0.3,1",
            "receiver_plane_bias=true",
            "resolution=1e3",
        ],
    )
    assert got == {
        "partitions": 3,
        "split_lambda": 0.8,
        "fit": "stable",
        "split": "manual",
        "splits": (0.1, 0.3, 1.0),
        "receiver_plane_bias": True,
        "resolution": 1000,
    }
    assert rm.parse_params("sdsm", ["max_scale=inf"]) == {"max_scale": float("inf")}
    assert rm.parse_params("shadow-map", []) == {}


@pytest.mark.parametrize(
    ("technique", "pairs", "message"),
    [
        ("foo", [], r"unknown technique 'foo'; choose one of shadow-map, csm, sdsm"),
        ("csm", ["cascades=4"], r"unknown parameter 'cascades'; valid parameters: .*partitions"),
        ("csm", ["partitions"], r"key=value"),
        ("csm", ["partitions=2.5"], r"partitions must be an integer in \[1, 8\], got '2.5'"),
        ("csm", ["partitions=0"], r"partitions must be an integer in \[1, 8\], got 0"),
        ("sdsm", ["format=D42"], r"format must be one of D16, D24, D32F, got 'D42'"),
        ("sdsm", ["stretch_ends=maybe"], r"stretch_ends must be a boolean"),
        ("csm", ["split_lambda=nan"], r"split_lambda must be a finite number in \[0, 1\]"),
        ("sdsm", ["border_z=inf"], r"border_z must be a finite number >= 0, got inf"),
        ("sdsm", ["border_xy=inf"], r"border_xy must be a finite number >= 0, got inf"),
        ("sdsm", ["dilation_texels=+inf"], r"dilation_texels must be a finite number"),
        ("sdsm", ["max_scale=-inf"], r"max_scale must be a number >= 1e-06 \(inf = no limit\)"),
        ("sdsm", ["max_scale=nan"], r"max_scale must be a number"),
        ("shadow-map", ["light_near=inf"], r"light_near must be a finite number"),
        ("shadow-map", ["perspective_bias=nan"], r"perspective_bias must be a finite number"),
        ("csm", ["splits=0.1,inf,0.5,1"], r"splits must be a comma-separated list of finite"),
        ("csm", ["bias=abc"], r"bias must be a number"),
        ("csm", ["split=manual", "splits=0.1,0.2"], r"one split per cascade"),
        ("csm", ["split=manual", "splits=0.5,0.2,0.7,1"], r"splits must increase"),
        ("sdsm", ["filter=evsm4", "receiver_plane_bias=1"], r"compare filters"),
    ],
)
def test_parse_params_errors(technique, pairs, message):
    with pytest.raises(rm.ModelError, match=message):
        rm.parse_params(technique, pairs)
    assert issubclass(rm.ModelError, ValueError)


def test_run_rejects_bad_values_and_lights(plate):
    with pytest.raises(rm.ModelError, match="unknown parameter 'cascades'"):
        rm.run("csm", plate, cascades=2)
    with pytest.raises(rm.ModelError, match="resolution must be an integer"):
        rm.run("csm", plate, resolution="big")
    with pytest.raises(rm.ModelError, match="unknown technique"):
        rm.run("vssm", plate)
    spot = scenes.load("spot", **SMALL)
    for technique in ("csm", "sdsm"):
        with pytest.raises(rm.ModelError, match="directional light.*spot light"):
            rm.run(technique, spot)


#: The techniques that render shadow maps with hardware-style filters (the contract below).
SHADOW_MAP_FAMILY = ("shadow-map", "csm", "sdsm")


@pytest.mark.parametrize("technique", list(rm.TECHNIQUES))
def test_every_technique_runs_with_its_defaults(plate, technique):
    """Defaults give finite float32 images of the frame's size, every described parameter is
    recorded, and the record is plain JSON."""
    r = rm.run(technique, plate)
    assert r.outputs
    for name, img in r.outputs.items():
        assert img.shape[:2] == (plate.height, plate.width), name
        assert img.dtype == np.float32, name
        assert np.isfinite(img).all(), name
    described = {
        p["name"] for p in rm.list_techniques()[list(rm.TECHNIQUES).index(technique)]["params"]
    }
    assert set(r.params) == described
    record = json.loads(json.dumps(r.to_json()))
    assert record["technique"] == technique


@pytest.mark.parametrize("technique", SHADOW_MAP_FAMILY)
def test_result_contract(plate, technique):
    r = rm.run(technique, plate, resolution=SMALL_MAP, filter="hw_pcf")
    assert set(r.outputs) == set(rm.OUTPUT_CHANNELS) | set(rm.COMPARE_OUTPUT_CHANNELS)
    for name, img in r.outputs.items():
        assert img.shape == (plate.height, plate.width), name
        assert img.dtype == np.float32, name
        assert np.isfinite(img).all(), name
    vis = r.outputs["visibility"]
    assert vis.min() >= 0.0 and vis.max() <= 1.0
    assert 0.0 < vis.mean() < 1.0  # the plate casts a shadow on the ground
    k = len(r.diagnostics["partitions"])
    assert set(np.unique(r.outputs["cascade"])) <= set(range(-1, k))
    assert set(r.cost) >= {
        "shadow_map_bytes",
        "texels_rendered",
        "render_passes",
        "texture_lookups_per_pixel",
        "readback_latency_frames",
    }
    assert r.cost["shadow_map_bytes"] == k * SMALL_MAP**2 * 4  # D32F
    assert r.cost["texels_rendered"] == k * SMALL_MAP**2
    assert r.cost["texture_lookups_per_pixel"] == 1.0
    described = {
        p["name"] for p in rm.list_techniques()[list(rm.TECHNIQUES).index(technique)]["params"]
    }
    assert set(r.params) == described
    assert r.params["resolution"] == SMALL_MAP and r.params["filter"] == "hw_pcf"
    record = json.loads(json.dumps(r.to_json()))
    assert record["technique"] == technique
    assert len(record["diagnostics"]["split_depths"]) == k + 1
    assert r.wall_seconds > 0


def test_sky_is_lit_and_back_faces_are_dark():
    s = scenes.load("star", **SMALL)
    r = rm.run("csm", s, resolution=SMALL_MAP)
    from raster_oracle.raster_models.gbuffer import trace_gbuffer

    g = trace_gbuffer(s)
    vis = r.outputs["visibility"].ravel()
    assert (vis[~g.valid] == 1.0).all()
    assert (r.outputs["cascade"].ravel()[~g.valid] == -1).all()
    assert (vis[g.valid & ~g.receiver] == 0.0).all()


def test_runs_are_deterministic(plate):
    kw = {"resolution": SMALL_MAP, "filter": "poisson", "poisson_rotate": True, "seed": 3}
    a = rm.run("sdsm", plate, **kw)
    b = rm.run("sdsm", plate, **kw)
    for name in rm.OUTPUT_CHANNELS:
        np.testing.assert_array_equal(a.outputs[name], b.outputs[name])
    c = rm.run("sdsm", plate, **{**kw, "seed": 4})
    assert not np.array_equal(a.outputs["visibility"], c.outputs["visibility"])


def test_cost_record_counts_passes_and_lookups(plate):
    r = rm.run(
        "csm",
        plate,
        resolution=SMALL_MAP,
        filter="evsm4",
        blur_size=3,
        partitions=2,
        moment_format="float16",
        format="D16",
    )
    # depth D16 + EVSM4 RGBA16F per cascade + one blur scratch texture
    assert r.cost["shadow_map_bytes"] == 2 * SMALL_MAP**2 * (2 + 8) + SMALL_MAP**2 * 8
    assert r.cost["render_passes"] == 2 * (1 + 1 + 2)  # depth, EVSM conversion, 2 blur passes
    r = rm.run("csm", plate, resolution=SMALL_MAP, filter="pcf", pcf_size=3, partitions=2)
    assert r.cost["texture_lookups_per_pixel"] == 9.0
    r = rm.run("sdsm", plate, resolution=SMALL_MAP, latency=2, filter="point")
    assert r.cost["readback_latency_frames"] == 2
    assert r.cost["compute_passes"] == 6


def test_family_of_every_technique():
    assert rm.family_of("csm") == "shadow"
    assert rm.family_of("coherent-shadow-map") == "shadow"
    assert rm.family_of("msaa") == "aa"
    assert rm.family_of("taa") == "taa"
    assert rm.family_of("pcss") == "soft" and rm.family_of("msm") == "shadow"
    assert {rm.family_of(t) for t in rm.TECHNIQUES} == {
        "shadow",
        "aa",
        "taa",
        "soft",
        "rtshadows",
        "alpha",
    }
    with pytest.raises(rm.ModelError, match=r"unknown technique 'nope'; choose one of shadow-map"):
        rm.family_of("nope")


#: Receivers whose visibility may differ between the model's own G-buffer and the same
#: points handed to visibility_at: that G-buffer's cos_l is the kernel's float32 value, the
#: points' cos_l is recomputed in float64, so grazing receivers (N.L ~ 0) can flip.
VISIBILITY_AT_MISMATCH_MAX = 0.01


@pytest.mark.parametrize(("scene_name", "technique"), [("city", "csm"), ("spot", "shadow-map")])
def test_visibility_at_pixel_centres_is_the_models_visibility(scene_name, technique):
    from raster_oracle.raster_models.gbuffer import trace_gbuffer
    from raster_oracle.raster_models.shadowmaps import visibility_at

    scene = scenes.load(scene_name, **SMALL)
    g = trace_gbuffer(scene)
    vis = visibility_at(
        scene,
        technique,
        position=g.position,
        normal=g.normal,
        geo_normal=g.normal,
        depth=g.depth,
        valid=g.valid,
    )
    want = rm.run(technique, scene).outputs["visibility"].ravel()
    assert vis.shape == want.shape and vis.dtype == np.float64
    assert 0.0 < want[g.receiver].mean() < 1.0  # lit and shadowed receivers
    assert np.mean(np.abs(vis - want) > 1e-6) <= VISIBILITY_AT_MISMATCH_MAX
    assert np.all(vis[~g.valid] == 1.0)


def test_visibility_at_refuses_unknown_techniques_and_lights():
    from raster_oracle.raster_models.shadowmaps import supported_lights, visibility_at

    spot = scenes.load("spot", **SMALL)
    pts = {
        "position": np.zeros((1, 3)),
        "normal": np.array([[0.0, 1.0, 0.0]]),
        "geo_normal": np.array([[0.0, 1.0, 0.0]]),
        "depth": np.ones(1),
        "valid": np.ones(1, bool),
    }
    assert supported_lights("csm") == ("directional",)
    assert "point" in supported_lights("shadow-map")
    with pytest.raises(rm.ModelError, match="csm needs a directional light; the scene's light"):
        visibility_at(spot, "csm", **pts)
    with pytest.raises(rm.ModelError, match="unknown shadow-map technique 'izb'"):
        visibility_at(spot, "izb", **pts)
