"""The Dr.Jit kernels of coherent shadow maps give the bytes of their NumPy references
(``tests/_coherent_reference.py``, compared exactly): visibility intervals (with misses,
edge-on spreads, ties at the stored value) and the greedy run compression of several
orderings at once, with its decoded maps; the stacked ray descriptions equal the one-map
projections within :data:`RAY_TABLE_TOL`."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.coherent import surfaces
from raster_oracle.raster_models.coherent.directions import Projections, map_directions, uv
from raster_oracle.raster_models.coherent.kernels import (
    MAX_CAPTURED,
    below_f32,
    intervals,
    launch_compression,
)
from raster_oracle.raster_models.coherent.rays import ray_table
from raster_oracle.raster_models.coherent.shading import (
    DIRECTIONAL_ROWS,
    direction_error,
    lookup,
    travel,
)
from raster_oracle.raster_models.coherent.surfaces import SPREAD_GUARD, render_intervals
from raster_oracle.scenes import backend

from raster_oracle import scenes
from tests._coherent_reference import below, compress_runs, visibility_intervals

#: Largest |stacked - one-map| value of a ray description, relative to the largest
#: magnitude of its vector (origin A, steps U and V, direction D; the span alone): 8 float64
#: epsilons. The stacked path takes the row norms with one vectorized
#: ``np.linalg.norm(axis=1)``, the one-map path with a dot product per vector: their
#: summations may differ by an ulp, which the frame, matrix inverse and grid carry to a few
#: ulps (measured on plate, city and point at 4 to 16384 maps: 3.0 epsilons at most).
RAY_TABLE_TOL = 8 * np.finfo(np.float64).eps


def _assert_ray_tables_close(table, one):
    assert table.shape == one.shape
    for start in range(0, 13, 3):  # A, U, V, D, then the span
        block = slice(start, start + 3)
        scale = np.abs(one[:, block]).max(axis=1, keepdims=True)
        assert (np.abs(table[:, block] - one[:, block]) <= RAY_TABLE_TOL * scale).all()


@pytest.fixture(scope="module")
def mi():
    return backend.mitsuba()


def _random_surfaces(rng, m):
    """Depths and spreads of every class the intervals distinguish: misses, single
    surfaces, second surfaces just behind, edge-on surfaces (infinite spread) and second
    surfaces closer than the bias (the float32 step below must be taken exactly)."""
    z1 = rng.random(m)
    z1[rng.random(m) < 0.2] = np.inf
    gap = rng.choice([1e-9, 1e-6, 1e-3, 0.02, 0.3], size=m) * rng.random(m)
    z2 = z1 + gap
    z2[(rng.random(m) < 0.3) | ~np.isfinite(z1)] = np.inf
    dz1 = rng.random(m) * 0.004
    dz1[rng.random(m) < 0.02] = np.inf
    dz1[~np.isfinite(z1)] = 0.0
    dz2 = rng.random(m) * 0.004
    dz2[rng.random(m) < 0.02] = np.inf
    dz2[~np.isfinite(z2)] = 0.0
    # Depths that are float32 values exactly: the stored value equals the surface depth.
    exact = rng.random(m) < 0.1
    z1[exact] = z1[exact].astype(np.float32)
    return z1, z2, dz1, dz2


@pytest.mark.parametrize("footprint", [True, False])
@pytest.mark.parametrize("bias", [0.0, 1e-7, 0.005])
def test_drjit_intervals_equal_the_numpy_reference(mi, footprint, bias):
    z1, z2, dz1, dz2 = _random_surfaces(np.random.default_rng(11), 1 << 16)
    spreads = {"dz1": dz1, "dz2": dz2} if footprint else {}
    lo, hi = visibility_intervals(z1, z2, bias, **spreads)
    d_lo, d_hi = intervals(
        mi.Float64(z1),
        mi.Float64(z2),
        bias,
        SPREAD_GUARD,
        **{k: mi.Float64(v) for k, v in spreads.items()},
    )
    assert np.array_equal(d_lo.numpy(), lo)
    assert np.array_equal(d_hi.numpy(), hi)
    assert np.any(hi > lo) and np.any(hi == lo)  # both classes occur


def test_drjit_step_below_equals_nextafter(mi):
    x = np.array([1e-3, 0.5, 1.0, 0.75, 3.0e38, 1e-45, np.inf, 1.0 + 1e-12, 0.1, 0.0, -0.5])
    expect = below(x)
    got = below_f32(mi.Float64(x)).numpy()
    assert np.array_equal(got, expect)
    finite = np.isfinite(x)
    assert np.all(got[finite].astype(np.float64) < x[finite])


@pytest.mark.parametrize(("n", "t"), [(4, 1), (16, 7), (64, 333), (8, 36), (32, 18), (256, 1024)])
def test_drjit_compression_equals_the_numpy_reference(mi, n, t):
    rng = np.random.default_rng(n + t)
    lo = rng.random((n, t), dtype=np.float32)
    # Narrow and wide intervals, exact ties (hi == lo) and cleared texels (hi = inf).
    hi = lo + rng.choice([0.0, 0.01, 0.2, np.inf], size=(n, t)).astype(np.float32)
    orders = [np.arange(n), rng.permutation(n), np.arange(n)[::-1], rng.permutation(n)]
    ref = [compress_runs(lo, hi, o) for o in orders]
    d_lo, d_hi = mi.Float(lo.ravel()), mi.Float(hi.ravel())
    for decode in range(len(orders)):
        runs, decoded = launch_compression(d_lo, d_hi, n, orders, decode=decode)()
        assert runs == [r for r, _ in ref]
        assert decoded.dtype == np.float32 and decoded.shape == (n, t)
        assert np.array_equal(decoded, ref[decode][1])
    runs, decoded = launch_compression(d_lo, d_hi, n, orders, decode=None)()
    assert runs == [r for r, _ in ref] and decoded is None


def _one_map(projs, m: int) -> np.ndarray:
    """The ray description of map ``m`` from its own projection's grid rays."""
    p = projs[m]
    grid = p.grid_rays(float(p.extent[4]), float(p.extent[5]))
    return np.concatenate(
        [grid["A"], grid["U"], grid["V"], grid["D"], [grid["z_end"] - grid["z_start"]]]
    ).astype(np.float64)


