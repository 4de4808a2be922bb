"""The anti-aliasing scenes (scenes.catalogue.aa_scenes): each loads, renders, and has its property.

The properties are measured, not assumed: the decal ties exactly and the reference sees one
colour (the closed-form Lambert value) across it; the stripes alternate at their pixel
frequency and the reference equals the closed-form half-and-half mix while one aggregate's
filtered inputs lose the albedo/normal correlation; the glossy beads carry sub-pixel
highlights that pixel-centre shading aliases inside surfaces; foliage has 3+ surfaces in many
pixels at the 8x standard positions; hdr-edge spans 180:1 across its edges.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.backend import raycast
from raster_oracle.scenes.catalogue import aa_scenes
from raster_oracle.scenes.catalogue.builtin import BUILTIN_SCENES, DEFAULT_SCENES
from raster_oracle.scenes.shading.phong import Specular

from raster_oracle import scenes

AA_NAMES = ("decal", "stripes", "glossy", "foliage", "hdr-edge")

#: The 8x standard sample positions (Vulkan table, y down; TECHNIQUES.md), restated here so
#: the scenes' properties do not depend on the models' own table.
STANDARD_8X = np.array(
    [
        (0.5625, 0.3125),
        (0.4375, 0.6875),
        (0.8125, 0.5625),
        (0.3125, 0.1875),
        (0.1875, 0.8125),
        (0.0625, 0.4375),
        (0.6875, 0.9375),
        (0.9375, 0.0625),
    ]
)
#: Sun irradiance of the scenes that use scenes.catalogue.builtin._sun's default.
SUN_E = 3.0
#: float32 radiance against float64 closed forms (a few ulps of values below 1).
TOL = 1e-5
#: Standard error of samples that all agree, relative to the value: the reference computes
#: the variance as a float32 mean of squares minus a squared mean, whose cancellation leaves
#: about sqrt(eps32) ~ 3e-4 of the value (measured 8e-5), not 0.
AGREE_REL = 1e-3


def _reference(s, spp, channels):
    ch, _ = render_reference(s, ReferenceSettings(spp=spp, channels=channels), quiet=True)
    return ch


def _rgb(ch, stem="color"):
    return np.stack([ch[f"{stem}.{c}"] for c in "RGB"], -1).astype(np.float64)


def _trace_samples(s, positions, *, color=False):
    """G-buffer at ``positions`` ((S, 2), in [0, 1)^2, y down) of every pixel: (H, W, S, ...)."""
    yy, xx = np.mgrid[0 : s.height, 0 : s.width]
    x = (xx[..., None] + positions[:, 0]).ravel()
    y = (yy[..., None] + positions[:, 1]).ravel()
    g = raycast.trace_film(s, x, y, color=color)
    shape = (s.height, s.width, len(positions))
    return {k: v.reshape(shape + v.shape[1:]) for k, v in g.items()}


def _lambert(albedo, to_light_unnormalized, normal=(0.0, 0.0, -1.0), e=SUN_E):
    l = np.asarray(to_light_unnormalized, float)
    cos = max(0.0, float(np.dot(normal, l / np.linalg.norm(l))))
    return np.asarray(albedo, float) / math.pi * e * cos


@pytest.mark.parametrize("name", AA_NAMES)
def test_aa_scene_is_builtin_and_renders(name):
    assert name in BUILTIN_SCENES and name not in DEFAULT_SCENES
    s = scenes.load(name, width=48, height=27)
    assert (s.width, s.height) == (48, 27)
    ch = _reference(s, 4, ("color", "coverage"))
    rgb = _rgb(ch)
    assert np.isfinite(rgb).all() and (rgb >= 0).all() and rgb.max() > 0
    assert ch["coverage"].mean() > 0.5


def test_only_glossy_switches_on_the_specular_lobe():
    for name in AA_NAMES:
        s = scenes.load(name, width=48, height=27)
        want = (
            Specular(aa_scenes.GLOSSY_KS, aa_scenes.GLOSSY_SHININESS)
            if name == "glossy"
            else Specular()
        )
        assert s.specular == want, name
    # the lobe is part of the scene's content: a change of it is a different cache entry
    assert scenes.load("glossy").content_hash != scenes.load("decal").content_hash


# ----------------------------------------------------------------------------- decal
def _inside_convex(poly, pts):
    """True where every point of ``pts`` (..., 2) is inside the convex polygon (either winding)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (pts[..., None, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (
        pts[..., None, 0] - a[:, 0]
    )
    return (cross > 0).all(-1) | (cross < 0).all(-1)


def _pixels_inside(s, verts):
    """Pixels whose four corners all lie inside the projection of the planar quad ``verts``."""
    poly = s.camera.project(verts)
    yy, xx = np.mgrid[0 : s.height, 0 : s.width]
    inside = np.ones((s.height, s.width), bool)
    for dx in (0, 1):
        for dy in (0, 1):
            inside &= _inside_convex(poly, np.stack([xx + dx, yy + dy], -1).astype(float))
    return inside


def test_decal_ties_exactly_and_the_reference_sees_one_colour():
    s = scenes.load("decal", width=80, height=45)
    wall, _ = s.mesh_data["wall"]
    decal, _ = s.mesh_data["decal"]
    # exactly coplanar as stored (float32): z = 0 for every vertex of the wall and the decal
    assert (wall[:, 2] == 0).all() and (decal[:, 2] == 0).all()
    # the duplicated panel: identical vertices and faces, bit for bit
    (pv, pf), (cv, cf) = s.mesh_data["panel"], s.mesh_data["panel_copy"]
    assert pv.tobytes() == cv.tobytes() and pf.tobytes() == cf.tobytes()

    ch = _reference(s, 16, ("color", "visibility", "id"))
    rgb, err = _rgb(ch), _rgb(ch, "color_stderr")
    lit = ch["visibility"] == 1.0
    on_decal = _pixels_inside(s, decal) & lit
    on_panel = _pixels_inside(s, pv) & lit
    assert on_decal.sum() >= 50 and on_panel.sum() >= 50
    to_light = (0.25, 0.3, -1.0)  # minus the sun's direction
    wall_rgb = _lambert([aa_scenes.DECAL_ALBEDO] * 3, to_light)
    panel_rgb = _lambert((0.8, 0.5, 0.2), to_light)
    # every sample of every pixel inside the decal sees the one colour: the wall's
    assert np.abs(rgb[on_decal] - wall_rgb).max() < TOL
    assert (err[on_decal] < AGREE_REL * wall_rgb).all()
    assert np.abs(rgb[on_panel] - panel_rgb).max() < TOL
    assert (err[on_panel] < AGREE_REL * panel_rgb).all()
    # and so does the wall around it (lit pixels centred on the wall or the decal whose
    # samples agree: the wall's colour, whichever of the two coplanar shapes a ray reports)
    on_wall = np.isin(ch["id"], [s.shape_names.index(n) for n in ("wall", "decal")])
    flat = lit & on_wall & (err < AGREE_REL * wall_rgb).all(-1)
    assert flat.sum() > 0.5 * s.width * s.height
    assert np.abs(rgb[flat] - wall_rgb).max() < TOL


# ----------------------------------------------------------------------------- stripes
#: Fine sampling step along a row, in pixels (a power of two: exact film positions).
STEP = 1 / 64


@pytest.mark.parametrize("width", [160, 96])
def test_stripes_alternate_at_the_intended_pixel_frequency(width):
    s = scenes.load("stripes", width=width, height=width * 9 // 16)
    assert s.camera.kind == "orthographic"
    names = s.shape_names
    x = np.arange(0, 24, STEP) + width / 2 - 12
    for row in (0.3 * s.height, 0.5 * s.height, 0.8 * s.height):
        g = raycast.trace_film(s, x, np.full_like(x, row))
        assert g["valid"].all()
        kind = np.array([names[i] for i in g["shape"]])
        change = np.nonzero(kind[1:] != kind[:-1])[0]
        # red and blue alternate: every run is one half period long, to the sampling step
        runs = np.diff(x[change])
        half = aa_scenes.STRIPE_PERIOD_PX / 2
        assert np.abs(runs - half).max() <= STEP + 1e-9
        assert len(change) >= 2 * 24 / aa_scenes.STRIPE_PERIOD_PX - 2
        assert set(kind) == {"stripes_red", "stripes_blue"}


# n.l of the red strips (normal (+0.71, 0, -0.71)) and blue strips (-0.71, 0, -0.71) for the
# stripes scene's to-light direction (0.6, 0.3, -0.75)
_STRIPE_L = np.array([0.6, 0.3, -0.75]) / np.linalg.norm([0.6, 0.3, -0.75])
_N_RED = np.array([1.0, 0.0, -1.0]) / math.sqrt(2)
_N_BLUE = np.array([-1.0, 0.0, -1.0]) / math.sqrt(2)
_RED, _BLUE = np.array([0.8, 0.15, 0.1]), np.array([0.1, 0.2, 0.8])
#: Reference noise allowance for an image mean: stratified samples of a two-valued signal.
STRIPES_MEAN_TOL = 0.01


def test_stripes_reference_is_the_half_mix_and_one_aggregate_loses_it():
    s = scenes.load("stripes", width=48, height=27)
    # closed form: exactly half of every pixel is red and half blue, both unshadowed
    c_red, c_blue = _N_RED @ _STRIPE_L, _N_BLUE @ _STRIPE_L
    assert c_red > 0.9 and 0 < c_blue < 0.15
    mix = 0.5 * (_RED * c_red + _BLUE * c_blue) * SUN_E / math.pi
    rgb = _rgb(_reference(s, 16, ("color",)))
    assert np.abs(rgb.mean((0, 1)) - mix).max() < STRIPES_MEAN_TOL * mix.max()

    # what 8 samples give: the per-sample Lambert mean (MSAA-like) vs one aggregate that
    # averages albedo and normal first (AGAA K=1, unnormalized normal)
    g = _trace_samples(s, STANDARD_8X)
    cos = np.maximum(g["normal"] @ _STRIPE_L, 0.0)
    per_sample = (g["albedo"] * cos[..., None]).mean(2)
    aggregate = g["albedo"].mean(2) * np.maximum(g["normal"].mean(2) @ _STRIPE_L, 0.0)[..., None]
    # every pixel holds both strips at 8 samples
    red = np.char.equal(np.array(s.shape_names)[g["shape"]], "stripes_red")
    assert (red.any(-1) & (~red).any(-1)).all()
    # the correlation is lost: red comes out >= 30 % too dark, blue >= 2x too bright
    ratio = aggregate.mean((0, 1)) / per_sample.mean((0, 1))
    assert ratio[0] < 0.7 and ratio[2] > 2.0


# ----------------------------------------------------------------------------- glossy
#: Relative error of pixel-centre shading that counts as aliased (the highlight is hit or
#: missed by the one sample).
ALIASED = 0.5


def test_glossy_beads_alias_inside_surfaces_through_their_highlights():
    s = scenes.load("glossy")
    ch = _reference(s, 16, ("color", "edge", "id"))
    ref = _rgb(ch)
    names = np.array(s.shape_names + ["sky"])
    bead = np.char.startswith(names[ch["id"].astype(int)], "bead_")
    interior = bead & (ch["edge"] == 0)  # every sample on one bead, all lit
    assert interior.sum() > 300
    # highlights: far above the diffuse maximum (albedo <= 0.6 facing the sun: 0.57)
    diffuse_max = 0.6 / math.pi * SUN_E
    assert ref.max() > 10 * diffuse_max

    def centre_error(loaded):
        yy, xx = np.mgrid[0 : s.height, 0 : s.width]
        g = raycast.trace_film(loaded, xx.ravel() + 0.5, yy.ravel() + 0.5, color=True)
        c = g["color"].reshape(ref.shape).mean(-1)
        r = _rgb(_reference(loaded, 16, ("color",))).mean(-1)
        return np.abs(c - r)[interior] / np.maximum(r[interior], 1e-3)

    aliased = centre_error(s) > ALIASED
    n_beads = int(np.char.startswith(np.array(s.shape_names), "bead_").sum())
    assert n_beads == 35
    # at least half the beads have an interior pixel whose centre sample hits or misses the
    # highlight; the same scene without the lobe has none (diffuse shading is smooth)
    assert aliased.sum() >= n_beads // 2
    diffuse = dataclasses.replace(s, specular=Specular())
    assert (centre_error(diffuse) > ALIASED).sum() == 0


# ----------------------------------------------------------------------------- foliage
def test_foliage_has_more_than_two_surfaces_in_many_pixels():
    s = scenes.load("foliage")
    g = _trace_samples(s, STANDARD_8X)
    ids = np.sort(g["shape"], -1)
    distinct = 1 + (np.diff(ids, axis=-1) != 0).sum(-1)
    # more than AGAA's K = 2 aggregates can hold by surface: >= 3 shapes in a fifth of all
    # pixels (sky and ground included), >= 4 in a tenth
    assert (distinct >= 3).mean() > 0.2
    assert (distinct >= 4).mean() > 0.1
    layers = [n for n in s.shape_names if n.startswith("blades_")]
    assert len(layers) == 4


# ----------------------------------------------------------------------------- hdr-edge
def test_hdr_edge_dynamic_range_exceeds_100_to_1():
    s = scenes.load("hdr-edge")
    ch = _reference(s, 16, ("color", "edge", "id", "visibility"))
    lum = _rgb(ch).mean(-1)
    names = np.array(s.shape_names + ["sky"])
    kind = names[ch["id"].astype(int)]
    flat = (ch["edge"] == 0) & (ch["visibility"] == 1.0)
    strip = flat & np.char.startswith(kind, "strip_")
    back = flat & (kind == "backdrop")
    assert strip.sum() > 100 and back.sum() > 1000
    # closed form: the same sun (irradiance 10) at the same angle on both planes
    to_light = (-0.1, 0.15, -1.0)
    l_strip = _lambert(aa_scenes.HDR_STRIP_ALBEDO, to_light, e=10.0)
    l_back = _lambert(aa_scenes.HDR_BACKDROP_ALBEDO, to_light, e=10.0)
    assert np.median(lum[strip]) == pytest.approx(l_strip, rel=TOL)
    assert np.median(lum[back]) == pytest.approx(l_back, rel=TOL)
    assert l_strip / l_back == pytest.approx(aa_scenes.HDR_CONTRAST)
    assert aa_scenes.HDR_CONTRAST > 100
    # strips 0.5 px wide and up: edge pixels hold mixes between the two levels, many of them
    # above 10x the backdrop (the bright side dominates any box resolve)
    edge = ch["edge"] == 1
    assert edge.sum() > 100 and (lum[edge] > 10 * l_back).sum() > 50


def test_export_writes_the_specular_lobe(tmp_path):
    import json

    from raster_oracle.scenes.formats.export import export

    s = scenes.load("decal", width=48, height=27)
    export(s, tmp_path / "plain")
    mats = json.loads((tmp_path / "plain" / "materials.json").read_text())
    assert mats["specular"]["ks"] == 0.0
    glossy_like = dataclasses.replace(s, specular=Specular(GLOSSY_KS_FOR_EXPORT, 64.0))
    export(glossy_like, tmp_path / "lobe")
    mats = json.loads((tmp_path / "lobe" / "materials.json").read_text())
    assert mats["specular"] == {
        "ks": GLOSSY_KS_FOR_EXPORT,
        "shininess": 64.0,
        "model": "normalized Blinn-Phong",
    }


#: A lobe weight for the export test (the glossy scene's 35 spheres tessellate to millions of
#: triangles, too many to export in a test).
GLOSSY_KS_FOR_EXPORT = 0.3
