"""Each technique option does what it says, end to end on built-in scenes (96x54 pixels)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.raster_models import params
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from raster_oracle.raster_models.shadowmaps import csm, sdsm, shadow_map
from raster_oracle.raster_models.shadowmaps.render import render_maps

from raster_oracle import raster_models as rm
from raster_oracle import scenes

SIZE = {"width": 96, "height": 54}
GOOD_BIAS = {"bias": 0.0005, "normal_offset": 1.5}


@pytest.fixture(scope="module")
def city():
    return scenes.load("city", **SIZE)


@pytest.fixture(scope="module")
def plate():
    return scenes.load("plate", **SIZE)


def _errors(scene, result) -> float:
    g = trace_gbuffer(scene, with_lit=True)
    lit = result.outputs["visibility"].ravel() >= 0.5
    return float(((lit != g.lit) & g.receiver).sum() / max(g.receiver.sum(), 1))


def test_every_default_round_trips_through_parse_params():
    for rec in rm.list_techniques():
        for p in rec["params"]:
            d = p["default"]
            text = ",".join(map(str, d)) if isinstance(d, list) else str(d)
            got = rm.parse_params(rec["name"], [f"{p['name']}={text}"])[p["name"]]
            if isinstance(d, list):
                assert list(got) == d
            elif d == "inf":
                assert got == math.inf
            else:
                assert got == d, p["name"]


@pytest.mark.parametrize("filter_", ["point", "hw_pcf", "pcf", "poisson", "vsm", "evsm2", "evsm4"])
@pytest.mark.parametrize("technique", ["csm", "sdsm"])
def test_every_filter_finds_the_shadows(city, technique, filter_):
    r = rm.run(technique, city, resolution=1024, filter=filter_, pcf_size=3, **GOOD_BIAS)
    assert r.outputs["visibility"].dtype == np.float32
    limit = 0.02 if technique == "sdsm" else 0.05
    assert _errors(city, r) < limit, filter_


def test_depth_formats_quantize_the_stored_maps(plate):
    for fmt, bits in (("D16", 16), ("D24", 24)):
        values = {"resolution": 64, "format": fmt}
        p = params.make("shadow-map", shadow_map.ShadowMapParams, values)
        setup = shadow_map.build(plate, None, p)
        depth = render_maps(plate, setup, p)[0].depth
        steps = depth * (2**bits - 1)
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
        assert depth.min() < 1.0  # the ground and the plate are in the map
    p = params.make("shadow-map", shadow_map.ShadowMapParams, {"resolution": 64})
    setup = shadow_map.build(plate, None, p)
    depth = render_maps(plate, setup, p)[0].depth
    np.testing.assert_array_equal(depth, depth.astype(np.float32))


def test_hardware_slope_scaled_bias_pushes_tilted_casters_back():
    s = scenes.load("curved", **SIZE)
    base = params.make("shadow-map", shadow_map.ShadowMapParams, {"resolution": 128})
    biased = params.make(
        "shadow-map",
        shadow_map.ShadowMapParams,
        {"resolution": 128, "slope_scaled_bias": 1.0, "depth_bias": 1000, "format": "D24"},
    )
    setup = shadow_map.build(s, None, base)
    d0 = render_maps(s, setup, base)[0].depth
    d1 = render_maps(s, setup, biased)[0].depth
    hit = d0 < 1.0
    diff = (d1 - d0)[hit]
    assert (diff >= 1000 * 2.0**-24 - 2.0**-23).all()  # at least DepthBias * r everywhere
    assert diff.max() > 10 * diff.min()  # the sphere's rim is steeper than its top


@pytest.mark.parametrize("scene_name", ["curved", "spot"])
def test_maps_rendered_in_launches_equal_one_launch(monkeypatch, scene_name):
    """Launches of 1000 texels (not dividing the map) give the same map bytes and moments as
    one launch: per-launch slopes use the launch's texel offset (ortho and perspective)."""
    from raster_oracle.raster_models.shadowmaps import raycast

    s = scenes.load(scene_name, **SIZE)
    values = {"resolution": 96, "slope_scaled_bias": 1.0, "depth_bias": 100, "format": "D24"}
    values["filter"] = "evsm4" if scene_name == "curved" else "pcf"
    p = params.make("shadow-map", shadow_map.ShadowMapParams, values)
    setup = shadow_map.build(s, None, p)
    whole = render_maps(s, setup, p)
    monkeypatch.setattr(raycast, "GRID_CHUNK", 1000)
    parts = render_maps(s, setup, p)
    for a, b in zip(whole, parts, strict=True):
        assert a.depth.tobytes() == b.depth.tobytes()
        assert a.texels_covered == b.texels_covered
        if a.moments is not None:
            assert a.moments.tobytes() == b.moments.tobytes()


