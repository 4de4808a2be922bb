"""Engine conventions as shadow-model parameters: caster faces, normal-offset direction and
units, bias space, lookup offset, the engine's own light matrix (issue 43, item 6-7)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.raster_models.errors import ModelError

from raster_oracle import raster_models, scenes

W, H, RES = 96, 54, 256
BASE = {"resolution": RES, "filter": "point", "bias": 0.002}


@pytest.fixture(scope="module")
def plate(_backend):
    return scenes.load("plate", width=W, height=H)


def _vis(scene, **kw):
    res = raster_models.run("shadow-map", scene, **{**BASE, **kw})
    return res.outputs["visibility"], res


def test_light_matrix_reproduces_the_fitted_map_in_both_texture_origins(plate, tmp_path):
    v0, res = _vis(plate)
    m = np.array(res.diagnostics["partitions"][0]["projection"]["matrix_world_to_texture"])
    (tmp_path / "dx.json").write_text(json.dumps({"matrix": m.tolist()}))
    gl = m.copy()
    gl[1] = gl[3] - gl[1]  # OpenGL/WebGL texture t grows up
    doc = {"matrix": gl.tolist(), "texture_origin": "bottom-left"}
    (tmp_path / "gl.json").write_text(json.dumps(doc))
    for name in ("dx.json", "gl.json"):
        v, r = _vis(plate, light_matrix=str(tmp_path / name))
        np.testing.assert_array_equal(v, v0)
        assert r.diagnostics["light_matrix"].endswith(name)
    # an engine box one texel over: the model renders and samples that map (the shadows
    # stay where they are in the image: the map moves with its lookups)
    shifted = m.copy()
    shifted[0, 3] += 1.0 / RES
    (tmp_path / "moved.json").write_text(json.dumps({"matrix": shifted.tolist()}))
    v, r = _vis(plate, light_matrix=str(tmp_path / "moved.json"))
    used = np.array(r.diagnostics["partitions"][0]["projection"]["matrix_world_to_texture"])
    np.testing.assert_allclose(used, shifted, atol=1e-12)
    assert np.mean(v != v0) < 0.01


@pytest.mark.parametrize(
    ("doc", "match"),
    [
        ("not json", "not JSON"),
        ('{"m": 1}', 'expected an object with "matrix"'),
        ('{"matrix": [[1, 0], [0, 1]]}', "4x4"),
        ('{"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,0]]}', "orthographic"),
        ('{"matrix": [[1,0,0,0],[1,1,0,0],[0,0,1,0],[0,0,0,1]]}', "not orthogonal"),
        ('{"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "texture_origin": "x"}', "origin"),
    ],
)
def test_bad_light_matrix_files_are_named(plate, tmp_path, doc, match):
    path = tmp_path / "m.json"
    path.write_text(doc)
    with pytest.raises(ModelError, match=match):
        _vis(plate, light_matrix=str(path))
    with pytest.raises(ModelError, match="cannot read"):
        _vis(plate, light_matrix=str(tmp_path / "missing.json"))


def test_caster_faces_cull_what_the_light_sees(plate):
    both, _ = _vis(plate)
    front, _ = _vis(plate, caster_faces="front")
    back, _ = _vis(plate, caster_faces="back")
    # the plate's casters are closed: the faces towards the light cast the same shadows
    # as all faces do; their back faces cast from the far side, and the ground (seen from
    # the light on its front) no longer shades itself
    np.testing.assert_array_equal(front, both)
    assert np.any(back != both)
    assert back.mean() >= both.mean()


def test_bias_space_and_lookup_offset(plate):
    v0, _ = _vis(plate)
    lin, _ = _vis(plate, bias_space="linear")
    np.testing.assert_array_equal(lin, v0)  # orthographic depth is linear: the same
    moved, _ = _vis(plate, lookup_offset=(1.0, 0.0))
    assert np.abs(moved - v0).max() == 1.0
    with pytest.raises(ModelError, match="lookup_offset"):
        raster_models.parse_params("shadow-map", ["lookup_offset=1"])


def test_normal_offset_world_units_and_vertex_direction(plate):
    v0, _ = _vis(plate)
    world, _ = _vis(plate, normal_offset=0.05, normal_offset_units="world")
    vertex, _ = _vis(
        plate, normal_offset=0.05, normal_offset_units="world", normal_offset_direction="vertex"
    )
    assert np.any(world != v0)
    # the plate's receivers are seen from their front: the wound normal is the facing one
    np.testing.assert_array_equal(vertex, world)
