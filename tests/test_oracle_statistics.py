"""The oracle's statistics: jitter independence, honest standard errors, the adaptive
stopping rule, significance tests an exact candidate passes, noise floors, shadow-ray offsets
far from the origin, spot receivers and the colour exposure (issue 8)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.oracle.reference import render as R
from raster_oracle.oracle.reference import settings as settings_module
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes import backend

from raster_oracle import metrics as M
from raster_oracle import scenes

CHANNELS = ("visibility", "coverage")


def _joint_chi2_z(a: np.ndarray, b: np.ndarray, bins: int = 32) -> float:
    """Standardised chi-square of the joint histogram of two uniform samples."""
    h = np.histogram2d(a, b, bins=bins, range=((0, 1), (0, 1)))[0]
    expected = len(a) / bins**2
    chi2 = float(((h - expected) ** 2 / expected).sum())
    dof = bins * bins - 1
    return (chi2 - dof) / math.sqrt(2 * dof)


@pytest.mark.parametrize(("d_pixel", "d_sample"), [(0, 1), (0, 2), (0, 16), (1, 0), (160, 0)])
def test_jitter_of_neighbouring_samples_is_independent(mi, d_pixel, d_sample):
    """Consecutive PCG32 stream numbers (the old seeding) gave joint chi-square deviations
    of thousands of sigma for samples s and s + 2; TEA-hashed seeds must look independent."""
    n = 1 << 18
    pix = np.arange(n, dtype=np.uint32)
    s = np.zeros(n, dtype=np.uint32) + 3
    u0, v0 = R.sample_jitter(mi.UInt32(pix), mi.UInt32(s), 7)
    u1, v1 = R.sample_jitter(mi.UInt32(pix + d_pixel), mi.UInt32(s + d_sample), 7)
    u0, v0, u1, v1 = (np.array(a) for a in (u0, v0, u1, v1))
    for a, b in ((u0, u1), (v0, v1), (u0, v1), (u0, v0)):
        assert abs(_joint_chi2_z(a, b)) < 6.0


def test_jitter_depends_on_seed(mi):
    pix = mi.UInt32(np.arange(1000, dtype=np.uint32))
    s = mi.UInt32(np.zeros(1000, dtype=np.uint32))
    a = np.array(R.sample_jitter(pix, s, 0)[0])
    b = np.array(R.sample_jitter(pix, s, 1)[0])
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.15
    assert np.all((a >= 0) & (a < 1))


def test_a_pixels_samples_split_over_launches_give_the_same_bytes(monkeypatch):
    """spp above the launch size splits a pixel's samples (bounded memory at any spp)."""
    scene = scenes.load("plate", width=8, height=6)
    settings = ReferenceSettings(spp=256, channels=("visibility", "coverage", "color"))
    whole, _ = render_reference(scene, settings, quiet=True)
    monkeypatch.setattr(settings_module, "SAMPLES_PER_CHUNK", 96)
    split, stats = render_reference(scene, settings, quiet=True)
    assert stats["primary_rays"] == 256 * 48
    for name in whole:
        # float64 block sums of float32 samples (R.block_sum): exact here in any order
        np.testing.assert_array_equal(split[name], whole[name])


def test_block_sums_do_not_depend_on_the_order(mi):
    """The root cause of the split-launch bytes on CUDA: a float32 block sum rounds in an
    order that depends on the block size and the backend (a tree on CUDA); 1 followed by
    2^-24s loses every 2^-24 in a sequential float32 sum and keeps them in a tree. Summed in
    float64, both orders give the exact sum."""
    import drjit as dr

    block = 64
    values = np.full(4 * block, 2.0**-24, np.float32)
    values[::block] = 1.0
    got = np.array(R.block_sum(dr, dr.ReduceOp.Add, mi.Float(values), block))
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, np.full(4, 1.0 + (block - 1) * 2.0**-24))


def test_agreeing_samples_report_the_binomial_floor_not_zero():
    scene = scenes.load("plate", width=32, height=18)
    ch, stats = render_reference(scene, ReferenceSettings(spp=16, channels=CHANNELS), quiet=True)
    floor = float(M.binomial_stderr_floor(16))
    assert floor == pytest.approx(math.sqrt((0.5 / 17) * (1 - 0.5 / 17) / 16))
    for c in CHANNELS:
        assert ch[f"{c}_stderr"].min() == pytest.approx(floor, rel=1e-6)


