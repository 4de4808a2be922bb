"""Alpha-tested surfaces (glTF MASK): the alpha sampler, its closed forms and the alpha-tested
closest hit of the intersection engine (scenes.shading.alpha, scenes.backend.alpha_hit)."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.scenes.backend.alpha_hit import alpha_scene, closest_hit_alpha, occluded_alpha
from raster_oracle.scenes.geometry.uv_mesh import QUAD_FACES, uv_mesh
from raster_oracle.scenes.shading.alpha import (
    ALPHA_ATTRIBUTE,
    DEFAULT_CUTOFF,
    AlphaError,
    AlphaMask,
    AlphaTable,
    AlphaTexture,
    checker_coverage,
    checker_texture,
    gltf_alpha_mode,
    sample_np,
    wrap_index_np,
)

#: Rays (and NumPy samples) per side of the stratified grid over the quad.
GRID = 512
#: A stratified grid's count differs from the area only in cells the covered region's boundary
#: crosses: at most 2 cells per unit of boundary length per 1/GRID, and the checker's 0.5
#: contour under LINEAR is at most 4 quad widths long.
GRID_BOUND = 8.0 / GRID
#: float32 texel arithmetic of the Dr.Jit sampler against NumPy's float64.
DR_TOL = 2e-5
WRAPS = ("repeat", "clamp", "mirror")


def _grid(n=GRID):
    g = (np.arange(n) + 0.5) / n
    return np.meshgrid(g, g)


def test_wrap_modes_follow_the_opengl_table():
    i = np.arange(-5, 7)
    assert wrap_index_np(i, 3, "repeat").tolist() == [1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0]
    assert wrap_index_np(i, 3, "clamp").tolist() == [0, 0, 0, 0, 0, 0, 1, 2, 2, 2, 2, 2]
    # MIRRORED_REPEAT: ... 1 2 2 1 0 | 0 1 2 | 2 1 0 0 1 ...
    assert wrap_index_np(i, 3, "mirror").tolist() == [1, 2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0]
    with pytest.raises(AlphaError, match="wrap mode must be one of"):
        wrap_index_np(i, 3, "border")


def test_nearest_and_linear_texel_selection():
    img = np.array([[0.0, 1.0], [2.0, 3.0]])
    # NEAREST picks the texel holding the point; row 0 is v in [0, 1/2)
    assert sample_np(img, 0.3, 0.2, nearest=True) == 0.0
    assert sample_np(img, 0.7, 0.8, nearest=True) == 3.0
    # LINEAR at texel centres gives the texel, midway the mean
    assert sample_np(img, 0.25, 0.75, wrap_s="clamp", wrap_t="clamp") == 2.0
    assert sample_np(img, 0.5, 0.5, wrap_s="clamp", wrap_t="clamp") == pytest.approx(1.5)
    # REPEAT at u = 0 blends the first and last columns, CLAMP keeps the first
    assert sample_np(img, 0.0, 0.25, wrap_t="clamp") == pytest.approx(0.5)
    assert sample_np(img, 0.0, 0.25, wrap_s="clamp", wrap_t="clamp") == 0.0
    assert sample_np(img, np.nan, 0.25) == 0.0


@pytest.mark.parametrize("wrap", WRAPS)
@pytest.mark.parametrize("nearest", [True, False])
@pytest.mark.parametrize("cutoff", [0.1, 0.3, 0.5, 0.62, 0.9, 1.0])
def test_checker_closed_form_against_dense_samples(wrap, nearest, cutoff):
    u, v = _grid(2048)
    tex = AlphaTexture(checker_texture(), wrap, wrap, nearest)
    measured = float(np.mean(tex.sample_np(u, v) >= cutoff))
    assert measured == pytest.approx(
        checker_coverage(cutoff=cutoff, nearest=nearest, wrap=wrap), abs=8.0 / 2048
    )


def test_checker_closed_form_values():
    # NEAREST: half the quad whatever the cutoff between the two alphas
    assert checker_coverage(cutoff=0.9, nearest=True, wrap="clamp") == 0.5
    # LINEAR at the mid value: the quadrants exactly (2 a b >= 0)
    assert checker_coverage(cutoff=0.5, nearest=False, wrap="repeat") == 0.5
    # cutoff = hi under clamp: only the four corner quarter-texel squares (alpha = hi exactly)
    assert checker_coverage(cutoff=1.0, nearest=False, wrap="clamp") == pytest.approx(0.125)
    assert checker_coverage(cutoff=1.0, nearest=False, wrap="repeat") == 0.0
    # symmetry about the mid value
    a = checker_coverage(cutoff=0.3, nearest=False, wrap="repeat")
    b = checker_coverage(cutoff=0.7, nearest=False, wrap="repeat")
    assert a + b == pytest.approx(1.0)
    assert checker_coverage(cutoff=1.01, nearest=False, wrap="clamp") == 0.0
    assert checker_coverage(cutoff=0.0, nearest=True, wrap="clamp") == 1.0


def test_alpha_cutoff_default_and_modes():
    assert gltf_alpha_mode({"alphaMode": "MASK"}) == ("MASK", DEFAULT_CUTOFF)
    assert DEFAULT_CUTOFF == 0.5
    assert AlphaMask().cutoff == 0.5
    assert gltf_alpha_mode({"alphaMode": "MASK", "alphaCutoff": 0.3}) == ("MASK", 0.3)
    assert gltf_alpha_mode({}) == ("OPAQUE", None)
    assert gltf_alpha_mode({"alphaCutoff": 0.2}) == ("OPAQUE", None)
    with pytest.raises(AlphaError, match="alphaMode BLEND; only OPAQUE and MASK"):
        gltf_alpha_mode({"alphaMode": "BLEND"}, label="material 3 (glass)")
    with pytest.raises(AlphaError, match="alphaCutoff must be a finite number >= 0"):
        gltf_alpha_mode({"alphaMode": "MASK", "alphaCutoff": -0.1})
    with pytest.raises(AlphaError, match="alphaCutoff must be a number"):
        gltf_alpha_mode({"alphaMode": "MASK", "alphaCutoff": "half"})
    with pytest.raises(AlphaError, match="expected OPAQUE, MASK or BLEND"):
        gltf_alpha_mode({"alphaMode": "CUTOUT"})


def test_table_numpy_alpha_and_vertex_alpha():
    tex = AlphaTexture(np.array([[0.2, 0.8]]), "clamp", "clamp", nearest=True)
    table = AlphaTable(
        [AlphaMask(factor=0.5, texture=tex, cutoff=0.3), AlphaMask(vertex_alpha=True)],
        np.array([-1, 0, 1]),
    )
    shape = np.array([-1, 1, 1, 2, 2, 0])  # sky, mask 0 twice, mask 1 twice, opaque
    u = np.array([0.1, 0.1, 0.9, 0.0, 0.0, 0.0])
    va = np.array([1.0, 1.0, 1.0, 0.4, 0.6, 0.1])
    assert table.alpha_np(shape, u, 0.5, va).tolist() == pytest.approx(
        [1.0, 0.1, 0.4, 0.4, 0.6, 1.0]
    )
    assert table.covered_np(shape, u, 0.5, va).tolist() == [True, False, True, False, True, True]
    with pytest.raises(AlphaError, match="shape_mask entries must be -1 or a mask index"):
        AlphaTable([AlphaMask()], np.array([1]))


def test_dr_sampler_matches_numpy(mi):
    import drjit as dr

    rng = np.random.default_rng(4)
    masks = []
    pairs = [("repeat", "clamp"), ("mirror", "repeat"), ("clamp", "clamp")]
    for k, (wrap_s, wrap_t) in enumerate(pairs):
        img = rng.uniform(0, 1, (3 + k, 5 - k))
        masks.append(AlphaMask(factor=0.9, texture=AlphaTexture(img, wrap_s, wrap_t, k == 1)))
    masks.append(AlphaMask(factor=0.7))
    table = AlphaTable(masks, np.arange(len(masks)))
    n = 4000
    m = rng.integers(0, len(masks), n)
    u, v = rng.uniform(-2.5, 3.5, n), rng.uniform(-2.5, 3.5, n)
    expect = table.alpha_np(m, u, v)
    got = table.alpha_dr(
        mi.Int32(m.astype(np.int32)), mi.Point2f(mi.Float(u), mi.Float(v)), None, mi.Bool(True)
    )
    dr.eval(got)
    assert np.max(np.abs(np.array(got) - expect)) < DR_TOL


def _quad(mi, y, *, vertex_alpha=None):
    corners = [[0, y, 0], [1, y, 0], [1, y, 1], [0, y, 1]]
    mesh = uv_mesh(mi, "quad", corners, QUAD_FACES, [[0, 0], [1, 0], [1, 1], [0, 1]])
    if vertex_alpha is not None:
        mesh.add_attribute(ALPHA_ATTRIBUTE, 1, np.asarray(vertex_alpha, np.float32))
    return mesh


def _down_rays(mi, n=GRID):
    x, z = _grid(n)
    o = mi.Point3f(mi.Float(x.ravel()), 5.0, mi.Float(z.ravel()))
    return mi.Ray3f(o, mi.Vector3f(0.0, -1.0, 0.0))


def _two_quads(mi, **kw):
    """An alpha-tested quad at y = 1 over an opaque one at y = 0."""
    return mi.load_dict({"type": "scene", "card": _quad(mi, 1.0, **kw), "floor": _quad(mi, 0.0)})


@pytest.mark.parametrize("wrap", ["repeat", "clamp"])
@pytest.mark.parametrize("nearest", [True, False])
@pytest.mark.parametrize("cutoff", [0.3, 0.62])
def test_checker_quad_traced_coverage(mi, wrap, nearest, cutoff):
    scene = _two_quads(mi)
    tex = AlphaTexture(checker_texture(), wrap, wrap, nearest)
    table = AlphaTable([AlphaMask(texture=tex, cutoff=cutoff)], np.array([0, -1]))
    ray = _down_rays(mi)
    si, layers, exhausted = closest_hit_alpha(
        scene, ray, alpha_scene(scene, table), flags=mi.RayFlags.UV
    )
    t = np.array(si.t)
    on_card = np.abs(t - 4.0) < 1e-4
    on_floor = np.abs(t - 5.0) < 1e-4
    assert np.all(on_card | on_floor)  # every ray ends on one of them, t from its origin
    expect = checker_coverage(cutoff=cutoff, nearest=nearest, wrap=wrap)
    if nearest:  # the grid is aligned with the texels: exact
        assert on_card.mean() == expect
    else:
        assert on_card.mean() == pytest.approx(expect, abs=GRID_BOUND)
    assert not np.any(np.array(exhausted))
    assert set(np.unique(np.array(layers))) == {0, 1}
    # the shadow query from above sees the floor everywhere (it is opaque)
    blocked, _ = occluded_alpha(scene, ray, alpha_scene(scene, table))
    assert np.all(np.array(blocked))
    # and without the floor, exactly the card's kept points block
    card_only = mi.load_dict({"type": "scene", "card": _quad(mi, 1.0)})
    blocked, _ = occluded_alpha(
        card_only, ray, alpha_scene(card_only, AlphaTable(table.masks, np.array([0])))
    )
    assert np.array_equal(np.array(blocked), on_card.ravel())


def test_cutoff_above_every_alpha_gives_an_empty_surface(mi):
    scene = _two_quads(mi)
    tex = AlphaTexture(checker_texture(0.2, 0.9), "repeat", "repeat", False)
    table = AlphaTable([AlphaMask(texture=tex, cutoff=0.95)], np.array([0, -1]))
    ray = _down_rays(mi, 64)
    si, _, _ = closest_hit_alpha(scene, ray, alpha_scene(scene, table), flags=mi.RayFlags.UV)
    assert np.allclose(np.array(si.t), 5.0, atol=1e-4)
    card_only = mi.load_dict({"type": "scene", "card": _quad(mi, 1.0)})
    alpha = alpha_scene(card_only, AlphaTable(table.masks, np.array([0])))
    blocked, _ = occluded_alpha(card_only, ray, alpha)
    assert not np.any(np.array(blocked))
    si, _, _ = closest_hit_alpha(card_only, ray, alpha, flags=mi.RayFlags.UV)
    assert not np.any(np.array(si.is_valid()))


def test_without_masks_the_plain_query(mi):
    scene = _two_quads(mi)
    ray = _down_rays(mi, 32)
    assert alpha_scene(scene, AlphaTable([AlphaMask()], np.array([-1, -1]))) is None
    si, layers, _ = closest_hit_alpha(scene, ray, None)
    plain = scene.ray_intersect(ray)
    assert np.array_equal(np.array(si.t), np.array(plain.t))
    assert not np.any(np.array(layers))


def test_stacked_cutouts_and_the_layer_bound(mi):
    shapes = {f"card{k}": _quad(mi, 1.0 + 0.25 * k) for k in range(6)}
    scene = mi.load_dict({"type": "scene", **shapes})
    empty = AlphaMask(factor=0.0)  # alpha 0 everywhere: every card is cut out
    table = AlphaTable([empty], np.zeros(6, np.int32))
    ray = _down_rays(mi, 16)
    si, layers, exhausted = closest_hit_alpha(
        scene, ray, alpha_scene(scene, table), flags=mi.RayFlags.UV
    )
    assert not np.any(np.array(si.is_valid()))
    assert np.all(np.array(layers) == 6) and not np.any(np.array(exhausted))
    # a bound below the layer count stops the rays on the surface they reached: deterministic
    si, layers, exhausted = closest_hit_alpha(
        scene, ray, alpha_scene(scene, table), flags=mi.RayFlags.UV, max_layers=3
    )
    assert np.all(np.array(exhausted)) and np.all(np.array(layers) == 3)
    assert np.allclose(np.array(si.t), 5.0 - 2.25 + 0.75, atol=1e-4)  # the fourth card, y=1.75
    blocked, exhausted = occluded_alpha(scene, ray, alpha_scene(scene, table), max_layers=3)
    assert np.all(np.array(blocked)) and np.all(np.array(exhausted))


def test_vertex_alpha_multiplies(mi):
    # alpha = x across the card (vertex alphas 0, 1, 1, 0): kept where x >= cutoff
    scene = mi.load_dict(
        {"type": "scene", "card": _quad(mi, 1.0, vertex_alpha=[0, 1, 1, 0]), "floor": _quad(mi, 0)}
    )
    table = AlphaTable([AlphaMask(vertex_alpha=True, cutoff=0.25)], np.array([0, -1]))
    si, _, _ = closest_hit_alpha(scene, _down_rays(mi), alpha_scene(scene, table))
    assert np.mean(np.abs(np.array(si.t) - 4.0) < 1e-4) == 0.75
