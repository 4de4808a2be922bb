"""IZB list build (orthographic grids, 32 samples): the Dr.Jit kernels against the NumPy
reference of ``tests/_izb_reference.py`` (exactly), and both against the definition (every
texel one of the 32 points falls in)."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.izb import build
from raster_oracle.raster_models.izb.build import Ortho32Build, grid, texel
from raster_oracle.raster_models.izb.lists import build_lists
from raster_oracle.scenes.geometry.tangent32 import tangent_offsets

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests._izb_reference import (
    BUILD_TOLERANCE,
    one_texel,
    ortho32_bounds,
    ortho32_nodes,
)

#: Grid texels per side of the synthetic cases: texels of a few units, points spread over 0
#: to several texels.
R = 64


def _receivers(rng, n=20000):
    """Light-frame centres and derivatives: most receivers inside one texel, some across a
    few, some over many; a few with zero derivatives (their box is a point)."""
    lc = rng.uniform(-50.0, 50.0, (n, 3))
    ldx = rng.normal(0.0, 0.3, (n, 3)) * rng.uniform(0.0, 1.0, (n, 1)) ** 3
    ldy = rng.normal(0.0, 0.3, (n, 3)) * rng.uniform(0.0, 1.0, (n, 1)) ** 3
    ldx[:50] *= 40.0  # over many texels
    ldx[50:100] = ldy[50:100] = 0.0
    return lc, ldx, ldy


def _point_texels(lc, ldx, ldy, box):
    """``(n, 32)`` texel ids of every point, as the definition reads."""
    a, b = tangent_offsets()
    x = lc[:, 0, None] + ldx[:, 0, None] * a + ldy[:, 0, None] * b
    y = lc[:, 1, None] + ldx[:, 1, None] * a + ldy[:, 1, None] * b
    i, j = texel(x, y, box, R)
    return j * R + i


def test_one_texel_receivers_have_every_point_in_that_texel():
    """The build's shortcut: a receiver whose point box lies in one texel gets that texel,
    and every one of its 32 points (computed as the full path does) falls in it."""
    lc, ldx, ldy = _receivers(np.random.default_rng(3))
    a, b = tangent_offsets()
    spread = np.abs(ldx) * np.abs(a).max() + np.abs(ldy) * np.abs(b).max()
    box = grid((lc - spread).min(axis=0)[:2], (lc + spread).max(axis=0)[:2])
    one, t = one_texel(lc, spread, box, R)
    texels = _point_texels(lc, ldx, ldy, box)
    assert 0.2 < one.mean() < 0.95  # both paths exercised
    np.testing.assert_array_equal(texels[one], np.repeat(t[one, None], 32, axis=1))
    assert (texels[~one] != texels[~one, :1]).any(axis=1).mean() > 0.5


@pytest.mark.parametrize("subset", [False, True])
def test_drjit_build_equals_numpy_and_the_definition(monkeypatch, subset):
    rng = np.random.default_rng(11)
    lc, ldx, ldy = _receivers(rng)
    a, b = tangent_offsets()
    sel = np.flatnonzero(rng.uniform(size=len(lc)) < 0.6) if subset else None
    monkeypatch.setattr(build, "DRJIT_BUILD_CHUNK", 4099)  # several launches
    fast = Ortho32Build(lc, ldx, ldy, a, b)
    lo, hi = fast.bounds(sel)
    box = grid(lo[:2], hi[:2])
    out = {True: (lo, hi, *fast.nodes(sel, box, R))}
    ref_lo, ref_hi = ortho32_bounds(lc, ldx, ldy, a, b, sel)
    ref = ortho32_nodes(lc, ldx, ldy, a, b, sel, box, R, chunk=3001)
    out[False] = (ref_lo, ref_hi, *ref)
    for x, y in zip(out[False], out[True], strict=True):
        assert x.dtype == y.dtype
        np.testing.assert_allclose(x, y, rtol=0, atol=BUILD_TOLERANCE)

    # The definition: bounds contain every point; nodes = distinct (receiver, texel) pairs.
    lo, hi, centre, node_texel, node_recv = out[True]
    idx = np.arange(len(lc)) if sel is None else sel
    spread = np.abs(ldx) * np.abs(a).max() + np.abs(ldy) * np.abs(b).max()
    np.testing.assert_array_equal(lo, (lc[idx] - spread[idx]).min(axis=0))
    np.testing.assert_array_equal(hi, (lc[idx] + spread[idx]).max(axis=0))
    box = grid(lo[:2], hi[:2])
    ci, cj = texel(lc[idx, 0], lc[idx, 1], box, R)
    np.testing.assert_array_equal(centre, cj * R + ci)
    texels = _point_texels(lc[idx], ldx[idx], ldy[idx], box)
    pairs = np.unique(np.stack([np.repeat(idx, 32), texels.ravel()], axis=1), axis=0)
    got = np.stack([node_recv, node_texel], axis=1)
    assert len(np.unique(got, axis=0)) == len(got)  # no duplicate node
    np.testing.assert_array_equal(np.unique(got, axis=0), pairs)
    # Order: the one-texel receivers' nodes first, then the others', each in receiver order.
    one, _ = one_texel(lc[idx], spread[idx], box, R)
    n_one = int(one.sum())
    assert 0 < n_one < len(idx)
    np.testing.assert_array_equal(node_recv[:n_one], idx[one])
    assert np.all(np.diff(node_recv[n_one:]) >= 0)
    counts = np.bincount(node_recv, minlength=len(lc))[idx]
    assert (counts > 1).sum() > 100 and counts.max() > 8  # receivers over several texels


@pytest.mark.parametrize("cascades", [1, 2])
def test_build_launches_do_not_change_the_model(monkeypatch, cascades):
    """The whole model with the build split into many Dr.Jit launches: the same bytes."""
    loaded = scenes.load("city", width=96, height=54)
    one = rm.run("izb", loaded, samples=32, resolution=64, cascades=cascades)
    monkeypatch.setattr(build, "DRJIT_BUILD_CHUNK", 1001)  # many launches
    many = rm.run("izb", loaded, samples=32, resolution=64, cascades=cascades)
    assert one.diagnostics["receivers"] > 3 * 1001
    assert one.cost == many.cost
    assert one.diagnostics["partitions"] == many.diagnostics["partitions"]
    for key in one.outputs:
        assert one.outputs[key].tobytes() == many.outputs[key].tobytes(), key


@pytest.mark.parametrize("top", [1000, 1 << 18, 1 << 23, 1 << 29])
def test_lists_are_a_stable_sort_by_texel(top):
    """The radix-sorted lists (16-bit digits, 8 for a short top digit) equal a stable sort
    by texel, in parts; the head offsets give each texel's run."""

    rng = np.random.default_rng(top)
    texels = rng.integers(0, top, 5000)
    texels[:2000] = rng.integers(0, 40, 2000)  # long runs: ties keep insertion order
    recv = np.arange(5000)
    lists = build_lists([(texels[:3000], recv[:3000]), (texels[3000:], recv[3000:])])
    order = np.argsort(texels, kind="stable")
    np.testing.assert_array_equal(lists.node_texel, texels[order])
    np.testing.assert_array_equal(lists.node_recv, recv[order])
    probe = np.concatenate([texels[:50], [top + 5]])
    lo, n = lists.span(probe)
    for t, first, count in zip(probe, lo, n, strict=True):  # a few probes, not a hot path
        run = np.flatnonzero(lists.node_texel == t)
        assert count == len(run) and (count == 0 or first == run[0])