@pytest.fixture(scope="module")
def thin_truth():
    scene = scenes.load("thin", width=160, height=90)
    truth, _ = render_reference(
        scene, ReferenceSettings(spp=4096, seed=1000, channels=CHANNELS), quiet=True
    )
    return scene, truth


def test_adaptive_sampling_does_not_stop_where_a_thin_feature_was_missed(thin_truth):
    """The first rule stopped every pixel whose 16 first-pass samples agreed: 1.2 % of
    `thin`'s pixels ended more than 0.03 from the truth, reporting stderr 0. Pixels near a
    feature (their own or a neighbour's) now refine; far pixels stop at the first pass."""
    scene, truth = thin_truth
    settings = ReferenceSettings(
        adaptive=True, adaptive_spp=16, target_stderr=0.01, max_spp=1024, channels=CHANNELS
    )
    ch, stats = render_reference(scene, settings, quiet=True)
    npix = scene.width * scene.height
    for c in CHANNELS:
        err = np.abs(ch[c] - truth[c])
        assert (err > 0.03).sum() <= 0.002 * npix
        # the reported stderr is honest: few pixels are off by more than 4 combined sigma
        sigma = np.hypot(ch[f"{c}_stderr"], truth[f"{c}_stderr"])
        assert (err > 4 * sigma).sum() <= 0.001 * npix
        assert ch[f"{c}_stderr"].min() > 0
    assert stats["adaptive"]["max_spp_used"] == 1024
    assert stats["adaptive"]["pixels_near_features"] < npix


@pytest.mark.parametrize("spp", [16, 64])
def test_an_exact_candidate_is_not_significant(thin_truth, spp):
    """A 4096-spp candidate stands in for the exact image: the binomial test must flag no
    pixel (family-wise alpha 0.01), where the normal test with a 1e-4 floor flagged many."""
    scene, truth = thin_truth
    ref, _ = render_reference(scene, ReferenceSettings(spp=spp, channels=CHANNELS), quiet=True)
    for c in CHANNELS:
        new = M.z_test(ref[c], ref[f"{c}_stderr"], truth[c], samples=spp, binary=True)
        assert new["significant_count"] == 0
    raw = np.where(ref["visibility"] * (1 - ref["visibility"]) > 0, ref["visibility_stderr"], 0)
    old = M.z_test(ref["visibility"], raw, truth["visibility"])
    assert old["significant_count"] > 10


def test_binary_test_still_flags_a_flipped_shadow_pixel():
    ref = np.full((4, 4), 1.0, np.float32)
    cand = ref.copy()
    cand[1, 2] = 0.0
    zt = M.z_test(ref, np.zeros_like(ref), cand, samples=64, binary=True)
    assert zt["significant_count"] == 1


def test_noise_floor_surrogate_scores_like_an_exact_candidate(thin_truth):
    """B - A has sqrt(2) the noise of T - A; A + (B - A)/sqrt(2) has the same as T - A."""
    scene, truth = thin_truth
    a, _ = render_reference(scene, ReferenceSettings(spp=16, seed=0, channels=CHANNELS), quiet=True)
    b, _ = render_reference(scene, ReferenceSettings(spp=16, seed=1, channels=CHANNELS), quiet=True)
    exact = np.abs(truth["visibility"] - a["visibility"]).mean()
    second = np.abs(b["visibility"] - a["visibility"]).mean()
    surrogate = np.abs(M.exact_surrogate(a["visibility"], b["visibility"]) - a["visibility"])
    assert second / exact > 1.2
    assert surrogate.mean() / exact == pytest.approx(1.0, abs=0.12)


