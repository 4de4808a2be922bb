"""ACAA's fast paths give the bytes of the direct ones: the proximity test that picks the
samples of the tie search (:mod:`raster_models.aa.acaa.ties`) against tracing every sample,
the grid lookup against testing every box, the per-pixel fragment grouping on the Dr.Jit
side (:mod:`raster_models.aa.acaa.trace`) against the NumPy rule, and the blend on
pixel-sorted runs against one addition at a time."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from raster_oracle.raster_models.aa import samples, trace
from raster_oracle.raster_models.aa.acaa import blend, groups, ties
from raster_oracle.raster_models.aa.acaa import model as acaa
from raster_oracle.raster_models.aa.acaa import trace as acaa_trace
from raster_oracle.scenes import backend
from raster_oracle.scenes.backend.raycast import shape_table

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests.aa_reference import group_fragments

SMALL = {"width": 64, "height": 36}
#: Relative agreement of the float32 tie radius with its float64 twin (float32 rounding of
#: a handful of operations; the radius carries a factor 2 of margin over the bound).
RADIUS_RTOL = 1e-5
#: Agreement of two algebraically equal float64 forms of the tie distance (a few roundings).
CLOSED_FORM_RTOL = 1e-9


def _grid_lookup_equals_direct(mi, dr, cam, grid, direct, pts):
    """Near-box flags of ``pts`` (D24 tie radius) by the grid lookup and by testing every
    box; asserts they are equal and returns them."""
    pf = mi.Point3f(*(mi.Float(np.ascontiguousarray(pts[:, a], np.float32)) for a in range(3)))
    zf = mi.Float(((pts - cam.position) @ cam.forward).astype(np.float32))
    radius = ties.point_radius_dr(dr, cam, "D24", zf, pf)
    got = ties.near_dr(mi, dr, grid, pf, radius).numpy()
    ref = ties.near_dr(mi, dr, direct, pf, radius).numpy()
    assert np.array_equal(got, ref)
    return ref


def _no_filter(scene, found, fmt):
    """Every sample a tie candidate of every group (the unfiltered tie search)."""
    box = np.zeros((0, 3), np.float32)
    return [ties.GroupFilter(True, box, box) for _ in found]


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("decal", {"samples": 8}),
        ("decal", {"samples": 4, "depth_format": "D32F", "centroid": True}),
        ("city", {"samples": 8}),
        ("thin", {"samples": 16, "accumulation": "rgba8"}),
    ],
)
def test_proximity_filtered_tie_search_equals_unfiltered(monkeypatch, name, params):
    """Tracing only the samples near a group's boxes finds every tie the unfiltered search
    finds: same outputs byte for byte, fewer rays (city: a handful instead of every
    sample)."""
    scene = scenes.load(name, **SMALL)
    fast = rm.run("acaa", scene, **params)
    monkeypatch.setattr(acaa_trace, "group_filters", _no_filter)
    full = rm.run("acaa", scenes.load(name, **SMALL), **params)
    for key, value in full.outputs.items():
        assert value.tobytes() == fast.outputs[key].tobytes(), key
    assert fast.cost == full.cost
    assert fast.diagnostics["tie_samples"] == full.diagnostics["tie_samples"]
    assert fast.diagnostics["per_shape_rays"] < full.diagnostics["per_shape_rays"]
    if name == "decal":
        assert fast.diagnostics["tie_samples"] > 0
    if name == "city":
        assert fast.diagnostics["per_shape_rays"] < 0.01 * full.diagnostics["per_shape_rays"]


def test_chunked_acaa_equals_one_launch(monkeypatch):
    """Launches ending mid-row (ties and fragments on both sides of a cut) give the bytes of
    one launch."""
    scene = scenes.load("decal", **SMALL)
    whole = rm.run("acaa", scene, samples=8, centroid=True)
    monkeypatch.setattr(trace, "CHUNK", 8 * 97)
    parts = rm.run("acaa", scenes.load("decal", **SMALL), samples=8, centroid=True)
    for key, value in whole.outputs.items():
        assert value.tobytes() == parts.outputs[key].tobytes(), key
    assert whole.diagnostics["tie_samples"] > 0


def test_radius_is_twice_the_tie_distance_plus_slack():
    """Perspective: ``radius(z) = 2 tie_distance(z) + POSITION_ERROR (z + p_max)`` (the
    closed form ``c z^2 / (1 - c z)`` of the tie distance's inverse depth); unbounded once
    ``c z`` reaches :data:`UNBOUNDED_CZ`; the float32 Dr.Jit twin agrees."""
    mi = backend.mitsuba()
    import drjit as dr

    cam = scenes.load("city", **SMALL).camera
    z = np.array([0.05, 1.0, 10.0, 100.0, 1000.0, 1999.0])
    for fmt in ("D24", "D32F"):
        got = ties.tie_radius(cam, fmt, z, 50.0)
        expect = 2.0 * groups.tie_distance(cam, z, fmt) + ties.POSITION_ERROR * (z + 50.0)
        assert np.allclose(got, expect, rtol=CLOSED_FORM_RTOL, atol=0)
        p = mi.Point3f(mi.Float(np.full(len(z), 50.0)), 0.0, 0.0)
        r32 = ties.point_radius_dr(dr, cam, fmt, mi.Float(z), p).numpy()
        assert np.allclose(r32, got, rtol=RADIUS_RTOL, atol=0)
    far_near = dataclasses.replace(cam, near=1e-4, far=1e5)
    c = ties.radius_constants(far_near, "D24")[0]
    zs = np.array([0.4, 0.6]) / c
    assert np.isfinite(ties.tie_radius(far_near, "D24", zs[0], 0.0))
    assert np.isinf(ties.tie_radius(far_near, "D24", zs[1], 0.0))


def test_grid_lookup_equals_testing_every_member():
    """City's 196 buildings (one group): the grid lists, for any sample point, every member
    whose box can lie within the point's tie radius, so its answer equals the test against
    every box, point for point (points inside, around and just off the boxes' faces, within
    a few radii)."""
    mi = backend.mitsuba()
    import drjit as dr

    scene = scenes.load("city", **SMALL)
    cam = scene.camera
    big = max(groups.tie_groups(scene, "D24"), key=len)
    grid = ties.group_filters(scene, [big], "D24")[0]
    assert grid.starts is not None and grid.longest >= 1
    direct = dataclasses.replace(grid, starts=None, members=None)
    rng = np.random.default_rng(7)
    k = rng.integers(0, len(big), 200_000)
    lo, hi = grid.lo[k].astype(np.float64), grid.hi[k].astype(np.float64)
    pts = lo + rng.random((len(k), 3)) * (hi - lo)
    # move half the points onto a face, then off it by up to three radii either way
    z = (pts - cam.position) @ cam.forward
    r_est = ties.tie_radius(cam, "D24", z, np.abs(pts).max(axis=1))
    face = rng.random(len(k)) < 0.5
    axis = rng.integers(0, 3, len(k))
    side = np.where(rng.random((len(k), 1)) < 0.5, lo, hi)[np.arange(len(k)), axis]
    off = (rng.random(len(k)) * 6.0 - 3.0) * r_est
    pts[face, axis[face]] = side[face] + off[face]
    ref = _grid_lookup_equals_direct(mi, dr, cam, grid, direct, pts)
    assert 0.05 < (~ref[face]).mean() < 0.95  # the face points fall on both sides


@pytest.mark.parametrize(("name", "n"), [("thin", 4), ("foliage", 16), ("decal", 8)])
def test_per_pixel_grouping_matches_numpy(name, n):
    """Representatives, sample counts and centroid sums from one lane a pixel equal the
    NumPy grouping (:func:`tests.aa_reference.group_fragments`) and ``np.bincount``'s sums
    exactly (the standard positions are multiples of 1/16: their float64 sums are exact in
    any order)."""
    mi = backend.mitsuba()
    import drjit as dr

    scene = scenes.load(name, **SMALL)
    offs = samples.positions(n)
    b = trace.trace_samples(scene, offs, keep=("valid", "shape", "prim", "depth"))
    ref = group_fragments(b["valid"], b["shape"], b["prim"])
    ox, oy = (mi.Float(offs[:, a].astype(np.float32)) for a in range(2))
    count = scene.width * scene.height
    table = shape_table(mi, dr, scene)
    base = dr.opaque(mi.UInt32, 0)
    valid, _, prim, shape, _ = acaa_trace.launch_prepass(
        scene, table, ox, oy, base, count, n, [], "D24"
    )
    counts = acaa_trace.fragments_of_pixels(valid, shape, prim, count, n)
    rep = dr.compress(counts > 0)
    r = rep.numpy().astype(np.int64)
    assert np.array_equal(r // n, ref.pixel) and np.array_equal(r % n, ref.sample)
    assert np.array_equal(dr.gather(mi.UInt32, counts, rep).numpy(), ref.count)
    sums = acaa_trace.position_sums(valid, shape, prim, rep, n, offs.astype(np.float64))
    of = ref.of_sample.ravel()
    ok = of >= 0
    slot = np.flatnonzero(ok) % n
    for a in range(2):
        expect = np.bincount(of[ok], weights=offs[slot, a], minlength=len(r))
        assert np.array_equal(sums[a].numpy(), expect)
    assert (ref.count < n).sum() > 10


@pytest.mark.parametrize("rgba8", [False, True])
def test_blend_equals_one_addition_at_a_time(rgba8):
    """The run-wise blend adds each pixel's values in their given order, as a loop of single
    additions does (float32, or float64 rounded to 8 bits after each), for any order of
    pixels in the input, onto a zero target or a given one."""
    rng = np.random.default_rng(3)
    n_pix = 50
    pixel = rng.integers(0, n_pix, 400)
    values = (rng.random((400, 3)) * 0.6).astype(np.float32)
    dtype = np.float64 if rgba8 else np.float32
    vals = values.astype(dtype)
    for start in (np.zeros((n_pix, 3)), rng.random((n_pix, 3)) * 0.2):
        ref = start.astype(dtype)
        order = np.argsort(pixel, kind="stable")
        for i in order:  # the definition, one blend at a time
            s = ref[pixel[i]] + vals[i]
            if rgba8:
                s = np.floor(np.clip(s, 0.0, 1.0) * 255.0 + 0.5) / 255.0
            ref[pixel[i]] = s
        got = blend.blend(values, pixel, start, rgba8=rgba8)
        assert got.dtype == dtype and got.tobytes() == ref.tobytes()
        # pixels grouped (contiguous runs) but not sorted: no sort needed
        grouped = np.argsort(pixel % 7 * 1000 + pixel, kind="stable")
        got = blend.blend(values[grouped], pixel[grouped], start, rgba8=rgba8, grouped=True)
        assert got.tobytes() == ref.tobytes()
        if not start.any():
            zero = blend.blend(values, pixel, n_pix, rgba8=rgba8)
            assert zero.tobytes() == ref.tobytes()


def test_fragment_merge_equals_sorting_everything():
    """Merging only the busy pixels and inserting them among the others gives the rows of
    sorting every entry by (pixel, shape, primitive, sample) and merging equal keys."""
    rng = np.random.default_rng(5)
    n, n_pix = 8, 400
    offs = samples.positions(n)
    # nearest fragments: pixel order, distinct (shape, prim) and first samples in a pixel
    per = rng.integers(0, 4, n_pix)
    pixel = np.repeat(np.arange(n_pix), per)
    rank = np.arange(len(pixel)) - np.repeat(np.cumsum(per) - per, per)
    near = {
        "pixel": pixel,
        "sample": rank * 2,
        "shape": rng.integers(0, 3, len(pixel)),
        "prim": rank * 10 + rng.integers(0, 5, len(pixel)),
        "count": rng.integers(1, 3, len(pixel)),
        "sum_x": rng.random(len(pixel)),
        "sum_y": rng.random(len(pixel)),
    }
    # ties: some repeat a nearest fragment's key (merged), some are new
    pick = rng.choice(len(pixel), 60, replace=False)
    t_shape = np.where(rng.random(60) < 0.5, near["shape"][pick], 7)
    ties = [(pixel[pick], (rank[pick] * 2 + 1) % n, t_shape, near["prim"][pick])]
    got = acaa.merge_fragments(near, ties, offs, n_pix, centroid=True)
    # reference: every entry sorted, equal (pixel, shape, prim) merged
    cat = {
        k: np.concatenate([near[k], v])
        for k, v in zip(("pixel", "sample", "shape", "prim"), ties[0], strict=True)
    }
    cat["count"] = np.concatenate([near["count"], np.ones(60, np.int64)])
    for a, key in enumerate(("sum_x", "sum_y")):
        cat[key] = np.concatenate([near[key], offs[ties[0][1], a]])
    order = np.lexsort((cat["sample"], cat["prim"], cat["shape"], cat["pixel"]))
    cat = {k: v[order] for k, v in cat.items()}
    key = np.stack([cat["pixel"], cat["shape"], cat["prim"]])
    first = np.flatnonzero(np.r_[True, (key[:, 1:] != key[:, :-1]).any(axis=0)])
    for k in ("pixel", "sample", "shape"):
        assert np.array_equal(got[k], cat[k][first]), k
    for k in ("count", "sum_x", "sum_y"):
        assert np.array_equal(got[k], np.add.reduceat(cat[k], first)), k
    assert len(got["pixel"]) < len(cat["pixel"])  # some ties merged


def test_grid_margin_covers_radii_wider_than_cells():
    """Thirty small cubes 1.5 km away (D24: tie radii of metres, cells of about one metre):
    a grid lookup still equals testing every cube, so each cube's cells reach as far as
    any radius a tie with it can have (points up to three radii off the faces)."""
    import types

    mi = backend.mitsuba()
    import drjit as dr

    cam = scenes.load("city", **SMALL).camera
    fwd, up = np.asarray(cam.forward), np.array([0.0, 1.0, 0.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    centres = [
        cam.position + fwd * 1500.0 + right * (30.0 * i - 75.0) + up * (30.0 * j - 60.0)
        for i in range(6)
        for j in range(5)
    ]
    T = mi.ScalarTransform4f
    shapes = {
        f"cube_{k}": {"type": "cube", "to_world": T().translate(c.tolist()).scale(0.5)}
        for k, c in enumerate(centres)
    }
    scene = types.SimpleNamespace(
        camera=cam, mi_scene=mi.load_dict({"type": "scene", **shapes}), memo={}
    )
    grid = ties.group_filters(scene, [list(range(len(centres)))], "D24")[0]
    assert grid.starts is not None and grid.longest <= ties.CELL_LIST
    direct = dataclasses.replace(grid, starts=None, members=None)
    rng = np.random.default_rng(11)
    k = rng.integers(0, len(centres), 100_000)
    lo, hi = grid.lo[k].astype(np.float64), grid.hi[k].astype(np.float64)
    z = (np.asarray(centres)[k] - cam.position) @ cam.forward
    r_est = ties.tie_radius(cam, "D24", z, np.abs(hi).max(axis=1))
    assert r_est.min() > 3.0 * grid.cell  # radii span several cells
    pts = lo + rng.random((len(k), 3)) * (hi - lo)
    axis = rng.integers(0, 3, len(k))
    side = np.where(rng.random((len(k), 1)) < 0.5, lo, hi)[np.arange(len(k)), axis]
    pts[np.arange(len(k)), axis] = side + (rng.random(len(k)) * 6.0 - 3.0) * r_est
    ref = _grid_lookup_equals_direct(mi, dr, cam, grid, direct, pts)
    assert 0.2 < ref.mean() < 0.8


@pytest.mark.parametrize(
    ("technique", "params"),
    [
        ("msaa", {}),
        ("msaa", {"centroid": True}),
        ("acaa", {}),
        ("acaa", {"centroid": True}),
        ("agaa", {}),
        ("ssaa", {}),
    ],
)
def test_all_sky_frame_has_no_fragment_and_no_error(technique, params):
    """A frame that sees only sky (the camera looks straight up over the star scene): every
    launch of the fused paths is empty; coverage, colour and shading events are 0."""
    from raster_oracle.oracle.studies.extremes.cases import EXTREMES
    from raster_oracle.oracle.studies.extremes.run import load_extreme

    scene = load_extreme(EXTREMES["all_sky"], base="star", **SMALL)
    out = rm.run(technique, scene, samples=4, **params).outputs
    assert not out["coverage"].any()
    assert not out["shading_events"].any()
    assert not out["color"].any()
