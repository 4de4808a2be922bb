"""The Dr.Jit paths of the shadow-map models against NumPy references kept here: the stored
texels of :mod:`raster_models.shadowmaps.depth_dr` (bias, clamp, quantization), SDSM's
per-partition bounds from light-frame extremes, launches split into chunks, and the map's
Dr.Jit texels. Equality is exact (``tobytes``), on random and edge inputs."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models import depth, gbuffer, params
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from raster_oracle.raster_models.light_frame import make_frame
from raster_oracle.raster_models.shadowmaps import (
    csm,
    depth_dr,
    filters,
    geometry,
    raycast,
    render,
    sdsm,
    shadow_map,
)

from raster_oracle import scenes

RNG = np.random.default_rng(20261123)

#: Depths the post-processing must treat exactly as NumPy does: signed zeros, the [0, 1]
#: ends and their neighbours, UNORM round-half-even ties, subnormals, misses and overflow.
EDGE = np.array(
    [
        0.0,
        -0.0,
        1.0,
        np.nextafter(1.0, 2.0),
        np.nextafter(0.0, -1.0),
        np.nextafter(1.0, 0.0),
        5e-324,
        -5e-324,
        -1e300,
        1e300,
        0.5 / 65535.0,
        1.5 / 65535.0,
        2.5 / 65535.0,
        0.5 / 16777215.0,
        2.5 / 16777215.0,
        np.inf,
        -np.inf,
        np.nan,
    ]
)


def _numpy_quantize(d, fmt):
    """NumPy reference of the depth-format rule (:func:`raster_models.depth.quantize_dr`):
    UNORM ``round(clip(d, 0, 1) * (2^n - 1)) / (2^n - 1)``, D32F ``float32(d)``; float64."""
    kind, bits = depth.FORMATS[fmt]
    d = np.asarray(d, dtype=np.float64)
    if kind == "unorm":
        scale = float((1 << bits) - 1)
        return np.round(np.clip(d, 0.0, 1.0) * scale) / scale
    with np.errstate(over="ignore"):  # +-1e300 -> +-inf, the IEEE cast as on Dr.Jit
        return d.astype(np.float32).astype(np.float64)


def _numpy_stored(z, fmt, *, depth_bias=0, slope=None, slope_scaled=0.0, clamp=0.0):
    """NumPy reference of the stored texels: the D3D11 hardware bias added first (when there
    is one), then the viewport clamp to [0, 1], then the format's quantization, as float32;
    misses (non-finite ``z``) store 1."""
    hit = np.isfinite(z)
    d = np.where(hit, z, 1.0)
    if depth_bias != 0 or slope_scaled != 0.0:
        bias = depth.hardware_bias(
            d, slope, fmt, depth_bias=depth_bias, slope_scaled=slope_scaled, clamp=clamp
        )
        d = _flush_subnormals(_flush_subnormals(d) + _flush_subnormals(bias))
    d = np.clip(d, 0.0, 1.0)
    stored = np.where(hit, _numpy_quantize(d, fmt), 1.0).astype(np.float32)
    return _flush_subnormals(stored), hit


def _flush_subnormals(x):
    """Dr.Jit's LLVM backend treats subnormal operands and results as (signed) zero: a
    depth or bias below 2^-1022 is +-0 in the add, and a D32F texel below 2^-126 (a bias of
    a few 2^-149 at depth 0) is stored as +-0. The compare ``ref <= texel`` is the same
    for +-0 and any reference >= 0; only texels in (0, 2^-126) differ, from references in
    that range."""
    tiny = np.abs(x) < np.finfo(x.dtype).tiny
    return np.where(tiny, np.copysign(x.dtype.type(0.0), x), x)


def _edge_depths(fmt):
    z = np.concatenate([EDGE, RNG.uniform(-0.2, 1.2, 20000), RNG.random(20000)])
    # Exact UNORM ties after scaling (round-half-even must agree).
    steps = float((1 << depth.FORMATS[fmt][1]) - 1)
    return np.concatenate([z, (np.arange(200) + 0.5) / steps])


@pytest.mark.parametrize("fmt", sorted(depth.FORMATS))
def test_quantize_dr_matches_numpy(mi, fmt):
    """The one format rule on Dr.Jit values (as ACAA's tie test calls it, unclamped depths
    in, float64 out) against the NumPy reference, bytes equal on random and edge inputs
    (float32 subnormals flushed to +-0 on the LLVM backend, see :func:`_flush_subnormals`)."""
    z = _edge_depths(fmt)
    got = depth.quantize_dr(mi, mi.Float64(z), fmt).numpy()
    assert got.dtype == np.float64
    want = _numpy_quantize(z, fmt)
    if depth.FORMATS[fmt][0] == "float":
        want = _flush_subnormals(want.astype(np.float32)).astype(np.float64)
    assert got.tobytes() == want.tobytes()


@pytest.mark.parametrize("fmt", sorted(depth.FORMATS))
@pytest.mark.parametrize(("depth_bias", "clamp"), [(0, 0.0), (3, 0.0), (-40, -1e-4), (900, 2e-5)])
def test_stored_depth_dr_matches_numpy(mi, fmt, depth_bias, clamp):
    z = _edge_depths(fmt)
    want, want_hit = _numpy_stored(z, fmt, depth_bias=depth_bias, clamp=clamp)
    bias = depth_dr.fused_bias(fmt, depth_bias=depth_bias, slope_scaled=0.0, clamp=clamp)
    if bias is None:
        # D32F's DepthBias scales with each texel's exponent: a per-texel bias array.
        assert fmt == "D32F" and depth_bias != 0
        d = np.where(np.isfinite(z), z, 1.0)
        bias = mi.Float64(
            depth.hardware_bias(d, None, fmt, depth_bias=depth_bias, slope_scaled=0.0, clamp=clamp)
        )
    got, got_hit = depth_dr.stored_depth_dr(mi, mi.Float64(z), fmt, bias)
    got = got.numpy()
    assert got.dtype == np.float32
    assert got.tobytes() == want.tobytes()
    np.testing.assert_array_equal(got_hit.numpy(), want_hit)


@pytest.mark.parametrize("fmt", sorted(depth.FORMATS))
def test_stored_depth_dr_per_texel_slope_bias(mi, fmt):
    """A slope-scaled bias per texel, passed as an array: the reference's bytes."""
    z = _edge_depths(fmt)
    slope = RNG.uniform(0.0, 2e3, len(z))
    kw = {"depth_bias": 2, "slope_scaled": 1.5, "clamp": 0.01}
    want, _ = _numpy_stored(z, fmt, slope=slope, **kw)
    d = np.where(np.isfinite(z), z, 1.0)
    bias = mi.Float64(depth.hardware_bias(d, slope, fmt, **kw))
    got, _ = depth_dr.stored_depth_dr(mi, mi.Float64(z), fmt, bias)
    assert got.numpy().tobytes() == want.tobytes()


