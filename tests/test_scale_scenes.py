"""Scenes of real size (issue 35): ``meadow`` and ``city-foliage``, their ``name:key=value``
parameters in every command and in the sweep spec."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.scenes.catalogue.builtin import SceneParamError, builtin_scene
from raster_oracle.scenes.catalogue.scale_scenes import grass_blades, meadow

from raster_oracle import scenes


def test_blades_have_the_stated_size():
    """Every blade: base 0.02 wide on the ground, 0.3-0.6 tall, inside 20 x 20."""
    v, f = grass_blades(np.random.default_rng(0), 20000)
    tri = v[f]
    assert f.shape == (20000, 3) and tri.shape == (20000, 3, 3)
    width = np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1)
    np.testing.assert_allclose(width, 0.02, rtol=1e-12)
    assert np.all(tri[:, :2, 1] == 0.0)
    h = tri[:, 2, 1]
    assert h.min() >= 0.3 and h.max() <= 0.6 and h.max() - h.min() > 0.29
    base = 0.5 * (tri[:, 0] + tri[:, 1])
    assert np.abs(base[:, [0, 2]]).max() <= 10.0
    lean = np.hypot(*(tri[:, 2, [0, 2]] - base[:, [0, 2]]).T)
    assert lean.max() > 0.1 and np.all(lean <= 0.36 * np.sqrt(2) * h)


def test_parameters_are_parsed_checked_and_named_canonically():
    spec = builtin_scene("meadow:seed=4:n=300")
    assert spec.name == "meadow:n=300:seed=4"  # the catalogue's order
    d = spec.factory(32, 18)
    assert len(d["grass"]["faces"]) == 300
    assert builtin_scene("meadow").name == "meadow"
    assert builtin_scene("meadow:n=01000").factory(8, 8)["grass"]["faces"].shape == (1000, 3)
    assert builtin_scene("no-such-scene:n=3") is None and builtin_scene("x.xml") is None
    for bad, text in [
        ("meadow:x=1", "not a parameter of 'meadow'"),
        ("meadow:n=-5", r"n must be a whole number \(decimal digits only\) in \[0, 100000000\]"),
        ("meadow:n=1.5", "must be a whole number"),
        ("meadow:n=1_000", "decimal digits only"),  # Python's digit grouping is not taken
        ("meadow:n=3:n=4", "given twice"),
        ("meadow:n", "not a parameter"),
        ("plate:n=3", "takes no parameters"),
    ]:
        with pytest.raises(SceneParamError, match=text):
            builtin_scene(bad)


def test_scenes_are_seeded_and_n_sets_the_triangle_count():
    a, b = meadow(16, 9, n=500, seed=2), meadow(16, 9, n=500, seed=2)
    c = meadow(16, 9, n=500, seed=3)
    assert np.array_equal(a["grass"]["vertices"], b["grass"]["vertices"])
    assert not np.array_equal(a["grass"]["vertices"], c["grass"]["vertices"])
    loaded = scenes.load("city-foliage:n=700", width=32, height=18)
    assert loaded.name == "city-foliage:n=700"
    trees = [k for k in loaded.mesh_data if k.startswith("tree_")]
    assert len(trees) == 16 and len(loaded.mesh_data) == 12 + 1 + 16  # buildings, ground
    # every leaf in one tree's mesh, beside its trunk (a box of 10 triangles: no bottom)
    assert sum(len(loaded.mesh_data[k][1]) for k in trees) == 700 + 16 * 10
    other = scenes.load("city-foliage:n=701", width=32, height=18)
    assert other.content_hash != loaded.content_hash
    assert scenes.load("meadow:n=0", width=16, height=9).shape_names == ["ground"]


def test_every_command_takes_scene_parameters(tmp_path, capsys):
    """reference, model, score and export take ``meadow:n=...``; a bad parameter is one line
    and exit 2."""
    small = ["--width", "32", "--height", "18", "--quiet"]
    out = tmp_path / "ref"
    rc = main(["reference", "meadow:n=200", "--spp", "4", "--no-cache", "--out", str(out), *small])
    assert rc == 0
    record = json.loads((out / "reference.json").read_text())
    assert record["scene"]["name"] == "meadow:n=200"
    rc = main(
        ["score", "meadow:n=200", "--technique", "fxaa", "--spp", "4", "--no-cache"]
        + ["--out", str(tmp_path / "score"), *small]
    )
    assert rc == 0 and (tmp_path / "score" / "metrics.json").is_file()
    assert main(["export", "city-foliage:n=50", "--out", str(tmp_path / "exp"), *small[:4]]) == 0
    capsys.readouterr()
    rc = main(["reference", "meadow:blades=3", "--out", str(tmp_path / "bad"), *small])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "not a parameter of 'meadow'" in err[0]
    assert not (tmp_path / "bad").exists()
    assert main(["scenes"]) == 0
    assert "meadow:n=N" in capsys.readouterr().out


def test_sweep_spec_takes_scene_parameters():
    from raster_oracle.oracle.sweeps.spec import SpecError, expand_spec

    data = {
        "name": "scale",
        "defaults": {"width": 32, "height": 18, "spp": 4},
        "case": [{"scenes": ["meadow:n=100", "meadow:n=100:seed=2"], "technique": "fxaa"}],
    }
    cases = expand_spec(data).cases
    assert sorted(c.scene for c in cases) == ["meadow:n=100", "meadow:n=100:seed=2"]
    bad = {**data, "case": [{"scenes": ["meadow:m=1"], "technique": "fxaa"}]}
    with pytest.raises(SpecError, match="not a parameter of 'meadow'"):
        expand_spec(bad)


@pytest.mark.parametrize("name", ["meadow:n=400", "city-foliage:n=400", "plate", "star", "slide"])
def test_layered_boundaries_match_the_polygon_path(name, monkeypatch):
    """The visible-boundary path (shapes in one depth order) gives the polygon-boolean path's
    channels within 1e-9 on layered scenes, and says which path it took."""
    from raster_oracle.oracle.reference.coverage import centre_shapes
    from raster_oracle.scenes.geometry import exact_coverage as ec

    monkeypatch.setattr(ec, "LAYERED_ABOVE_S", 0.0)  # the layered path even when small
    loaded = scenes.load(name, width=64, height=36)
    centre = centre_shapes(loaded)
    tset = ec.scene_triangle_set(loaded)
    fast = ec.exact_coverage_of(loaded.camera, tset, centre, grid_offset=(0.25, -0.5))
    assert fast.stats["method"] == "layered"
    monkeypatch.setattr(ec, "layered_coverage", lambda *a: None)
    slow = ec.exact_coverage_of(loaded.camera, tset, centre, grid_offset=(0.25, -0.5))
    assert slow.stats["method"] == "polygons"
    assert np.abs(fast.coverage - slow.coverage).max() < 1e-9
    assert np.abs(fast.front_coverage - slow.front_coverage).max() < 1e-9
    assert np.array_equal(fast.valid, slow.valid)
    assert 0.0 < fast.coverage.mean() <= 1.0


def test_interpenetrating_shapes_take_the_polygon_path(monkeypatch):
    """Two quads of two shapes crossing each other have no depth order: the polygon path
    splits them along their intersection."""
    from raster_oracle.scenes.camera import Camera
    from raster_oracle.scenes.geometry import exact_coverage as ec

    monkeypatch.setattr(ec, "LAYERED_ABOVE_S", 0.0)
    from raster_oracle.scenes.geometry.exact_coverage import TriangleSet, exact_coverage_of

    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, -10.0)
    cam = Camera("orthographic", m, 16, 16, 0.1, 100.0)
    a = np.array([[[-0.5, -0.5, -1], [0.5, -0.5, 1], [0.5, 0.5, 1]]], float)
    b = np.array([[[-0.5, -0.5, 1], [0.5, -0.5, -1], [0.5, 0.5, -1]]], float)
    tset = TriangleSet(np.concatenate([a, b]), np.array([0, 1]), np.zeros(2))
    ex = exact_coverage_of(cam, tset, np.zeros(256, np.int64))
    assert ex.stats["method"] == "polygons"