@pytest.mark.parametrize("offset", [1e4, 1e5])
def test_a_small_kerb_keeps_its_shadow_far_from_the_origin(tmp_path, offset):
    """A 0.08-unit kerb: the old offset 2^-19 (1 + max|p|) = 0.19 units at 1e5 jumped over it
    (0 % shadow against 8.6 % at the origin)."""
    from tests.test_models_xml import quad, write_scene

    shadow = {}
    for o_ in (0.0, offset):
        o = np.array([o_, 0.0, o_])
        path = write_scene(
            tmp_path / f"o{int(o_)}",
            origin=o + (0, 1.0, 1.2),
            target=o,
            sun=(0.0, -0.3, -1.0),
            shapes=[
                quad(o + (-5, 0, 5), (10, 0, 0), (0, 0, -10)),
                quad(o + (-2, 0, 0), (4, 0, 0), (0, 0.08, 0)),
            ],
            width=64,
            height=36,
        )
        ch, _ = render_reference(
            scenes.load(str(path)), ReferenceSettings(spp=4, channels=("visibility",)), quiet=True
        )
        shadow[o_] = float((1 - ch["visibility"]).mean())
    assert shadow[0.0] > 0.05
    assert shadow[offset] == pytest.approx(shadow[0.0], rel=0.05)


def test_spot_receivers_are_inside_the_cone():
    from raster_oracle.oracle.scoring.score import reference_receivers

    scene = scenes.load("spot", width=80, height=45)
    ch, _ = render_reference(
        scene, ReferenceSettings(spp=1, channels=("id", "normal", "position")), quiet=True
    )
    rec = reference_receivers(ch, scene.light)
    p = np.stack([ch[f"position.{c}"] for c in "XYZ"], -1).reshape(-1, 3).astype(np.float64)
    wl, _ = scene.light.to_light(p)
    inside = np.asarray(scene.light.in_cone(wl)).reshape(rec.shape)
    assert rec.sum() > 100
    assert not (rec & ~inside).any()
    valid = ch["id"] >= 0
    assert (valid & ~inside).sum() > 0, "test scene: part of the view must be outside the cone"


def test_exposure_ignores_black_sky_and_shadow():
    """Half the image black used to raise the exposure by log2 of the black fraction's
    weight; lit pixels alone now set it."""
    lit = np.full((8, 8, 3), 0.5, np.float32)
    half = lit.copy()
    half[:, :4] = 0.0
    assert M.exposure_from_reference(half) == pytest.approx(M.exposure_from_reference(lit))
    assert M.exposure_from_reference(lit) == pytest.approx(math.log2(0.18 / (0.5 + 1e-4)))


def _convex_shapes_scene(width, height):
    """A cylinder (open tube) and a sphere in the sky under a sun: closed form, nothing can
    shadow the outer light-facing side of either."""
    from raster_oracle.scenes.catalogue.factories import sensor, sun

    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 4, 8), target=(0, 0.5, 0), fov=45, near=0.1, far=200
        ),
        "sun": sun((0.5, -0.8, -0.3)),
        "tube": {
            "type": "cylinder",
            "p0": [-2.5, 0.6, 1.0],
            "p1": [-0.8, 0.9, -1.5],
            "radius": 0.25,
            "bsdf": {"type": "diffuse"},
        },
        "ball": {
            "type": "sphere",
            "center": [1.5, 1.0, 0.0],
            "radius": 0.8,
            "bsdf": {"type": "diffuse"},
        },
    }


def test_lit_side_of_convex_analytic_shapes_is_never_self_shadowed():
    """The cylinder's own intersection error exceeds the ray offset (30 % of its lit side read
    as shadowed before the self-hit skip); the outward lit side must be lit everywhere."""
    from raster_oracle.scenes.backend.raycast import camera_rays_dr, trace_film_dr
    from raster_oracle.scenes.catalogue.builtin import BuiltinScene

    mi = backend.mitsuba()
    import drjit as dr

    scene = scenes.load(
        BuiltinScene("convex", _convex_shapes_scene, "tube and ball"), width=320, height=180
    )
    ys, xs = np.mgrid[0:180, 0:320]
    x = mi.Float((xs.ravel() + 0.5).astype(np.float32))
    y = mi.Float((ys.ravel() + 0.5).astype(np.float32))
    out = trace_film_dr(scene, x, y, color=False)
    ray = camera_rays_dr(scene.camera, x, y)
    si = scene.mi_scene.ray_intersect(ray)
    wl, _ = scene.light.to_light(si.p)
    # Seen from outside (normal against the view ray) and facing the light.
    outward_lit = np.array(si.is_valid() & (dr.dot(si.n, wl) > 0.0) & (dr.dot(si.n, ray.d) < 0.0))
    tube = np.array(out["shape"]) == 0
    assert (outward_lit & tube).sum() > 500
    assert np.array(out["lit"])[outward_lit].all()