def test_fused_bias_only_for_constant_bias():
    assert depth_dr.fused_bias("D32F", depth_bias=0, slope_scaled=0.0, clamp=0.0) == 0.0
    assert depth_dr.fused_bias("D32F", depth_bias=1, slope_scaled=0.0, clamp=0.0) is None
    assert depth_dr.fused_bias("D24", depth_bias=0, slope_scaled=1.0, clamp=0.0) is None
    # UNORM: DepthBias * 1 / (2^n - 1), clamped (hand-computed).
    assert depth_dr.fused_bias("D16", depth_bias=2, slope_scaled=0.0, clamp=0.0) == 2 / 65535
    assert depth_dr.fused_bias("D16", depth_bias=9, slope_scaled=0.0, clamp=1e-4) == 1e-4


#: Each shadow-map technique's set-up (where its maps go).
BUILD = {"shadow-map": shadow_map.build, "csm": csm.build, "sdsm": sdsm.build}
PARAMS = {
    "shadow-map": shadow_map.ShadowMapParams,
    "csm": csm.CsmParams,
    "sdsm": sdsm.SdsmParams,
}


def _setup(loaded, technique, values):
    p = params.make(technique, PARAMS[technique], values)
    return BUILD[technique](loaded, trace_gbuffer(loaded), p), p


