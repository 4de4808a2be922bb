"""The fast paths of the shadow-map models give the bytes of the plain NumPy paths they
replace: the Dr.Jit texel post-processing of :mod:`raster_models.shadowmaps.depth_dr`, SDSM's
per-partition bounds from light-frame extremes, and the Dr.Jit gathers of the shading
geometry. Equality is exact (``tobytes``), on random and edge inputs."""

from __future__ import annotations

import numpy as np
import pytest

import scenes
from raster_models import depth as _depth
from raster_models.light_frame import make_frame
from raster_models.shadowmaps import depth_dr as _depth_dr
from raster_models.shadowmaps import render as _render
from raster_models.shadowmaps import sdsm

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


def _numpy_stored(z, fmt, depth_bias, clamp):
    """The NumPy path of ``_render._render_one`` (no slope-scaled bias)."""
    hit = np.isfinite(z)
    d = _depth.rasterized_depth(
        np.where(hit, z, 1.0), None, fmt, depth_bias=depth_bias, clamp=clamp
    )
    return np.where(hit, _depth.quantize(d, fmt), 1.0).astype(np.float32), hit


@pytest.mark.parametrize("fmt", sorted(_depth.FORMATS))
@pytest.mark.parametrize(("depth_bias", "clamp"), [(0, 0.0), (3, 0.0), (-40, -1e-4), (900, 2e-5)])
def test_stored_depth_dr_matches_numpy(mi, fmt, depth_bias, clamp):
    bias = _depth_dr.fused_bias(fmt, depth_bias=depth_bias, slope_scaled=0.0, clamp=clamp)
    if bias is None:
        # D32F's DepthBias scales with each texel's exponent: the NumPy path keeps it.
        assert fmt == "D32F" and depth_bias != 0
        return
    z = np.concatenate([EDGE, RNG.uniform(-0.2, 1.2, 20000), RNG.random(20000)])
    # Exact UNORM ties after scaling (round-half-even must agree).
    steps = float((1 << _depth.FORMATS[fmt][1]) - 1)
    z = np.concatenate([z, (np.arange(200) + 0.5) / steps])
    want, want_hit = _numpy_stored(z, fmt, depth_bias, clamp)
    got, got_hit = _depth_dr.stored_depth_dr(mi, mi.Float64(z), fmt, bias)
    got = got.numpy()
    assert got.dtype == np.float32
    assert got.tobytes() == want.tobytes()
    np.testing.assert_array_equal(got_hit.numpy(), want_hit)


def test_fused_bias_only_for_constant_bias():
    assert _depth_dr.fused_bias("D32F", depth_bias=0, slope_scaled=0.0, clamp=0.0) == 0.0
    assert _depth_dr.fused_bias("D32F", depth_bias=1, slope_scaled=0.0, clamp=0.0) is None
    assert _depth_dr.fused_bias("D24", depth_bias=0, slope_scaled=1.0, clamp=0.0) is None
    # UNORM: DepthBias * 1 / (2^n - 1), clamped (hand-computed).
    assert _depth_dr.fused_bias("D16", depth_bias=2, slope_scaled=0.0, clamp=0.0) == 2 / 65535
    assert _depth_dr.fused_bias("D16", depth_bias=9, slope_scaled=0.0, clamp=1e-4) == 1e-4


