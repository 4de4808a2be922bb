"""Coherent shadow maps: the Hilbert numbering, the lookup, error against the oracle as the
number of directions and the map resolution grow, lossless compression, orderings, bad
values, and following a light path."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.raster_models.coherent.directions import Projections, map_directions, uv
from raster_oracle.raster_models.coherent.hilbert import hilbert_cell, hilbert_index
from raster_oracle.raster_models.coherent.model import ORDERINGS
from raster_oracle.raster_models.coherent.surfaces import surfaces
from raster_oracle.raster_models.gbuffer import trace_gbuffer

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests._coherent_reference import compress_runs, visibility_intervals

W, H = 96, 54
#: Small bias plus normal offset (as the shadow-map convergence tests): acne-free on plate,
#: so the error left is direction quantization and resolution.
SMALL_BIAS = {"bias": 0.0005, "normal_offset": 1.5, "compression": False}

#: Orbit frames averaged so that one lucky direction does not decide the trend.
FRAMES = (0, 2, 4, 6)


# ------------------------------------------------------------------------------ Hilbert
@pytest.mark.parametrize("n", [1, 2, 4, 8, 16, 64])
def test_hilbert_curve_is_a_bijection_with_unit_steps(n):
    d = np.arange(n * n)
    x, y = hilbert_cell(n, d)
    assert x.min() >= 0 and y.min() >= 0 and x.max() < n and y.max() < n
    assert len(set(zip(x.tolist(), y.tolist(), strict=True))) == n * n  # every cell once
    assert np.array_equal(hilbert_index(n, x, y), d)  # inverse
    steps = np.abs(np.diff(x)) + np.abs(np.diff(y))
    assert np.all(steps == 1)


def test_hilbert_order_2_is_the_textbook_curve():
    # The 4x4 curve of Hilbert's paper (x right, y up): starts at (0,0), ends at (3,0).
    x, y = hilbert_cell(4, np.arange(16))
    assert list(zip(x.tolist(), y.tolist(), strict=True)) == [
        (0, 0), (1, 0), (1, 1), (0, 1), (0, 2), (0, 3), (1, 3), (1, 2),
        (2, 2), (2, 3), (3, 3), (3, 2), (3, 1), (2, 1), (2, 0), (3, 0),
    ]  # fmt: skip


def test_hilbert_refuses_a_side_that_is_not_a_power_of_two():
    with pytest.raises(ValueError, match="power of two"):
        hilbert_index(6, 0, 0)


# ------------------------------------------------------------------------------ lookup
@pytest.mark.parametrize("n", [16, 256, 4096])
def test_id_texture_and_directions_agree(n):
    dirs, ids = map_directions(n)
    g = math.isqrt(n)
    assert ids.shape == (g, g)
    assert sorted(ids.ravel().tolist()) == list(range(n))
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0)
    # A map's own direction looks up that map.
    u, v = uv(dirs)
    looked = ids[(v * g).astype(int), (u * g).astype(int)]
    assert np.array_equal(looked, np.arange(n))
    # Equal-area cells: the directions' mean is the centre of the sphere (to 1/g).
    assert np.linalg.norm(dirs.mean(axis=0)) < 1.0 / g
    # Consecutive ids are neighbouring cells: their directions are at most one cell apart
    # (a cell spans 2 pi / g in phi and 2 / g in cos(theta); at most pi/2 / ... near poles).
    ang = np.degrees(np.arccos(np.clip(np.sum(dirs[1:] * dirs[:-1], axis=1), -1, 1)))
    max_cell = np.degrees(max(2 * math.pi / g, math.acos(1 - 2 / g)))
    assert ang.max() <= max_cell + 1e-9


def _error(name, frames, truths, **params) -> float:
    errs = []
    for s, (rec, lit) in zip(frames, truths, strict=True):
        res = rm.run("coherent-shadow-map", s, **SMALL_BIAS, **params)
        vis = res.outputs["visibility"].ravel()
        errs.append(float(((vis >= 0.5) != lit)[rec].mean()))
    return float(np.mean(errs))


@pytest.fixture(scope="module")
def plate_orbit():
    frames = [
        scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=k) for k in FRAMES
    ]
    truths = []
    for s in frames:
        g = trace_gbuffer(s, with_lit=True)
        truths.append((g.receiver, g.lit))
    return frames, truths


def test_error_falls_with_the_number_of_directions(plate_orbit):
    # Steps of 16x in N (4x finer direction spacing): not every 4x step is monotone for a
    # handful of light directions, but each 16x step is.
    for chain in ((16, 256, 4096), (64, 1024, 16384)):
        errs = [_error("plate", *plate_orbit, directions=n, resolution=512) for n in chain]
        assert errs[0] > errs[1] > errs[2], (chain, errs)


def test_error_falls_with_map_resolution(plate_orbit):
    errs = [
        _error("plate", *plate_orbit, directions=16384, resolution=r) for r in (32, 128, 512, 1024)
    ]
    assert all(a > b for a, b in zip(errs, errs[1:], strict=False)), errs
    assert errs[-1] < 0.005  # at 1024^2 and 16384 maps: half a percent of receivers


def test_direction_error_is_within_a_cell():
    s = scenes.load("plate", width=48, height=27)
    for n in (64, 1024):
        res = rm.run("coherent-shadow-map", s, directions=n, resolution=64, compression=False)
        g = math.isqrt(n)
        bound = math.degrees(math.hypot(math.pi / g, math.acos(1 - 2 / g)))
        assert res.diagnostics["direction_error_deg_max"] <= bound
        assert res.diagnostics["maps_looked_up"] == 1  # a sun: one map for every receiver


# ------------------------------------------------------------------------------ compression
def test_compress_runs_by_hand():
    # One texel, four maps: [0,1] [0.5,2] -> run [0.5,1]; [1.5,3] [0,4] -> run [1.5,3].
    lo = np.array([[0.0], [0.5], [1.5], [0.0]], dtype=np.float32)
    hi = np.array([[1.0], [2.0], [3.0], [4.0]], dtype=np.float32)
    runs, decoded = compress_runs(lo, hi, np.arange(4))
    assert runs == 2
    assert decoded.ravel().tolist() == [0.5, 0.5, 1.5, 1.5]
    # Reversed order: [0,4] [1.5,3] -> [1.5,3]; [0.5,2] -> [1.5,2]; [0,1] breaks.
    runs, decoded = compress_runs(lo, hi, np.arange(4)[::-1])
    assert runs == 2
    assert decoded.ravel().tolist() == [0.0, 1.5, 1.5, 1.5]


@pytest.mark.parametrize("name", ["plate", "thin", "curved"])
def test_decompressed_visibility_equals_uncompressed_at_texel_centres(name):
    """Receivers on the first and second surface of every texel's ray, in every map, get
    the same answer from the decompressed maps as from the uncompressed ones."""
    s = scenes.load(name, width=48, height=27)
    n, r, bias = 256, 32, 0.005
    dirs, ids = map_directions(n)
    projs = Projections(s, dirs, r)
    parts = list(surfaces(s, projs, np.arange(n), second=True))
    z1, z2, dz1, dz2 = (
        np.concatenate([rec[k] for _, _, rec in parts]).reshape(n, r * r)
        for k in ("z1", "z2", "dz1", "dz2")
    )
    lo, hi = visibility_intervals(z1, z2, bias, dz1=dz1, dz2=dz2)
    assert np.all(lo <= hi)
    stored = lo.astype(np.float64)
    orders = {"hilbert": np.arange(n), "row_major": ids.ravel(), "random": np.arange(n)[::-1]}
    for order in orders.values():
        runs, decoded = compress_runs(lo, hi, order)
        assert runs <= n * r * r
        assert np.all((decoded >= lo) & (decoded <= hi))
        dec = decoded.astype(np.float64)
        for z in (z1, z2):
            ok = np.isfinite(z)
            ref = z[ok] - bias
            assert np.array_equal(ref <= stored[ok], ref <= dec[ok])


@pytest.mark.parametrize("lossless", ["footprint", "texel_centre"])
def test_compression_ratios_are_reported_per_ordering(lossless):
    s = scenes.load("curved", width=48, height=27)
    res = rm.run("coherent-shadow-map", s, directions=1024, resolution=32, lossless=lossless)
    comp = res.cost["compression"]
    assert set(comp) == set(ORDERINGS)
    for rec in comp.values():
        assert rec["ratio"] == pytest.approx(1024 * 32 * 32 / rec["stored_values"])
        assert 1.0 <= rec["ratio"] <= 1024.0
    # Neighbouring directions share values: Hilbert beats a random order and the
    # column-major one (a pole-to-pole jump at every column).
    assert comp["hilbert"]["ratio"] > comp["random"]["ratio"]
    assert comp["hilbert"]["ratio"] > comp["column_major"]["ratio"]


def test_texel_centre_criterion_compresses_far_more_than_footprint():
    s = scenes.load("curved", width=48, height=27)
    ratio = {
        mode: rm.run("coherent-shadow-map", s, directions=1024, resolution=32, lossless=mode).cost[
            "compression"
        ]["hilbert"]["ratio"]
        for mode in ("footprint", "texel_centre")
    }
    assert ratio["texel_centre"] > 10 * ratio["footprint"]


@pytest.mark.parametrize("name", ["plate", "curved", "thin", "point"])
def test_decompressed_image_equals_uncompressed(name):
    """lossless=footprint: every receiver of the image gets the uncompressed answer."""
    s = scenes.load(name, width=64, height=36)
    for n, r in ((1024, 64), (4096, 32)):
        res = rm.run("coherent-shadow-map", s, directions=n, resolution=r)
        assert res.cost["decompressed_mismatches"] == 0


@pytest.mark.parametrize("name", ["curved", "thin", "point"])
@pytest.mark.parametrize("lossless", ["footprint", "texel_centre"])
def test_hilbert_compresses_better_than_random(name, lossless):
    s = scenes.load(name, width=48, height=27)
    comp = rm.run("coherent-shadow-map", s, directions=1024, resolution=32, lossless=lossless).cost[
        "compression"
    ]
    assert comp["hilbert"]["ratio"] > comp["random"]["ratio"]


# ------------------------------------------------------------------------------ light paths
def test_model_follows_the_orbiting_sun():
    runs = []
    for k in (0, 3):
        s = scenes.load("plate", width=48, height=27, light_path="orbit-sun", frame=k)
        base = scenes.load("plate", width=48, height=27)
        direct = replace(base, lights=[s.light])
        a = rm.run("coherent-shadow-map", s, directions=256, resolution=128, compression=False)
        b = rm.run("coherent-shadow-map", direct, directions=256, resolution=128, compression=False)
        assert np.array_equal(a.outputs["visibility"], b.outputs["visibility"])
        runs.append(a)
    ids = [np.unique(r.outputs["map_id"][r.outputs["map_id"] >= 0]) for r in runs]
    assert len(ids[0]) == len(ids[1]) == 1
    assert ids[0][0] != ids[1][0]  # 30 degrees of azimuth: another map
    assert not np.array_equal(runs[0].outputs["visibility"], runs[1].outputs["visibility"])


def test_model_follows_the_moving_point_light():
    s = scenes.load("point", width=48, height=27, light_path="moving-point", frame=2)
    base = scenes.load("point", width=48, height=27)
    direct = replace(base, lights=[s.light])
    kw = {"directions": 256, "resolution": 64, "compression": False}
    a = rm.run("coherent-shadow-map", s, **kw).outputs
    b = rm.run("coherent-shadow-map", direct, **kw).outputs
    c = rm.run("coherent-shadow-map", base, **kw).outputs
    assert np.array_equal(a["visibility"], b["visibility"])
    assert np.array_equal(a["map_id"], b["map_id"])
    assert not np.array_equal(a["map_id"], c["map_id"])


def test_point_light_uses_one_map_per_direction():
    s = scenes.load("point", width=48, height=27)
    res = rm.run("coherent-shadow-map", s, directions=256, resolution=64, compression=False)
    assert res.diagnostics["maps_looked_up"] > 1


# ------------------------------------------------------------------------------ bad values
@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("directions=100", "power of 4"),
        ("directions=2", r"directions must be an integer in \[4, 65536\]"),
        ("resolution=nan", "resolution must be an integer"),
        ("bias=inf", "finite"),
        ("bias=-0.1", r"bias must be a number in \[0, 1\]"),
        ("compression=maybe", "boolean"),
        ("samples=4", "unknown parameter 'samples'"),
        ("lossless=exact", "lossless must be one of footprint, texel_centre"),
    ],
)
def test_bad_values_exit_2(tmp_path, capfd, setting, message):
    out = tmp_path / "out"
    argv = ["model", "coherent-shadow-map", "plate", "--width", "16", "--height", "12"]
    assert main([*argv, "--set", setting, "--out", str(out)]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert re.search(message, err[0]), err[0]
    assert not out.exists()


def test_compression_refuses_too_many_texels():
    s = scenes.load("plate", width=16, height=12)
    with pytest.raises(rm.ModelError, match="compression=false"):
        rm.run("coherent-shadow-map", s, directions=65536, resolution=512)


def test_spot_light_is_refused():
    s = scenes.load("spot", width=16, height=12)
    with pytest.raises(rm.ModelError, match="directional or point"):
        rm.run("coherent-shadow-map", s)


def test_listed_with_its_parameters():
    tech = {t["name"]: t for t in rm.list_techniques()}["coherent-shadow-map"]
    names = [p["name"] for p in tech["params"]]
    assert names == [
        "directions",
        "resolution",
        "bias",
        "normal_offset",
        "compression",
        "lossless",
        "seed",
    ]
    assert all(p["source"] for p in tech["params"])
