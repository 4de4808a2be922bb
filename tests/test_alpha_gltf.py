"""glTF MASK scenes end to end: loading (MASK accepted, BLEND refused, alphaCutoff default),
the truth's coverage and shadow of an alpha-tested checker quad against their closed forms,
exact coverage refusing alpha-tested shapes, and the alpha-foliage family."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.formats import gltf_write as gw
from raster_oracle.scenes.shading.alpha import checker_coverage

from raster_oracle import scenes

#: Film of the checker scenes: 3 x 3 m seen orthographically, 64 pixels a side.
RES, SPAN = 64, 3.0
#: Agreement with a closed form within this many standard errors of the reference.
Z = 4.0


def _down_camera(centre):
    """An orthographic glTF camera 10 m above ``centre`` looking straight down, image up
    along -Z, 3 m across."""
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = (1, 0, 0), (0, 0, -1), (0, 1, 0)
    m[:3, 3] = np.asarray(centre, float) + (0, 10, 0)
    return gw.GltfCamera(m, 0.1, 30.0, ymag=SPAN / 2, aspect=1.0, film=(RES, RES))


def _checker_glb(path, *, mode="MASK", cutoff=None, nearest=True, ground=True) -> str:
    """A vertical 2 x 2 m quad (x in [-1, 1], y in [1, 3], z = 0) whose base colour alpha is
    a 2 x 2 checker (CLAMP_TO_EDGE), over a ground; the sun travels along (0, -1, 1), so the
    quad's shadow falls on z in [1, 3] with the quad's own shape and area; the camera looks
    straight down at (0, 0, 2) (the quad itself is edge-on, outside the view)."""
    quad = np.array([[-1, 3, 0], [1, 3, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)  # v = 0 at the top
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
    meshes = [gw.GltfMesh("card", quad, faces, 0, np.tile([0, 0, 1], (4, 1)), uv)]
    if ground:
        g = np.array([[-4, 0, -2], [4, 0, -2], [4, 0, 6], [-4, 0, 6]], np.float32)
        meshes.append(gw.GltfMesh("ground", g, faces, 1, np.tile([0, 1, 0], (4, 1)), uv))
    rgba = np.ones((2, 2, 4))
    rgba[..., 3] = [[1, 0], [0, 1]]
    card = {"name": "card", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}
    card["doubleSided"] = True
    if mode != "OPAQUE":
        card["alphaMode"] = mode
    if cutoff is not None:
        card["alphaCutoff"] = cutoff
    soil = {"name": "soil", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}}
    sampler = {"magFilter": 9728 if nearest else 9729, "wrapS": 33071, "wrapT": 33071}
    data = gw.glb_bytes(
        camera=_down_camera((0, 0, 2)),
        lights=[gw.GltfLight("sun", "directional", gw.light_matrix((0, -1, 1)), intensity=3.0)],
        meshes=meshes,
        materials=[card, soil],
        images=[gw.png_bytes(rgba)],
        textures=[{"source": 0, "sampler": 0}],
        samplers=[sampler],
    )
    path.write_bytes(data)
    return str(path)


def test_mask_accepted_cutoff_default_and_blend_refused(tmp_path):
    loaded = scenes.load(_checker_glb(tmp_path / "mask.glb"))
    assert loaded.alpha is not None and loaded.alpha.any
    (mask,) = loaded.alpha.masks
    assert mask.cutoff == 0.5 and mask.texture.nearest  # alphaCutoff absent: 0.5
    assert mask.texture.alpha.tolist() == [[1.0, 0.0], [0.0, 1.0]]
    names = loaded.shape_names
    assert loaded.alpha.shape_mask[names.index("card")] == 0
    assert loaded.alpha.shape_mask[names.index("ground")] == -1
    other = scenes.load(_checker_glb(tmp_path / "c.glb", cutoff=0.25))
    assert other.alpha.masks[0].cutoff == 0.25
    assert scenes.load(_checker_glb(tmp_path / "o.glb", mode="OPAQUE")).alpha is None
    with pytest.raises(scenes.SceneError, match="alphaMode BLEND; only OPAQUE and MASK"):
        scenes.load(_checker_glb(tmp_path / "blend.glb", mode="BLEND"))


@pytest.mark.parametrize(("nearest", "cutoff"), [(True, 0.5), (False, 0.5), (False, 0.3)])
def test_checker_shadow_area_within_4_standard_errors(tmp_path, nearest, cutoff):
    loaded = scenes.load(_checker_glb(tmp_path / "s.glb", nearest=nearest, cutoff=cutoff))
    ch, _ = render_reference(
        loaded, ReferenceSettings(spp=64, channels=("visibility",)), quiet=True
    )
    px = (SPAN / RES) ** 2
    area = float(np.sum(1.0 - ch["visibility"])) * px
    se = float(np.sqrt(np.sum(ch["visibility_stderr"].astype(np.float64) ** 2))) * px
    expect = 4.0 * checker_coverage(cutoff=cutoff, nearest=nearest, wrap="clamp")
    assert abs(area - expect) <= Z * se + 1e-9
    assert se < 0.02  # the test has teeth: the bound is a few hundredths of a square metre
    # the opaque quad casts its whole 4 square metres
    opaque = scenes.load(_checker_glb(tmp_path / "o.glb", mode="OPAQUE"))
    settings = ReferenceSettings(spp=16, channels=("visibility",))
    ch, _ = render_reference(opaque, settings, quiet=True)
    assert float(np.sum(1.0 - ch["visibility"])) * px == pytest.approx(4.0, abs=0.1)


def _facing_glb(path, *, cutoff=None, nearest=True) -> str:
    """The checker card alone, seen face-on from 10 m (the same 3 m orthographic view)."""
    rgba = np.ones((2, 2, 4))
    rgba[..., 3] = [[1, 0], [0, 1]]
    quad = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
    card = {"name": "card", "alphaMode": "MASK", "doubleSided": True}
    card["pbrMetallicRoughness"] = {"baseColorTexture": {"index": 0}}
    if cutoff is not None:
        card["alphaCutoff"] = cutoff
    data = gw.glb_bytes(
        camera=_down_camera((0, 0, 0)),
        lights=[gw.GltfLight("sun", "directional", gw.light_matrix((0, -1, 0.2)), intensity=3.0)],
        meshes=[gw.GltfMesh("card", quad, faces, 0, np.tile([0, 1, 0], (4, 1)), uv)],
        materials=[card],
        images=[gw.png_bytes(rgba)],
        textures=[{"source": 0, "sampler": 0}],
        samplers=[{"magFilter": 9728 if nearest else 9729, "wrapS": 33071, "wrapT": 33071}],
    )
    path.write_bytes(data)
    return str(path)


@pytest.mark.parametrize(("nearest", "cutoff"), [(True, None), (False, 0.3), (False, 1.5)])
def test_checker_coverage_and_exact_coverage_refused(tmp_path, nearest, cutoff):
    loaded = scenes.load(_facing_glb(tmp_path / "f.glb", cutoff=cutoff, nearest=nearest))
    settings = ReferenceSettings(spp=64, channels=("coverage", "coverage_exact"))
    ch, stats = render_reference(loaded, settings, quiet=True)
    px = (SPAN / RES) ** 2
    area = float(np.sum(ch["coverage"])) * px
    se = float(np.sqrt(np.sum(ch["coverage_stderr"].astype(np.float64) ** 2))) * px
    cut = 0.5 if cutoff is None else cutoff
    expect = 4.0 * checker_coverage(cutoff=cut, nearest=nearest, wrap="clamp")
    assert abs(area - expect) <= Z * se + 1e-9
    if cutoff == 1.5:  # a cutoff above every alpha: an empty surface
        assert not np.any(ch["coverage"])
    # exact coverage does not claim the triangles' area, and says why
    assert not np.any(ch["coverage_exact_valid"])
    assert "alpha-tested shapes" in stats["coverage_exact"]["decision"]


def test_alpha_foliage_family(tmp_path):
    loaded = scenes.load("alpha-foliage:n=300", width=96, height=54)
    assert loaded.alpha is not None and loaded.alpha.masks[0].texture.wrap_s == "repeat"
    opaque = scenes.load("alpha-foliage:n=300:alpha=0", width=96, height=54)
    assert opaque.alpha is None
    settings = ReferenceSettings(spp=4, channels=("coverage",))
    cut, _ = render_reference(loaded, settings, quiet=True)
    full, _ = render_reference(opaque, settings, quiet=True)
    # the leaf texture keeps about 37 % of each card: the cut-out cards cover less
    assert 0.2 < cut["coverage"].mean() < 0.8 * full["coverage"].mean()
    with pytest.raises(scenes.SceneError, match=r"alpha must be in \[0, 1\], got 2"):
        scenes.load("alpha-foliage:alpha=2")
