"""AGAA's fused Dr.Jit frame (:mod:`raster_models.aa.agaa.kernels`) gives the bytes of the NumPy
path (:func:`raster_models.aa.agaa.model._run_numpy`): the same clustering, the same float32
material sums in ``np.add.reduceat``'s order, the same float64 resolve."""

from __future__ import annotations

import numpy as np
import pytest

import scenes
from raster_models.aa import samples as _samples
from raster_models.aa import trace as _trace
from raster_models.aa.agaa import kernels as _agaa_dr
from raster_models.aa.agaa import model as agaa
from raster_models.aa.agaa import pixels as _agaa_pixels
from scenes import backend

SMALL = {"width": 64, "height": 36}


def _both(scene, **kw):
    p = agaa.AgaaParams(**kw)
    offsets = _samples.positions(p.samples)
    fused = _agaa_dr.render(
        scene,
        offsets,
        k=p.aggregates,
        threshold=p.threshold,
        depth_weight=p.depth_weight,
        fmt=p.normal_format,
    )
    color, coverage, n_agg, surfaces, rays = agaa._run_numpy(scene, p, offsets)
    ref = {"color": color, "aggregates": n_agg, "surfaces": surfaces, "shadow_rays": rays}
    return fused, ref, coverage


def _assert_same(fused, ref, coverage, n):
    for key, val in ref.items():
        got = fused[key]
        assert np.asarray(got).tobytes() == np.asarray(val).tobytes(), key
    assert np.array_equal(fused["covered"] / n, coverage)


def _longest_aggregate(scene, n, fmt):
    """Most (fragment, aggregate) pairs summed into one aggregate of the frame."""
    b = _trace.trace_samples(
        scene, _samples.positions(n), group=True, cluster=(2, 0.1, 1.0, fmt), keep=()
    )
    pairs = b["pair_rep"]
    return max(int((pairs & (b["aggregate"] == a)).sum(axis=1).max()) for a in (0, 1))


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("foliage", {"samples": 16, "normal_format": "rgb10a2"}),
        ("foliage", {"samples": 8, "aggregates": 1, "normal_format": "oct16"}),
        ("glossy", {"samples": 8, "normal_format": "rgba16f"}),
        ("thin", {"samples": 4}),
        ("city", {"samples": 2}),
        ("foliage", {"samples": 1}),
    ],
)
def test_fused_frame_equals_numpy_path(name, params):
    scene = scenes.load(name, **SMALL)
    fused, ref, coverage = _both(scene, **params)
    _assert_same(fused, ref, coverage, params["samples"])
    assert fused["shadow_rays"] > 0
    if params["samples"] == 16:
        # foliage at 16 samples has aggregates of 9+ pairs: reduceat's unrolled branch
        assert _longest_aggregate(scene, 16, params["normal_format"]) >= 9