@pytest.mark.parametrize("name", ["plate", "city", "point"])
def test_ray_table_equals_the_one_map_path(name):
    """The stacked ray descriptions equal the one-map-at-a-time projections (frame, matrix,
    inverse, grid rays) within :data:`RAY_TABLE_TOL` for every map, at every grid size."""
    s = scenes.load(name, width=16, height=12)
    for n in (4, 64, 1024, 16384):
        dirs, _ = map_directions(n)
        projs = Projections(s, dirs, 32)
        ids = np.arange(n) if n <= 1024 else np.random.default_rng(n).choice(n, 1024)
        table = ray_table(projs, ids)
        one = np.stack([_one_map(projs, int(m)) for m in ids])
        _assert_ray_tables_close(table, one)


def test_ray_table_handles_a_direction_along_the_up_axis():
    """A map looking straight down +-Y takes make_frame's next up hint."""
    s = scenes.load("plate", width=16, height=12)
    dirs = np.array([[0.0, -1.0, 0.0], [0.6, 0.0, 0.8], [0.0, 1.0, 0.0]])
    projs = Projections(s, dirs, 16)
    table = ray_table(projs, np.arange(3))
    one = np.stack([_one_map(projs, m) for m in range(3)])
    _assert_ray_tables_close(table, one)
    assert np.allclose(table[:, 9:12], dirs)


@pytest.mark.parametrize("n_rows", [0, 1, 3, MAX_CAPTURED, MAX_CAPTURED + 1])
def test_drjit_decoded_rows_equal_the_numpy_reference(mi, n_rows):
    """Decoded maps of a few looked-up maps (followed during the walk) and of many (the
    backward pass) are the rows of the NumPy decoding, for every ordering decoded."""
    n, t = 64, 48
    rng = np.random.default_rng(n_rows)
    lo = rng.random((n, t), dtype=np.float32)
    hi = lo + rng.choice([0.0, 0.01, 0.2, np.inf], size=(n, t)).astype(np.float32)
    orders = [np.arange(n), rng.permutation(n), np.arange(n)[::-1]]
    # The first and last positions of every ordering are among the rows.
    rows = np.unique(np.concatenate([[0, n - 1], rng.choice(n, n_rows, replace=False)]))[:n_rows]
    d_lo, d_hi = mi.Float(lo.ravel()), mi.Float(hi.ravel())
    for decode, order in enumerate(orders):
        ref_runs, ref_decoded = compress_runs(lo, hi, order)
        runs, decoded = launch_compression(d_lo, d_hi, n, orders, decode=decode, rows=rows)()
        assert runs[decode] == ref_runs
        assert np.array_equal(decoded, ref_decoded[rows])


def test_directional_lookup_is_the_full_evaluation():
    """A directional light's lookup, evaluated on a slice and broadcast, has the bytes of
    the evaluation over every receiver (map ids and direction errors)."""
    from raster_oracle.raster_models.gbuffer import trace_gbuffer

    s = scenes.load("city", width=160, height=90)
    assert s.light.kind == "directional"
    gbuf = trace_gbuffer(s)
    pos = gbuf.position[gbuf.receiver]
    assert len(pos) > 10 * DIRECTIONAL_ROWS
    dirs, id_tex = map_directions(1024)
    w, sel, shared = lookup(s, pos, id_tex)
    assert shared
    g = id_tex.shape[0]
    w_full = travel(s, pos)
    u, v = uv(w_full)
    sel_full = id_tex[
        np.minimum((v * g).astype(np.int64), g - 1), np.minimum((u * g).astype(np.int64), g - 1)
    ]
    assert w.tobytes() == w_full.tobytes()
    assert np.array_equal(sel, sel_full)
    part = slice(0, DIRECTIONAL_ROWS)
    err = direction_error(np.ascontiguousarray(w[part]), dirs, np.ascontiguousarray(sel[part]))
    full = direction_error(w_full, dirs, sel_full)
    assert np.all(full.view(np.int64) == err[0].view(np.int64))


def test_interval_kernel_launches_do_not_change_the_intervals(monkeypatch):
    """Launching the map kernel in several chunks (scattered into one array) gives the
    bytes of one launch."""
    s = scenes.load("curved", width=16, height=12)
    dirs, _ = map_directions(64)
    projs = Projections(s, dirs, 32)
    one = [a.numpy() for a in render_intervals(s, projs, np.arange(64), 0.005)]
    monkeypatch.setattr(surfaces, "SURFACE_CHUNK", 1000)  # not a multiple of a map
    many = [a.numpy() for a in render_intervals(s, projs, np.arange(64), 0.005)]
    assert one[0].tobytes() == many[0].tobytes() and one[1].tobytes() == many[1].tobytes()
    assert np.any(one[1] > one[0])