@pytest.mark.parametrize("fmt", ["D16", "D32F"])
@pytest.mark.parametrize("technique", ["shadow-map", "csm"])
def test_rendered_maps_equal_numpy_reference(technique, fmt):
    """Whole maps: the kernel-finished texels against the NumPy reference applied to the
    cast depths, and the map's Dr.Jit texels are its stored depths."""
    loaded = scenes.load("city" if technique == "csm" else "spot", width=64, height=36)
    setup, p = _setup(loaded, technique, {"format": fmt, "resolution": 96})
    maps = render.render_maps(loaded, setup, p)
    assert sum(m is not None for m in maps) >= 1
    for part, m in zip(setup.partitions, maps, strict=True):
        if m is None:
            continue
        grid, dcoef, _ = render.map_rays(loaded, part.projection, depth_clamp=p.depth_clamp)
        ((_, _, hits),) = raycast.iter_grid(loaded, grid, 96, dcoef)
        want, hit = _numpy_stored(hits["z"], fmt)
        assert m.depth.dtype == np.float32
        assert m.depth.tobytes() == want.reshape(96, 96).tobytes()
        assert m.texels_covered == int(hit.sum()) > 0
        assert m.texels.numpy().tobytes() == m.depth.tobytes()


def test_partition_bounds_equal_bruteforce():
    """Extremes of transformed samples = transformed extremes (monotone rounding)."""
    frame = make_frame(
        np.array([0.3, -1.0, 0.2]), [("world", np.array([0.0, 1.0, 0.0]))], (1.0, 2.0, 3.0)
    )
    pts = RNG.normal(0.0, 50.0, (5000, 3)) + np.array([10.0, 0.0, -4.0])
    gmin = np.array([-200.0, -190.0, -210.0])
    gdim = np.array([400.0, 380.0, 420.0])
    # Partition 2 empty, some samples in none (-1).
    part = RNG.choice(np.array([-1, 0, 1, 3]), size=len(pts), p=[0.1, 0.5, 0.3, 0.1])
    k = 4
    lo, hi, counts = sdsm.partition_texture_bounds(frame, gmin, gdim, pts.copy(), part, k)
    tc = sdsm.to_texture(frame, gmin, gdim, pts)
    for i in range(k):
        sel = tc[part == i]
        assert counts[i] == len(sel)
        if len(sel):
            assert lo[i].tobytes() == sel.min(axis=0).tobytes()
            assert hi[i].tobytes() == sel.max(axis=0).tobytes()
        else:
            assert np.all(lo[i] == np.inf) and np.all(hi[i] == -np.inf)


@pytest.mark.parametrize(
    ("scene_name", "technique", "kw"),
    [
        ("city", "csm", {"receiver_plane_bias": True, "filter": "pcf", "normal_offset": 1.0}),
        ("spot", "shadow-map", {"perspective_normal_offset": 2.0}),
    ],
)
def test_drjit_geometry_launches_and_gathers(monkeypatch, scene_name, technique, kw):
    """The Dr.Jit shading geometry gathers the G-buffer in the kernel: several launches
    (scattered into NumPy arrays) give the bytes of one launch (views), and fresh G-buffer
    columns read a changed G-buffer field."""
    from raster_oracle import raster_models as rm

    loaded = scenes.load(scene_name, width=96, height=54)
    outs = []
    for chunk in (geometry.DRJIT_CHUNK, 777):
        monkeypatch.setattr(geometry, "DRJIT_CHUNK", chunk)
        outs.append(rm.run(technique, loaded, resolution=128, **kw).outputs)
    for key in outs[0]:
        assert outs[1][key].tobytes() == outs[0][key].tobytes(), key
    assert outs[0]["texels_per_pixel"].max() > 0

    setup, p = _setup(loaded, technique, {"resolution": 128, **kw})
    gb = trace_gbuffer(loaded)
    part = next(q for q in setup.partitions if q.projection is not None)
    pix = np.nonzero(gb.valid)[0]
    first = geometry.partition_geometry(p, part, gb, pix, geometry.DrjitColumns(gb))
    # Twice the screen derivatives: twice the texels per pixel.
    gb.dpdx, gb.dpdy = gb.dpdx * 2.0, gb.dpdy * 2.0
    second = geometry.partition_geometry(p, part, gb, pix, geometry.DrjitColumns(gb))
    np.testing.assert_allclose(second["tpp"], 2.0 * first["tpp"], rtol=1e-12)
    assert second["u"].tobytes() == first["u"].tobytes()


