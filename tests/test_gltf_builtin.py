"""The built-in glTF scenes and the AA models on glTF content (issue 29).

``pbr-spheres`` and ``pbr-foliage`` are GLB bytes written by the project's own writer and
read back by the glTF loader; the default sweep runs them. The anti-aliasing models shade
them with the glTF BRDF: where MSAA shades one fragment at the pixel centre of a flat
textured, normal-mapped surface, its colour is the oracle's own shading there (noaa).
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.oracle.sweeps.mainjob import default_spec
from raster_oracle.raster_models.registry import family_of, run
from raster_oracle.scenes.backend.raycast import trace_film
from raster_oracle.scenes.formats.export import export

from raster_oracle import scenes

W, H = 96, 54
#: MSAA's pixel-centre attributes are extrapolated from a sample's hit in float32; on the
#: flat ground (one plane, uv linear in position) they equal the centre hit's within float32
#: rounding of positions ~10 units from the origin (relative 1e-6), which the bilinear
#: texture lookups and the BRDF keep below this.
CENTRE_RTOL = 2e-4


@pytest.mark.parametrize("name", ["pbr-spheres", "pbr-foliage"])
def test_builtin_gltf_scenes_load_with_the_gltf_brdf(name):
    a = scenes.load(name, width=W, height=H)
    b = scenes.load(name, width=W, height=H)
    assert a.pbr is not None and a.content_hash == b.content_hash  # same bytes each time
    assert a.provenance()["shading_model"].startswith("gltf-metallic-roughness")
    assert all(lt.model == "gltf" for lt in a.lights)
    assert scenes.BUILTIN_SCENES[name].kind == "gltf"
    spec_scenes = {s for case in default_spec()["case"] for s in case["scenes"]}
    assert name in spec_scenes
    families = {family_of(c["technique"]) for c in default_spec()["case"] if name in c["scenes"]}
    assert families == {"shadow", "aa"}


def test_sphere_grid_materials_and_lights():
    loaded = scenes.load("pbr-spheres", width=W, height=H)
    assert [lt.kind for lt in loaded.lights] == ["directional", "spot"]
    pbr = loaded.pbr
    mats = {m.name: m for m in pbr.materials}
    assert {m.metallic for m in pbr.materials if m.name.startswith("m")} == {0.0, 0.5, 1.0}
    ground = mats["ground"]
    assert min(ground.base_color_texture, ground.metallic_roughness_texture) >= 0
    assert ground.normal_texture >= 0 and pbr.has_normal_textures
    assert sum(any(m.emissive) for m in pbr.materials) == 1
    assert "scenes.shading.pbr" not in loaded.shading_model and "gltf" in loaded.shading_model


@pytest.mark.parametrize("light", [0, 1])
def test_export_of_a_gltf_scene_loads_back_to_the_same_bytes(tmp_path, light):
    loaded = scenes.load("pbr-spheres", width=W, height=H, light=light)
    export(loaded, tmp_path / "out")
    back = scenes.load(tmp_path / "out" / "scene.glb", light=light)
    assert (back.width, back.height) == (W, H)
    assert back.light == loaded.light
    settings = ReferenceSettings(spp=4, seed=5, channels=("visibility", "coverage", "color"))
    a, _ = render_reference(loaded, settings, quiet=True)
    b, _ = render_reference(back, settings, quiet=True)
    for key in ("visibility", "coverage", "color.R", "color.G", "color.B"):
        assert a[key].tobytes() == b[key].tobytes(), key


@pytest.mark.parametrize(
    "technique, params",
    [("msaa", {"samples": 4}), ("acaa", {"samples": 4}), ("agaa", {"aggregates": 2})],
)
def test_aa_models_shade_a_flat_textured_surface_as_the_oracle_does(technique, params):
    """One surface in the pixel: the model's fragment (ACAA: its accumulated fragment, AGAA:
    its one aggregate) is shaded at the pixel centre with the glTF material there."""
    loaded = scenes.load("pbr-spheres", width=W, height=H)
    ground = loaded.shape_names.index("ground")
    msaa = run(technique, loaded, **params).outputs["color"]
    noaa = run("noaa", loaded).outputs["color"]
    # pixels whose whole square (an 8x8 grid of points) hits the ground, all lit or all not,
    # as their 8 neighbours do (AGAA filters the visibility of its N samples)
    g = (np.arange(8) + 0.5) / 8
    oy, ox = np.meshgrid(g, g, indexing="ij")
    py, px = np.mgrid[0:H, 0:W]
    x = (px[..., None] + ox.ravel()).ravel()
    y = (py[..., None] + oy.ravel()).ravel()
    res = trace_film(loaded, x, y)
    shape = res["shape"].reshape(H, W, -1)
    lit = res["lit"].reshape(H, W, -1)
    inside = (shape == ground).all(-1) & (lit.all(-1) | ~lit.any(-1))
    state = np.where(inside, lit[..., 0], 2).astype(np.int8)  # 2: not a clean pixel
    pad = np.pad(state, 1, constant_values=2)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inside &= pad[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W] == state
    assert inside.sum() > 0.3 * W * H
    np.testing.assert_allclose(msaa[inside], noaa[inside], rtol=CENTRE_RTOL, atol=1e-6)
    assert np.abs(msaa - noaa).max() > 0.01  # and the edges do differ


#: Mean radiance of a model's frame against the reference's on pbr-foliage (thin leaves:
#: 1-sample shading (the input of FXAA and SMAA) misses or doubles leaves; FXAA: 5.6 %).
MEAN_RTOL = {"ssaa": 0.02, "msaa": 0.05, "acaa": 0.05, "agaa": 0.05, "fxaa": 0.1, "smaa": 0.1}


@pytest.mark.parametrize("technique", sorted(MEAN_RTOL))
def test_aa_models_run_on_gltf_content(technique):
    loaded = scenes.load("pbr-foliage", width=W, height=H)
    ch, _ = render_reference(loaded, ReferenceSettings(spp=16, channels=("color",)), quiet=True)
    ref = np.stack([ch[f"color.{c}"] for c in "RGB"], -1)
    out = run(technique, loaded).outputs["color"]
    assert out.shape == ref.shape and np.isfinite(out).all()
    # the same shading model: mean radiance within a few percent of the reference's
    assert abs(out.mean() - ref.mean()) < MEAN_RTOL[technique] * ref.mean()
