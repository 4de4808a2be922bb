"""Unit tests of the shadow-model building blocks: depth formats, hardware bias, filters,
split schemes, light frames and projections (no ray tracing)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.raster_models import depth, splits
from raster_oracle.raster_models.light_frame import Projection, make_frame
from raster_oracle.raster_models.shadowmaps import depth_dr, filters

from tests._shadow_reference import projection_derivative

RNG = np.random.default_rng(1234)


def tex(depth_map):
    """The Dr.Jit texels the compare filters read (float32, as a rendered map stores)."""
    return filters.upload_texels(depth_map)


# ---------------------------------------------------------------------- depth formats
@pytest.mark.parametrize(("fmt", "bits"), [("D16", 16), ("D24", 24)])
def test_unorm_quantization(mi, fmt, bits):
    d = RNG.random(10000)
    q = depth.quantize_dr(mi, mi.Float64(d), fmt).numpy()
    steps = q * (2**bits - 1)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert np.abs(q - d).max() <= 0.5 / (2**bits - 1) + 1e-12
    clamped = depth.quantize_dr(mi, mi.Float64([-0.5, 1.5]), fmt).numpy()
    np.testing.assert_array_equal(clamped, [0.0, 1.0])


def test_float_quantization_is_float32_rounding(mi):
    d = RNG.random(1000)
    q = depth.quantize_dr(mi, mi.Float64(d), "D32F").numpy()
    np.testing.assert_array_equal(q, d.astype(np.float32))


def test_hardware_bias_units(mi):
    # UNORM: r = 1 / (2^n - 1), the format's smallest value > 0 (D3D11 functional spec; was
    # 2^-n before issue 8); D32F: r = 2^(exponent(z) - 23)
    assert depth.hardware_bias(
        np.array([0.3]), None, "D24", depth_bias=1, slope_scaled=0.0, clamp=0.0
    )[0] == 1.0 / (2**24 - 1)
    assert (
        depth.hardware_bias(
            np.array([0.3]), None, "D16", depth_bias=3, slope_scaled=0.0, clamp=0.0
        )[0]
        == 3.0 / 65535.0
    )
    # One UNORM step: a biased depth moves exactly one representable value.
    d = depth.quantize_dr(mi, mi.Float64([0.5]), "D16").numpy()
    b = depth.hardware_bias(d, None, "D16", depth_bias=1, slope_scaled=0.0, clamp=0.0)
    assert depth.quantize_dr(mi, mi.Float64(d + b), "D16").numpy()[0] == d[0] + 1.0 / 65535.0
    b = depth.hardware_bias(
        np.array([0.5, 0.3, 0.9]), None, "D32F", depth_bias=1, slope_scaled=0.0, clamp=0.0
    )
    np.testing.assert_array_equal(b, [2.0**-24, 2.0**-25, 2.0**-24])
    slope = np.array([0.01, 1e9])
    b = depth.hardware_bias(
        np.array([0.5, 0.5]), slope, "D24", depth_bias=0, slope_scaled=2.0, clamp=0.0
    )
    np.testing.assert_allclose(b, [0.02, 2.0 * depth.MAX_DEPTH_SLOPE])
    b = depth.hardware_bias(
        np.array([0.5]), np.array([0.01]), "D24", depth_bias=0, slope_scaled=2.0, clamp=0.005
    )
    assert b[0] == 0.005


def test_depth_bias_is_added_before_the_viewport_clamp(mi):
    # A pancaked caster (z < 0, in front of the near plane) stays at 0 whatever its bias: the
    # rasterizer adds the bias, then clamps (before issue 8 the clamp came first and the
    # caster was pushed to the bias). Values above 1 stay at 1.
    z = np.array([-0.5, -1e-3, 0.3, 0.99999, 1.5])
    r = 1.0 / (2**24 - 1)
    bias = depth_dr.fused_bias("D24", depth_bias=1000, slope_scaled=0.0, clamp=0.0)
    assert bias == 1000 * r
    out, hit = depth_dr.stored_depth_dr(mi, mi.Float64(z), "D24", bias)
    # D24 UNORM by hand: k / (2^24 - 1) for the nearest step k.
    steps = 2.0**24 - 1.0
    want = np.round(np.array([0.0, 0.0, 0.3 + 1000 * r, 1.0, 1.0]) * steps) / steps
    np.testing.assert_array_equal(out.numpy(), want.astype(np.float32))
    assert hit.numpy().all()
    plain, _ = depth_dr.stored_depth_dr(mi, mi.Float64(z), "D24", 0.0)
    want = (np.round(np.clip(z, 0, 1) * steps) / steps).astype(np.float32)
    np.testing.assert_array_equal(plain.numpy(), want)


# ---------------------------------------------------------------------- filters
def test_point_and_bilinear_compare_on_a_step():
    # Left half of the map at depth 0.2 (occluder), right half at 1.0.
    r = 8
    depth_map = np.ones((r, r))
    depth_map[:, : r // 2] = 0.2
    v = np.full(5, 0.5)
    u = (np.array([3.5, 4.0, 4.25, 4.5, 5.5])) / r  # texel centres at (i + 0.5) / r
    ref = np.full(5, 0.5)
    np.testing.assert_array_equal(filters.compare_point(tex(depth_map), u, v, ref), [0, 1, 1, 1, 1])
    got = filters.compare_bilinear(tex(depth_map), u, v, ref, subtexel_bits=0)
    # Bilinear PCF: 0 at the last occluded texel centre, 1 at the first lit one.
    np.testing.assert_allclose(got, [0.0, 0.5, 0.75, 1.0, 1.0])


def test_bilinear_subtexel_precision():
    depth_map = np.array([[0.0, 1.0], [0.0, 1.0]])
    u = np.array([0.25 + 0.5 * 0.3001])  # fraction 0.3001 between the two texel centres
    got8 = filters.compare_bilinear(tex(depth_map), u, np.array([0.5]), np.array([0.5]))
    exact = filters.compare_bilinear(
        tex(depth_map), u, np.array([0.5]), np.array([0.5]), subtexel_bits=0
    )
    assert exact[0] == pytest.approx(0.3001)
    assert got8[0] == round(0.3001 * 256) / 256


def test_address_modes():
    depth_map = np.zeros((4, 4))  # everything occluded
    u = np.array([-0.5, 1.5, 0.5])
    v = np.array([0.5, 0.5, 0.5])
    ref = np.full(3, 0.5)
    np.testing.assert_array_equal(
        filters.compare_point(tex(depth_map), u, v, ref, address="clamp"), [0, 0, 0]
    )
    np.testing.assert_array_equal(
        filters.compare_point(tex(depth_map), u, v, ref, address="border"), [1, 1, 0]
    )


@pytest.mark.parametrize("size", [1, 2, 3, 5])
@pytest.mark.parametrize("address", ["clamp", "border"])
def test_pcf_footprint_equals_sum_of_taps(size, address):
    depth_map = RNG.random((32, 32))
    u, v, ref = RNG.random(3000) * 1.2 - 0.1, RNG.random(3000) * 1.2 - 0.1, RNG.random(3000)
    fast = filters.pcf_grid(tex(depth_map), u, v, ref, size, address=address)
    zero_plane = (np.zeros(3000), np.zeros(3000))
    taps = filters.pcf_grid(tex(depth_map), u, v, ref, size, address=address, plane=zero_plane)
    np.testing.assert_allclose(fast, taps, atol=1e-12)
    if size == 1:
        np.testing.assert_array_equal(
            fast, filters.compare_bilinear(tex(depth_map), u, v, ref, address=address)
        )


def test_receiver_plane_tilts_each_tap():
    # A receiver exactly on a tilted plane (stored depth = receiver plane): with the plane
    # slopes every tap compares against its own depth and, with one texel's worth of static
    # bias for the 2x2 footprint of each tap (MJP's fractional sampling error), the receiver
    # is fully lit; without them the taps on the near side shadow it.
    r = 64
    jj, ii = np.mgrid[0:r, 0:r]
    slope_u = 0.3
    depth_map = 0.2 + slope_u * (ii + 0.5) / r
    u = np.array([0.5]) + 0.25 / r
    v = np.array([0.5])
    ref = 0.2 + slope_u * u - slope_u / r
    flat = filters.pcf_grid(tex(depth_map), u, v, ref, 5, subtexel_bits=0)
    tilted = filters.pcf_grid(
        tex(depth_map), u, v, ref, 5, subtexel_bits=0, plane=(np.array([slope_u]), np.zeros(1))
    )
    assert flat[0] < 0.9
    assert tilted[0] == pytest.approx(1.0)


def test_poisson_disc_is_a_spread_deterministic_pattern():
    a = filters.poisson_disc(16, 0)
    assert a.shape == (16, 2)
    assert (np.hypot(a[:, 0], a[:, 1]) <= 1.0).all()
    d = np.hypot(*(a[:, None, :] - a[None, :, :]).transpose(2, 0, 1))
    d[np.diag_indices(16)] = np.inf
    assert d.min() > 0.25
    np.testing.assert_array_equal(a, filters.poisson_disc(16, 0))
    assert not np.array_equal(a, filters.poisson_disc(16, 1))


def test_chebyshev_bound():
    m1 = np.full(4, 0.5)
    m2 = m1 * m1 + 0.01
    mean = np.array([0.4, 0.5, 0.6, 0.9])
    p = filters.chebyshev(m1, m2, mean, 1e-4, 0.0)
    assert p[0] == 1.0 and p[1] == 1.0
    assert p[2] == pytest.approx(0.01 / (0.01 + 0.01))
    assert p[3] < p[2]
    reduced = filters.chebyshev(m1, m2, mean, 1e-4, 0.5)
    assert reduced[2] == pytest.approx(0.0) and reduced[0] == 1.0


def test_evsm_exponent_limits():
    assert filters.evsm_exponents(800, 100, "float32") == (42.0, 42.0)
    assert filters.evsm_exponents(40, 5, "float16") == (5.54, 5.0)
    assert filters.evsm_exponents(800, 100, "float32", scale=0.01) == (8.0, 1.0)


@pytest.mark.parametrize("kind", ["vsm", "evsm2", "evsm4"])
def test_moment_filters_on_a_flat_occluder(kind):
    depth_map = np.full((16, 16), 0.3)
    exps = (40.0, 5.0) if kind != "vsm" else (0.0, 0.0)
    m = filters.blur_moments(filters.moments_from_depth(depth_map, kind, exps), 3, "float32")
    u = v = np.full(3, 0.5)
    vis = filters.moment_lookup(
        m,
        u,
        v,
        np.array([0.2, 0.3, 0.8]),
        kind,
        exponents=exps,
        min_variance=1e-4,
        bleed_reduction=0.0,
    )
    # In front of / at the occluder: lit (up to the float32 rounding of stored moments).
    np.testing.assert_allclose(vis[:2], 1.0, atol=1e-6)
    assert vis[2] < 0.01


@pytest.mark.parametrize("kind", ["vsm", "evsm2", "evsm4"])
@pytest.mark.parametrize("fmt", ["float32", "float16"])
@pytest.mark.parametrize("size", [1, 5])
def test_banded_moment_texture_equals_the_whole_map(monkeypatch, kind, fmt, size):
    """Bands of 7 rows / 5 columns (bands that do not divide the map) give the same bytes."""
    depth_map = np.random.default_rng(3).random((37, 23))
    exps = filters.evsm_exponents(40.0, 5.0, fmt) if kind != "vsm" else (0.0, 0.0)
    whole = filters.blur_moments(filters.moments_from_depth(depth_map, kind, exps), size, fmt)
    monkeypatch.setattr(filters, "MOMENT_BAND_TEXELS", 7 * 23)
    banded = filters.moment_texture(depth_map, kind, exps, size, fmt)
    assert banded.dtype == whole.dtype and banded.shape == whole.shape
    assert banded.tobytes() == whole.tobytes()


# ---------------------------------------------------------------------- splits
def test_split_formulas():
    n, f, k = 0.1, 2000.0, 4
    np.testing.assert_allclose(splits.log_splits(n, f, k), n * (f / n) ** (np.arange(5) / 4))
    np.testing.assert_allclose(splits.uniform_splits(n, f, k), n + (f - n) * np.arange(5) / 4)
    for lam in (0.0, 0.5, 0.8, 1.0):
        c = splits.practical_splits(n, f, k, lam)
        i = np.arange(5)
        want = lam * n * (f / n) ** (i / k) + (1 - lam) * (n + (f - n) * i / k)
        np.testing.assert_allclose(c, want, rtol=1e-12)
    np.testing.assert_allclose(
        splits.manual_splits(1.0, 11.0, (0.05, 0.15, 0.5, 1.0)), [1, 1.5, 2.5, 6, 11]
    )


def _log_uniform_samples(n, zmin, zmax):
    z = zmin * (zmax / zmin) ** RNG.random(n)
    return z, np.stack([z, z, z], axis=1)


def test_histogram_log_partitions_follow_log_splits():
    z, lc = _log_uniform_samples(200000, 5.0, 500.0)
    h = splits.build_histogram(z, lc, 0.1, 2000.0, 1024, 10.0)
    assert h.count.sum() == len(z)
    ends = splits.log_bins(h, 4)
    edges = h.bin_to_z(ends[:-1])
    want = splits.log_splits(5.0, 500.0, 4)[1:-1]
    np.testing.assert_allclose(edges, want, rtol=0.02)  # 1024 warped bins
    # Bins hold their samples' bounds.
    b = h.z_to_bin(z)
    assert (h.lo[b, 0] <= z).all() and (h.hi[b, 0] >= z).all()


def test_adaptive_log_skips_empty_bins_and_kmeans_centres_clusters():
    # Two clusters of depths: near 2-3 and far 900-1000, nothing between.
    z = np.concatenate([RNG.uniform(2, 3, 5000), RNG.uniform(900, 1000, 5000)])
    lc = np.stack([z, z, z], axis=1)
    h = splits.build_histogram(z, lc, 0.1, 2000.0, 1024, 10.0)
    ends = splits.adaptive_log_bins(h, 4)
    assert (np.diff(ends) >= 0).all() and ends[-1] == h.bins
    populated = h.count > 0
    for b in ends[:-1]:
        assert b == h.bins or populated[b], "each split is pushed to a populated bin"
    km = splits.kmeans_bins(h, 2, 32)
    split = h.bin_to_z(km[0])
    assert 3.0 < split < 900.0  # the split separates the clusters


# ---------------------------------------------------------------------- frames, projections
@pytest.mark.parametrize(
    "up", [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 1.0, 1e-9), (0.0, 0.0, 0.0)]
)
def test_light_frame_degenerate_up_falls_back(up):
    frame = make_frame((0.0, -1.0, 0.0), [("hint", up)])
    rot = frame.rotation()
    assert np.isfinite(rot).all()
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(frame.z, [0, -1, 0])
    assert frame.up_used != "hint"


def test_orthographic_projection_maps_its_box_to_the_unit_cube():
    frame = make_frame((0.3, -1.0, 0.2), [("world_y", (0, 1, 0))])
    proj = Projection("ortho", frame, (-2.0, 3.0, -1.0, 4.0, -5.0, 5.0), 64)
    lc = np.array([[-2, -1, -5], [3, 4, 5], [0.5, 1.5, 0]], dtype=float)
    world = lc @ frame.rotation()
    u, v, z, w = proj.project(world)
    np.testing.assert_allclose(u, [0, 1, 0.5], atol=1e-12)
    np.testing.assert_allclose(v, [1, 0, 0.5], atol=1e-12)  # v runs down from +y
    np.testing.assert_allclose(z, [0, 1, 0.5], atol=1e-12)
    np.testing.assert_allclose(w, 1.0)
    assert proj.texel_world_size() == pytest.approx(5.0 / 64)


def test_perspective_projection_and_derivative():
    frame = make_frame((0.0, -1.0, 0.2), [("world_y", (0, 1, 0))], origin=(1.0, 5.0, 0.0))
    tan_half = math.tan(math.radians(35))
    proj = Projection("persp", frame, (tan_half, 0.5, 20.0), 256)
    local = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 20.0], [tan_half * 3, -tan_half * 3, 3.0]])
    world = local @ frame.rotation() + frame.origin
    u, v, z, w = proj.project(world)
    np.testing.assert_allclose(z[:2], [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose([u[2], v[2]], [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(w, [0.5, 20.0, 3.0])
    p = world[2:3] + np.array([[0.3, -0.2, 0.1]])
    u, v, z, w = proj.project(p)
    d = projection_derivative(proj, u, v, z, w)[0]
    eps = 1e-6
    for axis in range(3):
        dp = p.copy()
        dp[0, axis] += eps
        u2, v2, z2, _ = proj.project(dp)
        num = (np.array([u2[0], v2[0], z2[0]]) - np.array([u[0], v[0], z[0]])) / eps
        np.testing.assert_allclose(d[:, axis], num, rtol=1e-4, atol=1e-7)


def test_float32_projection_rounds_the_matrix():
    frame = make_frame((0.3, -1.0, 0.2), [("world_y", (0, 1, 0))])
    p64 = Projection("ortho", frame, (1e5, 1e5 + 10, -1.0, 9.0, -5.0, 5.0), 1024)
    p32 = Projection("ortho", frame, (1e5, 1e5 + 10, -1.0, 9.0, -5.0, 5.0), 1024, "float32")
    assert p32.matrix_used.dtype == np.float32
    np.testing.assert_array_equal(p32.matrix, p32.matrix_used.astype(np.float64))
    assert not np.array_equal(p32.matrix, p64.matrix)