def test_gbuffer_launches_equal_one_launch(monkeypatch):
    """Several G-buffer launches (copied into NumPy) give the bytes of one launch (the
    kernel's own arrays as views, (N, 3) fields interleaved by scatters)."""
    loaded = scenes.load("city", width=80, height=45)  # sky and shadowed pixels
    one = gbuffer.trace_gbuffer(loaded, with_lit=True)
    monkeypatch.setattr(gbuffer, "CHUNK", 1000)  # 4 launches, the last one partial
    many = gbuffer.trace_gbuffer(loaded, with_lit=True)
    fields = ("valid", "depth", "position", "normal", "cos_l", "receiver", "dpdx", "dpdy", "lit")
    for name in fields:
        a, b = getattr(one, name), getattr(many, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        assert a.tobytes() == b.tobytes(), name
    assert one.position.shape == (80 * 45, 3)
    assert 0 < one.valid.sum() < one.size and one.receiver.any() and not one.lit.all()


def test_map_texels_lookups(mi):
    """Lookups read a map's Dr.Jit texels: the kernel output a fused map is a view of gives
    the results of an uploaded copy of the NumPy map."""
    r = 64
    texels = mi.Float(RNG.random(r * r).astype(np.float32))
    view = texels.numpy().reshape(r, r)
    copy = filters.upload_texels(view.copy())
    n = 50000
    u, v = RNG.uniform(-0.1, 1.1, n), RNG.uniform(-0.1, 1.1, n)
    ref = np.concatenate([RNG.uniform(-0.2, 1.2, n - len(EDGE[:-1])), EDGE[:-1]])
    for size in (0, 1, 3):
        a = filters.compare_taps(texels, u, v, ref, size, address="clamp", subtexel_bits=8)
        b = filters.compare_taps(copy, u, v, ref, size, address="clamp", subtexel_bits=8)
        assert a.tobytes() == b.tobytes()
        assert 0.0 < a.mean() < 1.0


@pytest.mark.parametrize(
    ("values", "has_texels"),
    [
        ({"slope_scaled_bias": 2.0}, True),  # per-texel bias: texels uploaded after the map
        ({"filter": "vsm"}, False),  # moment filters read the moments
    ],
)
def test_map_texels_follow_the_filter(values, has_texels):
    loaded = scenes.load("city", width=32, height=18)
    setup, p = _setup(loaded, "csm", {"resolution": 64, **values})
    maps = [m for m in render.render_maps(loaded, setup, p) if m is not None]
    assert maps
    for m in maps:
        assert (m.texels is not None) == has_texels
        if has_texels:
            assert m.texels.numpy().tobytes() == m.depth.tobytes()
        else:
            assert m.moments is not None


def test_filter_launches_equal_one_launch(monkeypatch):
    """Several compare launches (copied into NumPy) give the bytes of one (a view)."""
    texels = filters.upload_texels(RNG.random((48, 48)).astype(np.float32))
    u, v, ref = RNG.random(30000), RNG.random(30000), RNG.random(30000)
    one = filters.compare_taps(texels, u, v, ref, 3, address="border", subtexel_bits=8)
    monkeypatch.setattr(filters, "DRJIT_CHUNK", 7000)
    many = filters.compare_taps(texels, u, v, ref, 3, address="border", subtexel_bits=8)
    assert one.tobytes() == many.tobytes()


@pytest.mark.parametrize("values", [{"format": "D24"}, {"format": "D32F", "depth_bias": 4}])
def test_map_launches_equal_one_launch(monkeypatch, values):
    """A map over several launches (copied into NumPy) has the bytes and covered count of
    the single-launch map (a view of the kernel's output), constant or per-texel bias."""
    loaded = scenes.load("city", width=64, height=36)
    setup, p = _setup(loaded, "csm", {"resolution": 80, **values})
    one = render.render_maps(loaded, setup, p)
    monkeypatch.setattr(raycast, "GRID_CHUNK", 1000)  # 7 launches, the last one partial
    monkeypatch.setattr(render, "GRID_CHUNK", 1000)
    many = render.render_maps(loaded, setup, p)
    for a, b in zip(one, many, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            assert a.depth.tobytes() == b.depth.tobytes()
            assert a.texels.numpy().tobytes() == b.texels.numpy().tobytes()
            assert a.texels_covered == b.texels_covered > 0
