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
    assert stats["alpha_tested"]["shapes"]["card"]["cutoff"] == cut


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


def _soft_scene(kind: str):
    """A 2 x 2 m plate 2 m above a ground under a 1 m square area light: ``mask`` (a Mitsuba
    mask BSDF whose opacity is the 0/1 checker, NEAREST), ``split`` (the two opaque squares
    the checker keeps) or ``full`` (the whole plate, opaque)."""
    from raster_oracle.scenes import backend
    from raster_oracle.scenes.catalogue.factories import diffuse, ground, sensor
    from raster_oracle.scenes.catalogue.soft_scenes import rectangle_light

    def square(x0, z0, x1, z1, bsdf):
        v = np.array([[x0, 2, z0], [x1, 2, z0], [x1, 2, z1], [x0, 2, z1]], np.float32)
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
        f = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
        return {"type": "ro_mesh", "vertices": v, "faces": f, "texcoords": uv, "bsdf": bsdf}

    def factory(width, height):
        scene = {
            "type": "scene",
            "camera": sensor(
                width, height, origin=(0, 9, 0.01), target=(0, 0, 0), fov=40, near=0.1, far=50
            ),
            "area_light": rectangle_light((0.3, 5.0, 0.2), (0, -1, 0), (1.0, 1.0), 40.0),
            "ground": ground(20.0, 0.6),
        }
        grey = diffuse((0.5, 0.5, 0.5))
        if kind == "mask":
            checker = np.array([[1, 0], [0, 1]], np.float32)[..., None]
            opacity = {
                "type": "bitmap",
                "data": backend.mitsuba().TensorXf(checker),
                "raw": True,
                "filter_type": "nearest",
                "wrap_mode": "clamp",
            }
            mask = {"type": "mask", "opacity": opacity, "material": grey}
            scene["plate"] = square(-1, -1, 1, 1, mask)
        elif kind == "split":
            scene["a"], scene["b"] = square(-1, -1, 0, 0, grey), square(0, 0, 1, 1, grey)
        else:
            scene["plate"] = square(-1, -1, 1, 1, grey)
        return scene

    from raster_oracle.scenes.catalogue.builtin import BuiltinScene

    return scenes.load(BuiltinScene(f"soft-{kind}", factory, "test", 48, 48))


def test_area_light_shadow_sees_the_cut_out_surface():
    settings = ReferenceSettings(spp=16, channels=("soft", "visibility"))
    mask, split, full = (
        render_reference(_soft_scene(k), settings, quiet=True)[0] for k in ("mask", "split", "full")
    )
    assert _soft_scene("mask").alpha is not None
    for ch in ("soft_visibility", "visibility"):
        # the mask plate shadows as the two squares it keeps, not as the whole plate
        assert np.mean(np.abs(mask[ch] - split[ch])) < 0.005
        assert np.mean(np.abs(mask[ch] - full[ch])) > 0.03


def test_export_writes_mask_and_loads_back_to_the_same_bytes(tmp_path):
    import json

    from raster_oracle.scenes.formats.export import export

    loaded = scenes.load("alpha-foliage:n=200", width=64, height=36)
    export(loaded, tmp_path / "out")
    back = scenes.load(tmp_path / "out" / "scene.glb")
    (a,), (b,) = loaded.alpha.masks, back.alpha.masks
    assert (b.cutoff, b.factor, b.texture.wrap_s, b.texture.nearest) == (0.5, 1.0, "repeat", False)
    assert np.array_equal(a.texture.alpha, b.texture.alpha)
    record = json.loads((tmp_path / "out" / "materials.json").read_text())
    assert record["shapes"]["cards"]["alpha"]["cutoff"] == 0.5
    settings = ReferenceSettings(spp=4, seed=5, channels=("visibility", "coverage"))
    x, _ = render_reference(loaded, settings, quiet=True)
    y, _ = render_reference(back, settings, quiet=True)
    for key in ("visibility", "coverage"):
        assert x[key].tobytes() == y[key].tobytes(), key


def test_shadow_map_depth_pass_discards_or_ignores_the_cutout(tmp_path):
    from raster_oracle.raster_models.registry import run

    loaded = scenes.load(_checker_glb(tmp_path / "s.glb"))
    px = (SPAN / RES) ** 2
    area = {}
    for mode in ("test", "ignore"):
        vis = run("shadow-map", loaded, resolution=1024, caster_alpha=mode).outputs["visibility"]
        area[mode] = float(np.sum(1.0 - vis)) * px
    # the depth pass that discards keeps the checker's half of the 4 square metres; the one
    # that ignores alpha (three.js issues 24995, 31802) casts the whole quad
    assert area["test"] == pytest.approx(2.0, abs=0.15)
    assert area["ignore"] == pytest.approx(4.0, abs=0.15)


@pytest.mark.parametrize("technique", ["noaa", "msaa", "acaa"])
def test_aa_models_sample_the_cut_out_surface(tmp_path, technique):
    from raster_oracle.raster_models.registry import run

    loaded = scenes.load(_facing_glb(tmp_path / "f.glb"))
    kw = {} if technique == "noaa" else {"samples": 4}
    cover = run(technique, loaded, **kw).outputs["coverage"]
    # the NEAREST checker keeps half the 4 square metres: a model that ignored alpha
    # would cover all of them
    assert float(np.sum(cover)) * (SPAN / RES) ** 2 == pytest.approx(2.0, abs=0.1)