def test_blend_band_blends_with_the_next_cascade(city):
    plain = rm.run("csm", city, resolution=128, **GOOD_BIAS)
    blended = rm.run("csm", city, resolution=128, blend_band=0.3, **GOOD_BIAS)
    n = blended.diagnostics["blended_receivers"]
    assert n > 0 and plain.diagnostics["blended_receivers"] == 0
    rec = blended.diagnostics["receivers"]
    assert blended.cost["texture_lookups_per_pixel"] == pytest.approx(1.0 + n / rec)
    assert not np.array_equal(plain.outputs["visibility"], blended.outputs["visibility"])
    assert _errors(city, blended) < 0.05


def test_selection_by_projection_picks_the_first_containing_cascade(city):
    depth = rm.run("csm", city, resolution=256, selection="depth")
    proj = rm.run("csm", city, resolution=256, selection="projection")
    cd, cp = depth.outputs["cascade"], proj.outputs["cascade"]
    valid = cd >= 0
    assert (cp[valid] <= cd[valid]).all()
    assert (cp[valid] < cd[valid]).any()  # slices overlap in light space
    assert proj.diagnostics["uncovered_receivers"] == 0


@pytest.mark.parametrize("split", ["uniform", "log", "practical", "manual"])
def test_split_schemes(city, split):
    r = rm.run("csm", city, resolution=256, split=split, partitions=4)
    z = r.diagnostics["split_depths"]
    cam = city.camera
    assert z[0] == pytest.approx(cam.near) and z[-1] == pytest.approx(cam.far)
    if split == "manual":
        np.testing.assert_allclose(
            z[1:], cam.near + np.array([0.05, 0.15, 0.5, 1.0]) * (cam.far - cam.near)
        )
    if split == "log":
        np.testing.assert_allclose(np.diff(np.log(z)), np.log(cam.far / cam.near) / 4)


def test_stable_fit_rounds_the_sphere_and_snaps_the_origin(city):
    p = params.make("csm", csm.CsmParams, {"resolution": 512, "fit": "stable"})
    setup = csm.build(city, None, p)
    for part in setup.partitions:
        radius = part.info["sphere_radius"]
        assert radius * 16 == int(radius * 16)
        x0, x1, y0, y1, _, _ = part.projection.extent
        texel = (x1 - x0) / 512
        assert x1 - x0 == pytest.approx(2 * radius)
        assert x0 / texel == pytest.approx(round(x0 / texel), abs=1e-6)
        assert y1 / texel == pytest.approx(round(y1 / texel), abs=1e-6)


@pytest.mark.parametrize("scheme", ["log", "log_histogram", "adaptive_log", "kmeans"])
def test_sdsm_schemes_cover_every_receiver(city, scheme):
    # (No normal offset: it moves lookups off the samples the bounds were built from.)
    kw = {"resolution": 512, "filter": "hw_pcf", "receiver_plane_bias": True}
    r = rm.run("sdsm", city, scheme=scheme, **kw)
    d = r.diagnostics
    assert d["uncovered_receivers"] == 0
    z = d["split_depths"]
    assert z[0] == pytest.approx(city.camera.near) and z[-1] == pytest.approx(city.camera.far)
    assert all(b >= a for a, b in zip(z, z[1:], strict=False))
    assert _errors(city, r) < 0.01
    samples = sum(p.get("samples", 0) for p in d["partitions"])
    assert samples == d["samples"]
    if scheme == "log":
        inner = np.array(z[1:-1])
        want = d["zmin"] * (d["zmax"] / d["zmin"]) ** (np.arange(1, 4) / 4)
        np.testing.assert_allclose(inner, want, rtol=1e-9)


def test_sdsm_tight_bounds_zoom_in(city):
    tight = rm.run("sdsm", city, resolution=512, filter="hw_pcf")
    loose = rm.run("sdsm", city, resolution=512, filter="hw_pcf", tight_bounds=False)
    t_tight = np.median(tight.outputs["texels_per_pixel"][tight.outputs["cascade"] >= 0])
    t_loose = np.median(loose.outputs["texels_per_pixel"][loose.outputs["cascade"] >= 0])
    assert t_tight > 2 * t_loose
    # Dilation: every partition is larger than its samples by 10 texels of its map.
    for part in tight.diagnostics["partitions"]:
        lo, hi = np.array(part["texture_bounds_min"]), np.array(part["texture_bounds_max"])
        scale = np.array(part["scale"])
        inner = ((hi - lo) * scale)[:2]  # fraction of the map the samples cover
        full = (hi - lo)[:2] > sdsm.MIN_EXTENT  # else: a degenerate (floored) partition
        assert full.any()
        np.testing.assert_allclose(inner[full], 1.0 - 2 * 10 / 512, rtol=1e-6)