def test_fused_frame_launch_by_launch(monkeypatch):
    """Launches of two pixel rows, some of them all sky (the star's top rows: no fragment
    in the launch) give the bytes of the NumPy path in one launch."""
    scene = scenes.load("star", **SMALL)
    monkeypatch.setattr(_trace, "CHUNK", 8 * 2 * SMALL["width"] // _agaa_dr.LAUNCH_CHUNKS)
    fused = _agaa_dr.render(
        scene, _samples.positions(8), k=2, threshold=0.1, depth_weight=1.0, fmt="rgb10a2"
    )
    monkeypatch.setattr(_trace, "CHUNK", 1 << 21)
    p = agaa.AgaaParams()
    color, coverage, n_agg, surfaces, rays = agaa._run_numpy(scene, p, _samples.positions(8))
    rows = fused["covered"].reshape(SMALL["height"], SMALL["width"]).sum(axis=1)
    assert (rows[0::2] + rows[1::2] == 0).any()  # a launch without a surface
    _assert_same(
        fused,
        {"color": color, "aggregates": n_agg, "surfaces": surfaces, "shadow_rays": rays},
        coverage,
        8,
    )


def test_add_reduceat_order_is_numpys():
    """Random segments of 1-16 rows out of 16 candidates (signed zeros, magnitudes over six
    decades): the Dr.Jit sum equals ``np.add.reduceat`` byte for byte."""
    mi = backend.mitsuba()
    import drjit as dr

    rng = np.random.default_rng(3)
    n, lanes, width = 16, 4000, 3
    vals = rng.standard_normal((n, lanes, width)) * 10.0 ** rng.integers(-3, 4, (n, lanes, 1))
    vals = vals.astype(np.float32)
    vals[rng.random(vals.shape) < 0.15] = np.float32(-0.0)
    vals[rng.random(vals.shape) < 0.05] = np.float32(0.0)
    active = rng.random((n, lanes)) < rng.random(lanes)
    active[rng.integers(0, n, lanes), np.arange(lanes)] = True  # no empty segment
    active[:, :200] = True  # full segments
    at = np.cumsum(active, axis=0) - active
    rows = [[mi.Float(vals[i, :, c]) for c in range(width)] for i in range(n)]
    got, count = _add(mi, dr, rows, active, at)
    lane_of, row_of = np.nonzero(active.T)
    seq = vals[row_of, lane_of]
    first = np.r_[0, np.cumsum(active.sum(axis=0))[:-1]]
    expect = np.add.reduceat(seq, first, axis=0)
    assert np.array_equal(count, active.sum(axis=0))
    assert (active.sum(axis=0) >= 9).sum() > 500  # the unrolled branch, often
    assert got.tobytes() == expect.tobytes()


def _add(mi, dr, rows, active, at):
    sums, count = _agaa_dr.add_reduceat_order(
        dr,
        rows,
        [mi.Bool(a) for a in active],
        [mi.UInt32(a.astype(np.uint32)) for a in at],
        len(rows),
    )
    dr.eval(sums, count)
    return np.stack([s.numpy() for s in sums], axis=1), count.numpy()


@pytest.mark.parametrize(
    ("name", "n", "fmt", "k"),
    [
        ("foliage", 16, "rgb10a2", 2),
        ("foliage", 8, "oct16", 2),
        ("thin", 4, "rgba16f", 2),
        ("glossy", 2, "rgb10a2", 2),
        ("foliage", 1, "rgb10a2", 2),
        ("foliage", 8, "rgb10a2", 1),
    ],
)
def test_pixel_lanes_equal_sample_lanes(name, n, fmt, k):
    """Fragment representatives and aggregates computed one lane a pixel
    (:func:`_agaa_pixels.pixel_prepass`) equal those of one lane a sample
    (:mod:`raster_models.aa.pixel_dr`, tested against the NumPy rule) sample for sample,
    and the block sums equal :func:`drjit.block_reduce`'s bytes."""
    mi = backend.mitsuba()
    import drjit as dr

    scene = scenes.load(name, **SMALL)
    offs = _samples.positions(n)
    ref = _trace.trace_samples(scene, offs, group=True, cluster=(k, 0.1, 1.0, fmt))
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    n_pix = SMALL["width"] * SMALL["height"]
    table = _trace.shape_table(mi, dr, scene)
    pix = dr.arange(mi.UInt32, n_pix)
    valid, depth, prim, shape, nrm, _ = _trace.prepass_dr(
        scene, scene.mi_scene, table, ox, oy, pix, n, normals=True, group=False, cluster=None
    )
    first, agg, rep_bits = _agaa_pixels.pixel_prepass(
        mi, dr, (valid, depth, prim, shape, nrm), n, k, 0.1, 1.0, fmt
    )
    dr.eval(first, agg, rep_bits)
    first = np.stack([f.numpy() for f in first], axis=1)
    agg = np.stack([a.numpy() for a in agg], axis=1)
    bits = (rep_bits.numpy()[:, None] >> np.arange(n)) & 1
    assert np.array_equal(first, ref["first"])
    assert np.array_equal(agg, ref["aggregate"])
    assert np.array_equal(bits.astype(bool), ref["rep"])
    if k == 2 and n >= 4:
        assert (agg == 1).any()
    # the pixel sums themselves, on values with signed zeros and six decades
    rng = np.random.default_rng(n)
    x = rng.standard_normal((5000, n)) * 10.0 ** rng.integers(-3, 4, (5000, n))
    x = x.astype(np.float32)
    x[rng.random(x.shape) < 0.3] = np.float32(-0.0)
    x[:50] = np.float32(-0.0)
    got = _agaa_pixels.block_sum(dr, [mi.Float(x[:, j]) for j in range(n)])
    expect = dr.block_reduce(dr.ReduceOp.Add, mi.Float(x.ravel()), n, mode="evaluated")
    assert got.numpy().tobytes() == expect.numpy().tobytes()