@pytest.mark.parametrize("fmt", ["D16", "D32F"])
@pytest.mark.parametrize("technique", ["shadow-map", "csm"])
def test_fused_maps_equal_numpy_maps(monkeypatch, technique, fmt):
    """Whole maps: the kernel-finished texels against the NumPy post-processing."""
    import raster_models
    from raster_models.gbuffer import trace_gbuffer
    from raster_models.registry import TECHNIQUES

    loaded = scenes.load("city" if technique == "csm" else "spot", width=64, height=36)
    tech = TECHNIQUES[technique]
    module = __import__(tech.runner.__module__, fromlist=["build"])
    p = raster_models.params.make(technique, tech.params, {"format": fmt, "resolution": 96})
    setup = module.build(loaded, trace_gbuffer(loaded), p)
    fused = _render.render_maps(loaded, setup, p)
    monkeypatch.setattr(_render, "fused_bias", lambda *a, **k: None)
    plain = _render.render_maps(loaded, setup, p)
    assert sum(m is not None for m in fused) >= 1
    for a, b in zip(fused, plain, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            assert a.depth.dtype == np.float32
            assert a.depth.tobytes() == b.depth.tobytes()
            assert a.texels_covered == b.texels_covered
            assert a.texels_covered > 0


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
    lo, hi, counts = sdsm._partition_texture_bounds(frame, gmin, gdim, pts.copy(), part, k)
    tc = sdsm._to_texture(frame, gmin, gdim, pts)
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
    (scattered into NumPy arrays) give the bytes of one launch (views), and a G-buffer whose
    field is replaced is gathered from the new field, not the uploaded copy."""
    import raster_models as rm
    from raster_models.gbuffer import trace_gbuffer
    from raster_models.shadowmaps import shade as _shade

    loaded = scenes.load(scene_name, width=96, height=54)
    monkeypatch.setattr(_shade, "DRJIT_MIN_PIXELS", 1)
    outs = []
    for chunk in (_shade.DRJIT_CHUNK, 777):
        monkeypatch.setattr(_shade, "DRJIT_CHUNK", chunk)
        outs.append(rm.run(technique, loaded, resolution=128, **kw).outputs)
    for key in outs[0]:
        assert outs[1][key].tobytes() == outs[0][key].tobytes(), key
    assert outs[0]["texels_per_pixel"].max() > 0

    tech = rm.TECHNIQUES[technique]
    module = __import__(tech.runner.__module__, fromlist=["build"])
    p = rm.params.make(technique, tech.params, {"resolution": 128, **kw})
    gb = trace_gbuffer(loaded)
    setup = module.build(loaded, gb, p)
    part = next(q for q in setup.partitions if q.projection is not None)
    pix = np.nonzero(gb.valid)[0]
    first = _shade._partition_geometry(p, part, gb, pix)
    # Twice the screen derivatives: twice the texels per pixel.
    gb.dpdx, gb.dpdy = gb.dpdx * 2.0, gb.dpdy * 2.0
    second = _shade._partition_geometry(p, part, gb, pix)
    np.testing.assert_allclose(second["tpp"], 2.0 * first["tpp"], rtol=1e-12)
    assert second["u"].tobytes() == first["u"].tobytes()


def test_gbuffer_launches_equal_one_launch(monkeypatch):
    """Several G-buffer launches (copied into NumPy) give the bytes of one launch (the
    kernel's own arrays as views, (N, 3) fields interleaved by scatters)."""
    from raster_models import gbuffer as _gbuffer

    loaded = scenes.load("city", width=80, height=45)  # sky and shadowed pixels
    one = _gbuffer.trace_gbuffer(loaded, with_lit=True)
    monkeypatch.setattr(_gbuffer, "CHUNK", 1000)  # 4 launches, the last one partial
    many = _gbuffer.trace_gbuffer(loaded, with_lit=True)
    fields = ("valid", "depth", "position", "normal", "cos_l", "receiver", "dpdx", "dpdy", "lit")
    for name in fields:
        a, b = getattr(one, name), getattr(many, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        assert a.tobytes() == b.tobytes(), name
    assert one.position.shape == (80 * 45, 3)
    assert 0 < one.valid.sum() < one.size and one.receiver.any() and not one.lit.all()


def test_registered_texture_lookups(mi):
    """A map that is a view of a Dr.Jit array is looked up from that array: same results as
    an uploaded copy, one kernel output per launch or several, and the registry entry leaves
    with the map."""
    import gc

    from raster_models.shadowmaps import filters as _filters

    r = 64
    texels = mi.Float(RNG.random(r * r).astype(np.float32))
    view = texels.numpy().reshape(r, r)
    copy = view.copy()
    _filters.register_drjit_texture(view, texels)
    n = 50000
    u, v = RNG.uniform(-0.1, 1.1, n), RNG.uniform(-0.1, 1.1, n)
    ref = np.concatenate([RNG.uniform(-0.2, 1.2, n - len(EDGE[:-1])), EDGE[:-1]])
    for size in (0, 1, 3):
        a = _filters.compare_taps_drjit(view, u, v, ref, size, address="clamp", subtexel_bits=8)
        b = _filters.compare_taps_drjit(copy, u, v, ref, size, address="clamp", subtexel_bits=8)
        assert a.tobytes() == b.tobytes()
        assert 0.0 < a.mean() < 1.0
    key = id(view)
    assert key in _filters._DRJIT_TEXTURES
    del view
    gc.collect()
    assert key not in _filters._DRJIT_TEXTURES


def test_filter_launches_equal_one_launch(monkeypatch):
    """Several compare launches (copied into NumPy) give the bytes of one (a view)."""
    from raster_models.shadowmaps import filters as _filters

    depth = RNG.random((48, 48)).astype(np.float32)
    u, v, ref = RNG.random(30000), RNG.random(30000), RNG.random(30000)
    one = _filters.compare_taps_drjit(depth, u, v, ref, 3, address="border", subtexel_bits=8)
    monkeypatch.setattr(_filters, "DRJIT_CHUNK", 7000)
    many = _filters.compare_taps_drjit(depth, u, v, ref, 3, address="border", subtexel_bits=8)
    assert one.tobytes() == many.tobytes()


def test_fused_map_launches_equal_one_launch(monkeypatch):
    """A map finished in the kernel over several launches (copied into NumPy) has the bytes
    and covered count of the single-launch map (a view of the kernel's output)."""
    import raster_models as rm
    from raster_models.gbuffer import trace_gbuffer
    from raster_models.shadowmaps import raycast as _raycast

    loaded = scenes.load("city", width=64, height=36)
    p = rm.params.make("csm", rm.CsmParams, {"resolution": 80, "format": "D24"})
    setup = rm.shadowmaps.csm.build(loaded, trace_gbuffer(loaded), p)
    one = _render.render_maps(loaded, setup, p)
    monkeypatch.setattr(_raycast, "GRID_CHUNK", 1000)  # 7 launches, the last one partial
    monkeypatch.setattr(_render, "GRID_CHUNK", 1000)
    many = _render.render_maps(loaded, setup, p)
    for a, b in zip(one, many, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            assert a.depth.tobytes() == b.depth.tobytes()
            assert a.texels_covered == b.texels_covered > 0
