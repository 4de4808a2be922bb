"""glTF ``COLOR_0`` vertex alpha on ``MASK`` materials: read as the specification defines it
(float, or normalized unsigned byte and short; VEC3 or VEC4), bounded like other accessors,
and multiplied into the alpha test: a card whose vertex alpha ramps 0..1 across is covered
on the half where the ramp reaches the cutoff."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.formats import gltf_write as gw

from raster_oracle import scenes

#: Film: 3 x 3 m seen orthographically from above, 64 pixels a side.
RES, SPAN = 64, 3.0
#: Agreement with a closed form within this many standard errors of the reference.
Z = 4.0


def _ramp_glb(path, colors, *, mode="MASK", cutoff=0.5) -> str:
    """A 2 x 2 m card (x, z in [-1, 1], y = 0) seen face-on from 10 m above, whose vertices
    at x = -1 have ``colors[0]`` and at x = 1 ``colors[1]`` (COLOR_0)."""
    quad = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
    c = np.asarray(colors)
    rgba = np.stack([c[0], c[1], c[1], c[0]])
    card = {"name": "card", "doubleSided": True, "alphaMode": mode, "alphaCutoff": cutoff}
    if mode == "OPAQUE":
        del card["alphaCutoff"]
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = (1, 0, 0), (0, 0, -1), (0, 1, 0)
    m[:3, 3] = (0, 10, 0)
    camera = gw.GltfCamera(m, 0.1, 30.0, ymag=SPAN / 2, aspect=1.0, film=(RES, RES))
    data = gw.glb_bytes(
        camera=camera,
        lights=[gw.GltfLight("sun", "directional", gw.light_matrix((0, -1, 0.2)), intensity=3.0)],
        meshes=[gw.GltfMesh("card", quad, faces, 0, np.tile([0, 1, 0], (4, 1)), colors=rgba)],
        materials=[card],
    )
    path.write_bytes(data)
    return str(path)


#: The ramp 0..1 in each encoding the specification allows for COLOR_0.
RAMPS = {
    "float VEC4": np.array([[1, 1, 1, 0], [1, 1, 1, 1]], np.float32),
    "unsigned byte VEC4": np.array([[255, 255, 255, 0], [255, 255, 255, 255]], np.uint8),
    "unsigned short VEC4": np.array([[65535] * 3 + [0], [65535] * 4], np.uint16),
}


@pytest.mark.parametrize("encoding", list(RAMPS))
def test_vertex_alpha_ramp_covers_half_the_card(tmp_path, encoding):
    loaded = scenes.load(_ramp_glb(tmp_path / "ramp.glb", RAMPS[encoding]))
    (mask,) = loaded.alpha.masks
    assert mask.vertex_alpha and mask.texture is None
    ch, _ = render_reference(loaded, ReferenceSettings(spp=64, channels=("coverage",)), quiet=True)
    px = (SPAN / RES) ** 2
    area = float(np.sum(ch["coverage"])) * px
    se = float(np.sqrt(np.sum(ch["coverage_stderr"].astype(np.float64) ** 2))) * px
    # alpha = (x + 1) / 2 across the card: kept where x >= 0, half of its 4 square metres
    assert abs(area - 2.0) <= Z * se + 1e-9
    assert se < 0.02
    # and on the right half: the covered pixels' mean x is +0.5
    xs = (np.arange(RES) + 0.5) / RES * SPAN - SPAN / 2
    cov = ch["coverage"].astype(np.float64)
    assert float((cov.sum(axis=0) * xs).sum() / cov.sum()) == pytest.approx(0.5, abs=0.05)


def test_vec3_colour_is_alpha_one(tmp_path):
    """A VEC3 COLOR_0 has no alpha: the whole card is kept."""
    white = np.ones((2, 3), np.float32)
    loaded = scenes.load(_ramp_glb(tmp_path / "v3.glb", white))
    ch, _ = render_reference(loaded, ReferenceSettings(spp=4, channels=("coverage",)), quiet=True)
    assert float(np.sum(ch["coverage"])) * (SPAN / RES) ** 2 == pytest.approx(4.0, abs=0.1)


@pytest.mark.parametrize(
    ("colors", "mode", "message"),
    [
        (np.array([[1, 1, 1, -0.5], [1, 1, 1, 1]], np.float32), "MASK", "outside \\[0, 1\\]"),
        (np.array([[1, 1, 1, np.nan], [1, 1, 1, 1]], np.float32), "MASK", "finite"),
        (np.array([[0.2, 1, 1, 1], [1, 1, 1, 1]], np.float32), "MASK", "tints the base colour"),
        (np.array([[1, 1, 1, 0], [1, 1, 1, 1]], np.float32), "OPAQUE", "not alphaMode MASK"),
    ],
)
def test_bad_vertex_colours_are_refused_in_one_line(tmp_path, colors, mode, message):
    with pytest.raises(scenes.SceneError, match=message):
        scenes.load(_ramp_glb(tmp_path / "bad.glb", colors, mode=mode))


@pytest.mark.parametrize("technique", ["alpha-test", "alpha-hashed"])
def test_the_alpha_rules_read_the_vertex_alpha_too(tmp_path, technique):
    """The registered rules multiply the interpolated vertex alpha in as the truth does: the
    ramp card (no texture) is kept on its right half, 2 of its 4 square metres (the plain
    test to a pixel column; hashed alpha's uniform threshold keeps the ramp's mean alpha,
    half the card too)."""
    from raster_oracle import raster_models as rm

    loaded = scenes.load(_ramp_glb(tmp_path / "ramp.glb", RAMPS["float VEC4"]))
    cov = rm.run(technique, loaded, samples=4).outputs["coverage"].astype(np.float64)
    px = (SPAN / RES) ** 2
    tol = 0.1 if technique == "alpha-test" else 0.25
    assert float(cov.sum()) * px == pytest.approx(2.0, abs=tol)
    if technique == "alpha-test":
        c = (np.arange(RES) + 0.5) / RES * SPAN - SPAN / 2  # pixel centres, x and z alike
        inner = np.abs(c) < 0.95
        assert np.all(cov[np.ix_(inner, (c > 0.05) & (c < 0.95))] == 1.0)
        assert np.all(cov[:, c < -0.05] == 0.0)