def test_sdsm_max_scale_and_quantize(city):
    r = rm.run("sdsm", city, resolution=512, filter="hw_pcf", max_scale=4.0)
    for part in r.diagnostics["partitions"]:
        assert max(part["scale"][:2]) <= 4.0 + 1e-12
    q = rm.run("sdsm", city, resolution=512, filter="hw_pcf", quantize=True)
    for part in q.diagnostics["partitions"]:
        s = np.array(part["scale"][:2])
        np.testing.assert_array_equal(s, np.exp2(np.round(np.log2(s))))  # powers of two
        b = np.array(part["bias"][:2]) * 512
        np.testing.assert_allclose(b, np.round(b), atol=1e-6)  # whole texels
    assert q.diagnostics["light_up_used"] == "world_y"
    assert q.diagnostics["uncovered_receivers"] == 0


def test_sdsm_depth_range_failure_modes(city):
    base = rm.run("sdsm", city, resolution=256, filter="hw_pcf")
    far = rm.run("sdsm", city, resolution=256, filter="hw_pcf", sky_as_far=True)
    assert far.diagnostics["zmax"] == city.camera.far > base.diagnostics["zmax"]
    q = rm.run("sdsm", city, resolution=256, filter="hw_pcf", depth_readback="unorm16")
    quantum = (city.camera.far - city.camera.near) / 65535
    for key in ("zmin", "zmax"):
        assert abs(q.diagnostics[key] - base.diagnostics[key]) <= quantum / 2 + 1e-9
        k = (q.diagnostics[key] - city.camera.near) / quantum
        assert k == pytest.approx(round(k), abs=1e-6)


def test_sdsm_empty_partition_is_a_sentinel(plate):
    # Eight partitions over the plate scene's short depth range: some log slices are empty.
    r = rm.run("sdsm", plate, resolution=128, partitions=8, filter="hw_pcf")
    empty = [p for p in r.diagnostics["partitions"] if p["empty"]]
    samples = [p.get("samples", 0) for p in r.diagnostics["partitions"]]
    assert len(empty) == sum(1 for n in samples if n == 0)
    assert r.cost["texels_rendered"] == (8 - len(empty)) * 128 * 128
    assert r.diagnostics["uncovered_receivers"] == 0


def test_evsm_exponents_follow_intel_light_space_scaling(city):
    r = rm.run("sdsm", city, resolution=256, filter="evsm4")
    parts = [p for p in r.diagnostics["partitions"] if not p["empty"]]
    exps = [p["evsm_exponents"] for p in parts]
    assert all(0 < e[0] <= 42 and 0 < e[1] <= 42 for e in exps)
    assert all(e[0] / e[1] == pytest.approx(8.0) for e in exps if e[0] < 42)
    fp16 = rm.run("csm", city, resolution=256, filter="evsm4", moment_format="float16")
    for part in fp16.diagnostics["partitions"]:
        assert part["evsm_exponents"] == [5.54, 5.0]


def test_partition_record_lists_bounds_and_statistics(city):
    r = rm.run("sdsm", city, resolution=256, filter="hw_pcf")
    for part in r.diagnostics["partitions"]:
        if part["empty"]:
            continue
        b = part["projection"]["light_space_bounds"]
        assert b["x"][0] < b["x"][1] and b["y"][0] < b["y"][1] and b["z"][0] < b["z"][1]
        st = part["statistics"]
        assert st["receivers"] <= st["pixels"]
    total = sum(p["statistics"]["receivers"] for p in r.diagnostics["partitions"])
    assert total == r.diagnostics["receivers"]


def test_sdsm_setup_is_reusable_for_the_uncovered_map(plate):
    """The current-frame SDSM's partitions contain every sample they were built from."""
    p = params.make("sdsm", sdsm.SdsmParams, {"resolution": 256, "filter": "point"})
    g = trace_gbuffer(plate)
    setup = sdsm.build(plate, g, p)
    for part in setup.partitions:
        if part.projection is None:
            continue
        inside = (g.depth >= part.z_begin) & (g.depth < part.z_end) & g.valid
        u, v, _, _ = part.projection.project(g.position[inside])
        assert ((u >= 0) & (u <= 1) & (v >= 0) & (v <= 1)).all()
