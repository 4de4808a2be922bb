"""glTF 2.0 scenes (issue 29): loading, the glTF BRDF as the colour truth, KHR lights.

Closed forms: the oracle's colour at pixel centres of a flat plane equals the specification's
BRDF evaluated by hand (tests/gltf_scenes.py, float64, none of the oracle's code) under a
directional, a point and a spot light.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from gltf_scenes import flat_plane, pbr_material, plate_twin, spec_brdf
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.backend.raycast import trace_film
from raster_oracle.scenes.formats.gltf_write import GltfLight, light_matrix

from raster_oracle import scenes

W, H = 96, 54
#: The oracle shades in float32 (Dr.Jit), the hand evaluation in float64: directions and
#: dot products carry ~1e-7 relative error; away from the specular peak (the views below
#: keep it out of the picture) the BRDF's sensitivity keeps the result within 1e-5.
REL = 1e-5


@pytest.fixture(scope="module")
def plate_pair(tmp_path_factory):
    ref = scenes.load("plate", width=W, height=H)
    path = tmp_path_factory.mktemp("gltf") / "plate.glb"
    path.write_bytes(plate_twin(ref))
    return ref, scenes.load(path, width=W, height=H)


def test_plate_twin_gives_the_same_visibility_and_coverage_bytes(plate_pair):
    ref, twin = plate_pair
    assert twin.shape_names == ref.shape_names
    assert twin.pbr is not None and ref.pbr is None
    assert "gltf" in twin.provenance()["shading_model"]
    assert "lambert" in ref.provenance()["shading_model"]
    settings = ReferenceSettings(spp=16, seed=3, channels=("visibility", "coverage", "color"))
    a, _ = render_reference(ref, settings, quiet=True)
    b, _ = render_reference(twin, settings, quiet=True)
    for key in ("visibility", "visibility_stderr", "coverage", "coverage_stderr"):
        assert a[key].tobytes() == b[key].tobytes(), key
    assert 0.02 < 1.0 - a["visibility"].mean() < 0.5  # the shadow is in view
    # the colours differ (Lambert against the glTF BRDF, roughness 1: a weak specular lobe)
    assert not np.array_equal(a["color.R"], b["color.R"])


def _centres(loaded):
    y, x = np.mgrid[0 : loaded.height, 0 : loaded.width] + 0.5
    res = trace_film(loaded, x.ravel(), y.ravel(), color=True)
    assert res["valid"].all()
    return res


def _expected(loaded, res, base, metallic, roughness):
    p = res["position"].astype(np.float64)
    y, x = np.mgrid[0 : loaded.height, 0 : loaded.width] + 0.5
    v = -loaded.camera.rays(x.ravel(), y.ravel())[1]  # towards the eye (either projection)
    n = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    light = loaded.light
    if light.kind == "directional":
        l_dir = -np.asarray(light.direction)
        l_vec = np.tile(l_dir / np.linalg.norm(l_dir), (len(p), 1))
        scale = np.ones(len(p))
    else:
        delta = np.asarray(light.position)[None] - p
        d = np.linalg.norm(delta, axis=1)
        l_vec = delta / d[:, None]
        scale = 1.0 / d**2
        if light.range:
            scale *= np.clip(1 - (d / light.range) ** 4, 0, 1)
        if light.kind == "spot":
            cos_o = math.cos(math.radians(light.cutoff_angle))
            cos_i = math.cos(math.radians(light.beam_width))
            s = 1.0 / max(0.001, cos_i - cos_o)
            cd = -(l_vec @ np.asarray(light.direction))
            scale *= np.clip(cd * s - cos_o * s, 0, 1) ** 2
    f = spec_brdf(base, metallic, roughness, n, l_vec, v)
    cos = np.maximum(l_vec[:, 1], 0)
    return f * np.asarray(light.color)[None] * (scale * cos)[:, None]


@pytest.mark.parametrize("metallic", [0.0, 1.0])
@pytest.mark.parametrize("roughness", [0.1, 0.5, 1.0])
def test_directional_light_matches_the_spec_brdf_at_every_pixel_centre(
    tmp_path, roughness, metallic
):
    base = (0.8, 0.5, 0.2)
    sun = GltfLight("sun", "directional", light_matrix((0.3, -1.0, -0.5)), intensity=2.5)
    path = tmp_path / "plane.glb"
    path.write_bytes(flat_plane(lights=[sun], material=pbr_material(base, metallic, roughness)))
    loaded = scenes.load(path, width=48, height=27)
    d = np.array([0.3, -1.0, -0.5])
    np.testing.assert_allclose(loaded.light.direction, d / np.linalg.norm(d), rtol=1e-6)
    assert loaded.light.color == (2.5, 2.5, 2.5)  # lux as the linear irradiance
    res = _centres(loaded)
    want = _expected(loaded, res, base, metallic, roughness)
    got = res["color"].astype(np.float64)
    assert want.min() > 0
    np.testing.assert_allclose(got, want, rtol=REL, atol=0)


def test_point_light_inverse_square_along_a_row(tmp_path):
    base = (0.6, 0.6, 0.6)
    point = GltfLight("lamp", "point", light_matrix(None, (0.0, 2.0, 0.0)), intensity=40.0)
    path = tmp_path / "point.glb"
    mat = pbr_material(base, 0.0, 0.5)
    path.write_bytes(flat_plane(lights=[point], material=mat, ortho=4.0))
    loaded = scenes.load(path, width=64, height=16)
    np.testing.assert_allclose(loaded.light.position, [0.0, 2.0, 0.0])
    assert loaded.light.color == (40.0, 40.0, 40.0)  # candela as the linear intensity
    res = _centres(loaded)
    row = slice(7 * 64, 8 * 64)  # a row of pixels through the light's foot
    want = _expected(loaded, res, base, 0.0, 0.5)[row]
    np.testing.assert_allclose(res["color"][row], want, rtol=REL, atol=0)
    # the row is symmetric about the light's foot, brightest there
    c = res["color"][row, 0]
    assert np.argmax(c) in (31, 32)
    np.testing.assert_allclose(c, c[::-1], rtol=REL)


def test_point_light_range_window(tmp_path):
    point = GltfLight("lamp", "point", light_matrix(None, (0.0, 2.0, 0.0)), 40.0, range=6.0)
    point.intensity = 40.0
    point.color = (1.0, 1.0, 1.0)
    path = tmp_path / "range.glb"
    path.write_bytes(
        flat_plane(lights=[point], material=pbr_material((0.6,) * 3, 0.0, 0.5), ortho=4.0)
    )
    loaded = scenes.load(path, width=64, height=16)
    assert loaded.light.range == 6.0
    res = _centres(loaded)
    want = _expected(loaded, res, (0.6,) * 3, 0.0, 0.5)
    np.testing.assert_allclose(res["color"], want, rtol=REL, atol=1e-12)
    d = np.linalg.norm(res["position"] - np.array([0, 2.0, 0], np.float32), axis=1)
    assert (res["color"][d > 6.0] == 0).all() and (res["color"][d < 5.5] > 0).all()


def test_spot_cone_attenuation_along_a_row(tmp_path):
    spot = GltfLight(
        "spot",
        "spot",
        light_matrix((0.0, -1.0, 0.0), (0.0, 3.0, 0.0)),
        intensity=60.0,
        inner=math.radians(20.0),
        outer=math.radians(45.0),
    )
    path = tmp_path / "spot.glb"
    path.write_bytes(
        flat_plane(lights=[spot], material=pbr_material((0.7,) * 3, 0.0, 0.8), ortho=4.0)
    )
    loaded = scenes.load(path, width=64, height=16)
    assert loaded.light.model == "gltf" and loaded.light.cutoff_angle == pytest.approx(45.0)
    assert loaded.light.beam_width == pytest.approx(20.0)
    np.testing.assert_allclose(loaded.light.position, [0.0, 3.0, 0.0])
    res = _centres(loaded)
    row = slice(7 * 64, 8 * 64)
    want = _expected(loaded, res, (0.7,) * 3, 0.0, 0.8)[row]
    np.testing.assert_allclose(res["color"][row], want, rtol=REL, atol=1e-12)
    # outside the outer cone (|x| > 3 tan 45 deg = 3) the colour is exactly 0; inside the
    # inner cone the cone factor is 1, between them strictly between
    x = np.abs(res["position"][row, 0])
    assert (res["color"][row][x > 3.01] == 0).all()
    assert (res["color"][row][x < 2.9] > 0).all()


def _srgb_decode(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.mark.parametrize(
    "tangent, below",
    [(None, False), ((0.0, 0.0, 1.0, -1.0), False), (None, True), ((0.0, 0.0, 1.0, -1.0), True)],
)
def test_textures_and_normal_texture_match_the_spec_by_hand(tmp_path, tangent, below):
    """Constant textures: base colour sRGB-decoded, metallic from B and roughness from G
    (times the factors), emissive sRGB; the normal texture bends the normal in the tangent
    frame: ``T = dp/du`` (+X here) and ``B = n x T`` without ``TANGENT``, ``T`` and
    ``B = w (n x T)`` with one (+Z and w = -1: B = -X). Seen from below (a back face, lit
    from below) the normal, tangent and bitangent all flip, as in the sample renderer: the
    bent normal is the front one negated."""
    from raster_oracle.scenes.formats.gltf_write import png_bytes

    texel = {  # 8-bit values as the PNGs store them
        "base": np.array([200, 100, 50]) / 255,
        "mr": np.array([0, 140, 200]) / 255,
        "emissive": np.array([30, 60, 90]) / 255,
        "normal": np.array([170, 100, 230]) / 255,
    }
    images = [png_bytes(np.broadcast_to(texel[k], (2, 2, 3))) for k in texel]
    material = {
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.9, 1.0, 0.8, 1.0],
            "metallicFactor": 0.7,
            "roughnessFactor": 0.9,
            "baseColorTexture": {"index": 0},
            "metallicRoughnessTexture": {"index": 1},
        },
        "emissiveFactor": [0.5, 0.25, 1.0],
        "emissiveTexture": {"index": 2},
        "normalTexture": {"index": 3, "scale": 0.8},
    }
    sun_dir = (0.3, 1.0 if below else -1.0, -0.5)
    sun = GltfLight("sun", "directional", light_matrix(sun_dir), intensity=2.5)
    path = tmp_path / "textured.glb"
    glb = flat_plane(lights=[sun], material=material, images=images, tangents=tangent, below=below)
    path.write_bytes(glb)
    loaded = scenes.load(path, width=48, height=27)
    res = _centres(loaded)
    base = _srgb_decode(texel["base"]) * [0.9, 1.0, 0.8]
    metallic, roughness = 0.7 * texel["mr"][2], 0.9 * texel["mr"][1]
    emissive = _srgb_decode(texel["emissive"]) * [0.5, 0.25, 1.0]
    t, b = (np.array([1.0, 0, 0]), np.array([0, 0, -1.0]))
    if tangent is not None:
        t, b = np.array([0, 0, 1.0]), -np.cross([0.0, 1.0, 0.0], [0, 0, 1.0])
    x, y, z = 2 * texel["normal"] - 1
    n = 0.8 * x * t + 0.8 * y * b + z * np.array([0.0, 1.0, 0.0])
    n /= np.linalg.norm(n) * (-1.0 if below else 1.0)
    y, x_ = np.mgrid[0 : loaded.height, 0 : loaded.width] + 0.5
    v = -loaded.camera.rays(x_.ravel(), y.ravel())[1]
    ld = -np.asarray(loaded.light.direction)
    l_vec = np.tile(ld / np.linalg.norm(ld), (len(v), 1))
    nn = np.tile(n, (len(v), 1))
    f = spec_brdf(base, metallic, roughness, nn, l_vec, v)
    want = f * np.asarray(loaded.light.color) * np.maximum(l_vec @ n, 0)[:, None] + emissive
    np.testing.assert_allclose(res["color"], want, rtol=REL, atol=0)
    np.testing.assert_allclose(res["albedo"], np.tile(base, (len(v), 1)), rtol=1e-6)
