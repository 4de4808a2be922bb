"""Hostile geometry in exact coverage (issue 35 / 39): bounded time and memory through the
budget, no crash; where it cannot be exact it says so and the Monte Carlo truth is used."""

from __future__ import annotations

import time

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import EXACT_BUDGET_S
from raster_oracle.scenes.camera import Camera, look_at
from raster_oracle.scenes.geometry.exact_coverage import (
    NotExact,
    OutOfTime,
    OverBudget,
    TriangleSet,
    estimate_cost,
    exact_coverage_of,
)

W, H = 32, 18
#: Deadline of the hostile cases the estimate lets through (seconds).
DEADLINE_S = 10.0


def _camera(near=0.1, far=100.0):
    return Camera("perspective", look_at((0, 0, -10), (0, 0, 0)), W, H, near, far, 40.0)


def _tset(tris, shape=None):
    tris = np.asarray(tris, np.float64)
    shape = np.zeros(len(tris), np.int64) if shape is None else shape
    return TriangleSet(tris, shape, np.zeros(len(tris)))


def _in_one_pixel(rng, n, *, coplanar=False, spread=0.001):
    """``n`` triangles inside one pixel around the optical axis at depth 10 (one shape):
    crossing each other at random depths, or all in the plane z = 0."""
    c = rng.uniform(-spread, spread, (n, 3, 3))
    c[..., 2] = 0.0 if coplanar else rng.uniform(-0.5, 0.5, (n, 3))
    return _tset(c)


def _centre():
    return np.full(W * H, -1, np.int64)


@pytest.mark.parametrize(
    ("n", "coplanar"),
    [(10_000, False), (100_000, True), (1_000_000, False)],
    ids=["1e4-interpenetrating", "1e5-coplanar", "1e6"],
)
def test_many_triangles_in_one_pixel_are_refused_by_the_budget(n, coplanar):
    """10^4 crossing, 10^5 coplanar or 10^6 triangles in one pixel: the estimate (NumPy,
    chunked) counts their pairs; the default budget refuses the larger two before any
    polygon operation, and the smallest (estimated within it: one shape, no depth order to
    resolve) is stopped by its deadline if the estimate is wrong (no segfault, no hang)."""
    tset = _in_one_pixel(np.random.default_rng(n), n, coplanar=coplanar)
    est = estimate_cost(_camera(), tset)
    assert est["triangles"] == n
    assert est["pairs"] >= n * (n - 1) // 2
    t0 = time.perf_counter()
    deadline = t0 + DEADLINE_S
    try:
        exact_coverage_of(_camera(), tset, _centre(), budget=EXACT_BUDGET_S, deadline=deadline)
    except (OverBudget, OutOfTime) as exc:
        assert n == 10_000 or isinstance(exc, OverBudget)
    else:
        assert n == 10_000
    assert time.perf_counter() - t0 < DEADLINE_S + 10.0  # chunks between checks, a loaded machine


def test_a_few_crossing_triangles_in_one_pixel_are_exact():
    """The same geometry small enough for the budget is computed; a pixel's coverage is at
    most 1 and the rest of the film is empty."""
    tset = _in_one_pixel(np.random.default_rng(1), 50)
    ex = exact_coverage_of(_camera(), tset, _centre(), budget=EXACT_BUDGET_S)
    assert ex.coverage.max() <= 1.0 and ex.coverage.sum() > 0
    assert np.count_nonzero(ex.coverage) <= 4  # the pixels around the axis


@pytest.mark.parametrize("where", ["behind", "nearer than near", "beyond far"])
def test_nothing_in_view_gives_empty_exact_channels(where):
    """Every triangle behind the camera, nearer than the near plane or beyond the far one:
    zero coverage everywhere, exactly (no IndexError), front coverage 1 on the sky."""
    z = {"behind": -20.0, "nearer than near": -9.95, "beyond far": 200.0}[where]
    tris = [[[-1, -1, z], [1, -1, z], [0, 1, z]], [[-2, -1, z], [2, -1, z], [0, 3, z]]]
    ex = exact_coverage_of(_camera(), _tset(tris), _centre(), budget=EXACT_BUDGET_S)
    assert ex.stats["method"] == "empty"
    assert not ex.coverage.any() and ex.valid.all() and (ex.front_coverage == 1.0).all()


@pytest.mark.parametrize("size", [1e30, 1e38])
def test_a_huge_ground_is_not_passed_off_as_exact(size):
    """A ground of +-1e30 or +-1e38 cannot be clipped exactly in float64: NotExact, not a
    silently wrong channel."""
    g = [[-size, -1.0, -size], [size, -1.0, -size], [size, -1.0, size], [-size, -1.0, size]]
    g = np.array(g, np.float32).astype(np.float64)  # Mitsuba's float32 vertices
    tris = np.stack([g[[0, 1, 2]], g[[0, 2, 3]]])
    with pytest.raises(NotExact, match="coordinates too large"):
        exact_coverage_of(_camera(), _tset(tris), _centre(), budget=EXACT_BUDGET_S)


def test_not_exact_falls_back_to_the_monte_carlo_truth(capsys):
    """Through the reference: one line on stderr, valid 0 everywhere, the decision recorded."""
    from raster_oracle.oracle.reference.coverage import exact_channels
    from raster_oracle.scenes.geometry import exact_coverage as ec
    from raster_oracle.scenes.loader import load

    loaded = load("plate", width=W, height=H)
    loaded.memo[ec.MEMO_KEY] = {"planar": _tset(_huge_ground())}
    channels, record = exact_channels(loaded, np.zeros(W * H, np.int64), {})
    assert record["decision"].startswith("not exact: coordinates too large")
    assert not channels["coverage_exact_valid"].any()
    err = [line for line in capsys.readouterr().err.splitlines() if "coverage_exact" in line]
    assert len(err) == 1 and "Monte Carlo" in err[0]


def _huge_ground():
    s = 1e30
    return [[[-s, -1, -s], [s, -1, -s], [s, -1, s]], [[-s, -1, -s], [s, -1, s], [-s, -1, s]]]
