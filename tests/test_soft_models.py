"""PCSS and moment shadow maps (issue 38): closed forms of the penumbra estimate and of the
Hamburger 4MSM reconstruction, the published constants, and small end-to-end runs."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from raster_oracle.raster_models.light_frame import Projection, make_frame
from raster_oracle.raster_models.shadowmaps import msm_filter, pcss_filter
from raster_oracle.raster_models.shadowmaps.filters import upload_texels
from raster_oracle.raster_models.shadowmaps.pcss import PRESETS, PcssParams, resolved
from raster_oracle.raster_models.shadowmaps.records import MapData

from raster_oracle import raster_models, scenes


# ------------------------------------------------------------------ PCSS: closed forms
def _persp(tan_half=1.0, near=0.5, far=20.0, res=64):
    frame = make_frame((0.0, -1.0, 0.0), [("x", (1.0, 0.0, 0.0))], (0.0, 10.0, 0.0))
    return Projection("persp", frame, (tan_half, near, far), res)


def _hyper(proj, tau):
    _, n, f = proj.extent
    return f / (f - n) - f * n / (f - n) / tau


def test_linear_depth_inverts_the_perspective_depth():
    proj = _persp()
    tau = np.array([0.5, 1.0, 3.0, 19.0])
    assert np.allclose(pcss_filter.linear_depth(proj, _hyper(proj, tau)), tau, rtol=1e-12)


def test_penumbra_estimate_of_a_flat_blocker_is_the_formula():
    # Blocker plane at 4, receiver at 10, light 1 m: w = (10 - 4) * 1 / 4 = 1.5 m at the
    # receiver, i.e. 1.5 / (2 * 10 * tan_half) in map coordinates.
    proj = _persp(tan_half=0.5)
    r = pcss_filter.penumbra_radius_uv(proj, 10.0, 4.0, light_size=1.0, light_angle=0.0)
    assert r == pytest.approx(1.5 / (2.0 * 10.0 * 0.5), rel=1e-12)
    # Contact: no distance, no penumbra; the estimate grows with the distance.
    zb = np.array([10.0, 9.0, 7.0, 4.0])
    radii = pcss_filter.penumbra_radius_uv(proj, 10.0, zb, light_size=1.0, light_angle=0.0)
    assert radii[0] == 0.0 and np.all(np.diff(radii) > 0)


def test_search_region_is_similar_triangles_to_the_near_plane():
    proj = _persp(tan_half=1.0, near=2.0)
    size_uv = 0.8 / (2.0 * 2.0 * 1.0)
    got = pcss_filter.search_radius_uv(proj, 8.0, light_size=0.8, light_angle=0.0)
    assert got == pytest.approx(size_uv * (8.0 - 2.0) / 8.0, rel=1e-12)
    # A nearer-reaching search (the nearest caster) cannot be nearer than the map's plane.
    assert pcss_filter.search_radius_uv(
        proj, 8.0, light_size=0.8, light_angle=0.0, near=1.0
    ) == pytest.approx(got)


def test_orthographic_penumbra_uses_the_angular_diameter():
    frame = make_frame((0.0, -1.0, 0.0), [("x", (1.0, 0.0, 0.0))])
    proj = Projection("ortho", frame, (-5.0, 5.0, -5.0, 5.0, 0.0, 20.0), 64)
    r = pcss_filter.penumbra_radius_uv(proj, 12.0, 10.0, light_size=0.0, light_angle=2.0)
    assert r == pytest.approx(2.0 * 2.0 * math.tan(math.radians(1.0)) / 10.0, rel=1e-12)


def _flat_blocker_map(proj, res, tau_blocker, tau_ground, half_width_uv):
    """A square blocker (plane at tau_blocker) in the middle of the map over a ground plane."""
    c = (np.arange(res) + 0.5) / res
    inside = (np.abs(c[:, None] - 0.5) < half_width_uv) & (np.abs(c[None, :] - 0.5) < half_width_uv)
    depth = np.where(inside, _hyper(proj, tau_blocker), _hyper(proj, tau_ground))
    depth = depth.astype(np.float32)
    return MapData(depth, None, (0.0, 0.0), int(inside.sum()), 0.0, upload_texels(depth))


def test_pcss_blocker_search_finds_the_flat_blocker_depth():
    res = 256
    proj = _persp(tan_half=1.0, near=1.0, far=20.0, res=res)
    data = _flat_blocker_map(proj, res, 4.0, 10.0, 0.25)
    p = resolved(PcssParams(light_size=1.0), None)
    u = np.array([0.5, 0.5, 0.9])
    v = np.array([0.5, 0.74, 0.9])
    z = _hyper(proj, np.full(3, 10.0))
    vis, radius, zb = pcss_filter.pcss_lookup(data, proj, u, v, z, z - 1e-6, p)
    # Receivers under the blocker: the average blocker depth is its plane; the filter radius
    # is the formula's; far from it no blocker is found and the receiver is lit.
    assert zb[0] == pytest.approx(4.0, rel=1e-5) and vis[0] == 0.0
    assert radius[0] == pytest.approx((10 - 4) / 4 * 1.0 / (2 * 10 * 1.0), rel=1e-5)
    assert 0.0 < vis[1] < 1.0  # the edge: partly lit
    assert vis[2] == 1.0 and zb[2] == 0.0 and radius[2] == 0.0
    est = pcss_filter.estimates(proj, z - 1e-6, radius, zb, p)
    # Parallel planes: (10 - 4) x 1 m / 4 = 1.5 m of penumbra, 6 m from blocker to receiver.
    assert est["penumbra_width"][0] == pytest.approx(1.5, rel=1e-4)
    assert est["blocker_distance"][0] == pytest.approx(6.0, rel=1e-4)
    assert est["penumbra_width"][2] == 0.0


def test_fibonacci_disk_is_hdrp_table():
    # HDRP 10.10.1 HDPCSS.hlsl lines 23-25: fibonacciSpiralDirection[0..2]; radius
    # sqrt(i / N + 0.5 / N) (line 91).
    d = pcss_filter.disk("fibonacci", 16)
    radius = np.sqrt((np.arange(16) + 0.5) / 16)
    assert np.allclose(np.hypot(d[:, 0], d[:, 1]), radius, atol=1e-12)
    table = [
        (1.0, 0.0),
        (-0.7373688780783197, 0.6754902942615238),
        (0.08742572471695988, -0.9961710408648278),
    ]
    for i, (x, y) in enumerate(table):
        assert d[i] / radius[i] == pytest.approx([x, y], abs=1e-12)


def test_presets_transcribe_the_engines():
    assert PRESETS["nvidia"][:3] == (16, 16, "poisson16")
    assert PRESETS["hdrp"][:3] == (24, 16, "fibonacci")
    assert pcss_filter.POISSON_16.shape == (16, 2)
    # NVIDIA's "disk" fills the square [-1, 1]^2: taps reach 1.234 times the radius.
    assert np.all(np.abs(pcss_filter.POISSON_16) <= 1.0)
    assert np.hypot(*pcss_filter.POISSON_16.T).max() == pytest.approx(1.2339, abs=1e-4)
    assert pcss_filter.POISSON_16[0] == pytest.approx([-0.94201624, -0.39906216])
    p = resolved(PcssParams(preset="hdrp", filter_samples=8), SimpleNamespace(is_area=False))
    assert (p.blocker_samples, p.filter_samples, p.disk, p.rotation) == (24, 8, "fibonacci", "ign")
    # HDRP's minimum filter size, 1e-4 of the 4096 fit, and its default shape radius 0.025
    assert p.min_filter_uv == pytest.approx(1e-4 * 4096 / p.resolution)
    assert p.light_size == pytest.approx(0.05) and p.softness == "hdrp"
    q = resolved(PcssParams(), SimpleNamespace(is_area=False))
    assert (q.light_size, q.min_filter_uv, q.softness) == (0.5, 0.0, "physical")


def test_interleaved_gradient_noise_is_jimenez_formula():
    val = pcss_filter.interleaved_gradient_noise(10.5, 3.5)
    inner = (0.06711056 * 10.5 + 0.00583715 * 3.5) % 1.0
    assert val == pytest.approx((52.9829189 * inner) % 1.0, abs=1e-12)


# ------------------------------------------------------------------ MSM: closed forms
def test_hamburger_on_one_depth_is_the_exact_step_without_bias():
    b = msm_filter.raw_moments(np.full(6, 0.4))
    z = np.array([0.1, 0.39, 0.4, 0.41, 0.6, 0.99])
    vis = 1.0 - msm_filter.hamburger_4msm(b, z, 0.0)
    assert np.array_equal(vis, [1.0, 1.0, 1.0, 0.0, 0.0, 0.0])


@pytest.mark.parametrize("alpha", [3e-5, 3e-7])
def test_moment_bias_leaks_at_most_alpha_over_distance_squared(alpha):
    d0 = 0.4
    delta = np.array([0.02, 0.05, 0.1, 0.3, 0.55])
    b = msm_filter.raw_moments(np.full(len(delta), d0))
    vis = 1.0 - msm_filter.hamburger_4msm(b, d0 + delta, alpha)
    assert np.all(vis > 0) and np.all(vis <= alpha / delta**2)
    front = 1.0 - msm_filter.hamburger_4msm(b[:3], d0 - delta[:3], alpha)
    assert np.all(front == 1.0)


def test_two_depth_distribution_is_reconstructed_where_vsm_bleeds():
    # 30 % of the filter region at depth 0.3, 70 % at 0.6: a receiver between them is lit
    # 70 %, one behind both is in full shadow. Four moments determine two points exactly.
    w, d1, d2 = 0.3, 0.3, 0.6
    z = np.array([0.45, 0.5, 0.59, 0.7, 0.9])
    b = w * msm_filter.raw_moments(np.full(5, d1)) + (1 - w) * msm_filter.raw_moments(
        np.full(5, d2)
    )
    truth = np.array([0.7, 0.7, 0.7, 0.0, 0.0])
    exact = 1.0 - msm_filter.hamburger_4msm(b, z, 0.0)
    assert np.allclose(exact, truth, atol=1e-9)
    biased = 1.0 - msm_filter.hamburger_4msm(b, z, 3e-5)
    assert np.all(np.abs(biased - truth) < 0.01)
    # VSM's Chebyshev bound on the same moments leaks far more behind both casters.
    mu, var = b[:, 0], b[:, 1] - b[:, 0] ** 2
    vsm = np.where(z <= mu, 1.0, var / (var + (z - mu) ** 2))
    assert np.all(vsm[3:] > 10 * biased[3:])


def test_optimized_quantization_round_trip_and_range():
    d = np.linspace(0.0, 1.0, 257)
    q = msm_filter.encode16(msm_filter.raw_moments(d))
    assert q.min() >= -1e-9 and q.max() <= 1.0 + 1e-9
    assert np.allclose(msm_filter.decode16(q), msm_filter.raw_moments(d), atol=1e-8)
    # ENCODE and DECODE are inverse matrices to the published digits.
    assert np.allclose(msm_filter.ENCODE_16 @ msm_filter.DECODE_16, np.eye(4), atol=1e-6)


def test_msm_texture_quantizes_to_16_bits():
    depth = np.linspace(0.1, 0.9, 64, dtype=np.float32).reshape(8, 8)
    tex = msm_filter.msm_texture(depth, 3, "unorm16")
    k = tex.astype(np.float64) * 65535.0
    assert np.allclose(k, np.round(k), atol=1e-3)
    raw = msm_filter.msm_texture(depth, 1, "float32")
    assert raw[..., 1] == pytest.approx(depth.astype(np.float64) ** 2, rel=1e-6)


# ------------------------------------------------------------------ end to end (small)
@pytest.fixture(scope="module")
def contact():
    return scenes.load("soft-contact", width=48, height=27)


def test_pcss_on_the_area_light_softens_and_keeps_hard_umbrae(contact):
    hard = raster_models.run("shadow-map", contact, resolution=256)
    soft = raster_models.run("pcss", contact, resolution=256)
    vh, vs = hard.outputs["visibility"], soft.outputs["visibility"]
    soft_h = np.mean((vh > 0.02) & (vh < 0.98))
    soft_s = np.mean((vs > 0.02) & (vs < 0.98))
    assert soft_s > 2 * soft_h
    assert soft.diagnostics["pcss"]["light_size"] == pytest.approx(1.0)
    assert soft.diagnostics["area_map"]["tan_half"] > 0
    assert soft.cost["texture_lookups_per_pixel"] == pytest.approx(32.0)
    width = soft.outputs["penumbra_width"]
    assert width.shape == vs.shape and width.max() > 0 and np.all(width >= 0)


def test_msm_runs_and_counts_its_moment_memory(contact):
    res = raster_models.run("msm", contact, resolution=128, blur_size=3)
    # one map along the area light's normal: D32F depth, 4 x 16-bit moments, a blur scratch
    assert res.cost["shadow_map_bytes"] == 128 * 128 * (4 + 8 + 8)
    assert res.diagnostics["area_map"]["tan_half"] > 0
    v = res.outputs["visibility"]
    assert np.all((v >= 0) & (v <= 1))


def test_linear_moment_depth_inverts_the_hyperbolic_depth():
    proj = _persp(tan_half=1.0, near=0.5, far=20.0)
    tau = np.array([0.5, 5.0, 12.75, 20.0])
    got = msm_filter.moment_depth(proj, _hyper(proj, tau), "linear")
    assert got == pytest.approx((tau - 0.5) / 19.5, abs=1e-9)
    assert np.array_equal(msm_filter.moment_depth(proj, [0.3], "stored"), [0.3])


def test_msm_on_a_spot_light_needs_linear_depth_at_16_bits():
    # Hyperbolic depths crowd into the top of [0, 1], under 16-bit quantization: most
    # receivers are falsely shadowed; the linear depth restores the hard map's shadows.
    loaded = scenes.load("spot", width=48, height=27)
    hard = raster_models.run("shadow-map", loaded, resolution=256).outputs["visibility"]
    stored = raster_models.run("msm", loaded, resolution=256).outputs["visibility"]
    linear = raster_models.run("msm", loaded, resolution=256, moment_depth="linear")
    assert abs(linear.outputs["visibility"].mean() - hard.mean()) < 0.02
    assert stored.mean() < hard.mean() - 0.1


def test_msm_moment_bias_follows_the_format(contact):
    from raster_oracle.raster_models.shadowmaps.msm import FORMAT_BIAS

    assert FORMAT_BIAS == {"unorm16": 6e-5, "float32": 3e-6}
    res = raster_models.run("msm", contact, resolution=64, msm_format="float32")
    assert res.diagnostics["moment_bias"] == 3e-6 and res.params["moment_bias"] == -1.0
    res = raster_models.run("msm", contact, resolution=64, moment_bias=1e-4)
    assert res.diagnostics["moment_bias"] == 1e-4


# ------------------------------------------------------------------ scoring (soft truth)
def test_soft_scores_closed_form():
    from raster_oracle.oracle.studies.soft_shadows import soft_scores

    ref = np.array([[0.0, 0.5, 1.0, 0.25]])
    ref2 = np.array([[0.0, 0.6, 1.0, 0.25]])
    rec = np.array([[True, True, True, False]])
    chans = {"light_fraction": ref, "light_fraction_stderr": np.full_like(ref, 0.1)}
    got = soft_scores(chans, [[0.1, 0.5, 1.0, 0.0]], rec, ref2_ch={"light_fraction": ref2})
    lf = got["light_fraction"]
    assert lf["mae"] == pytest.approx(0.1 / 3) and lf["penumbra_mae"] == 0.0
    assert lf["noise_floor"] == pytest.approx(0.1 / math.sqrt(2) / 3)
    assert lf["penumbra_pixels"] == 1 and lf["pixels"] == 3
    assert "soft_visibility" not in got
    # without a second reference the floor is the mean standard error
    assert soft_scores(chans, ref, rec)["light_fraction"]["noise_floor"] == pytest.approx(0.1)


def test_pcss_is_scored_against_the_area_light_truth(tmp_path):
    from raster_oracle.oracle.reference.cache import ReferenceCache
    from raster_oracle.oracle.scoring.options import ScoreOptions
    from raster_oracle.oracle.scoring.request import ScoreRequest
    from raster_oracle.oracle.scoring.technique import score_model

    loaded = scenes.load("soft-contact", width=32, height=18)
    cache = ReferenceCache(tmp_path)
    kw = dict(options=ScoreOptions(spp=4, seed=0), cache=cache)
    res = score_model(ScoreRequest.for_model(loaded, "pcss", {"resolution": 256}, **kw))
    rec = res.record
    assert rec["channel"] == "soft_visibility"
    assert 0.0 <= rec["visibility_mae"] < 0.1 and rec["noise_floor"]["visibility_mae"] >= 0
    asked = ScoreRequest.for_model(
        loaded, "pcss", {"resolution": 256}, channel="light_fraction", **kw
    )
    lf = score_model(asked)
    assert lf.record["channel"] == "light_fraction"
    assert lf.record["visibility_mae"] == pytest.approx(rec["visibility_mae"], abs=0.02)


def test_contact_hardening_and_its_claim():
    from raster_oracle.oracle.studies.claims.run import NOT, PARTLY, REPRODUCED, run_claims

    data = run_claims(None, only=["pcss-penumbra-error-grows"], size=(64, 36))
    (row,) = data["claims"]
    assert row["verdict"] in (REPRODUCED, PARTLY, NOT), row.get("note")
    assert {c["preset"] for c in row["cases"]} == {"nvidia", "hdrp"}
    for c in row["cases"]:
        assert c["lo"] < c["hi"] and c["pixels"] >= 10
        assert c["true_width"] > 0 and c["abs_error"] >= 0 and 0 <= c["missed"] <= 1
    # under the flat plate (2-4 m from the ground) NVIDIA's parallel-plane estimate is the
    # geometry's; HDRP's is its fitted softness (tests/test_pcss_hdrp.py checks its formula)
    far = [c for c in row["cases"] if c["lo"] == 2.0]
    assert {c["preset"] for c in far} == {"nvidia", "hdrp"}
    assert all(c["rel_error"] < 0.1 for c in far if c["preset"] == "nvidia")


def test_soft_shadows_section_renders_its_three_tables():
    from raster_oracle.reports.sections import render_section, soft_shadows_section

    score = {"mae": 0.01, "penumbra_mae": 0.1, "noise_floor": 0.001, "penumbra_noise_floor": 0.01}
    row = {"lookups": 32.0, "light_fraction": score, "soft_visibility": score}
    bleed = {"mean": 0.02, "leak_fraction": 0.05, "misclassified": 0.001}
    data = {
        "resolution": [32, 18],
        "reference_spp": 4,
        "map_resolution": 2048,
        "ranking": {
            "scene": "soft-contact",
            "ranked_by": "light_fraction mae",
            "rows": [{"label": "pcss <a>", **row}, {"label": "pcf 5x5", "separated": True, **row}],
        },
        "contact_hardening": {
            "presets": {
                "nvidia": {
                    "bins": [
                        {"lo": 0.0, "hi": 0.1, "pixels": 0},
                        {
                            "lo": 2.0,
                            "hi": 4.0,
                            "pixels": 12,
                            "true_width": 0.6,
                            "abs_error": 0.02,
                            "abs_error_stderr": 0.004,
                            "rel_error": 0.03,
                            "missed": 0.0,
                        },
                    ]
                }
            }
        },
        "bleeding": {
            "visibility_mae_floor": {"plate": 0.001},
            "rows": [
                {"scene": "plate", "blur": b, "filter": f, **bleed}
                for b in (1, 5)
                for f in ("VSM", "MSM 16-bit")
            ],
        },
    }
    section = soft_shadows_section(data)
    assert section["filters"] == ["VSM", "MSM 16-bit"] and len(section["bleeding"]) == 2
    html = render_section(section)
    assert "pcss &lt;a&gt;" in html and "pcss <a>" not in html  # user text is escaped
    assert "Contact hardening" in html and "Light bleeding of moment shadow maps" in html
    assert html.count("<tr>") >= 2 + 1 + 1 + 2
    assert "Filter extent" not in html  # records before issue 45 have no extent
    per = {"radius": {"min": 0.47, "max": 1.24}, "transition": {"factor": 0.68}}
    data["extent"] = {"fovs": [30.0, 90.0], "presets": {"hdrp": {"30": per, "90": per}}}
    html = render_section(soft_shadows_section(data))
    assert "Filter extent" in html and html.count("0.47") == 2 and html.count("0.68") == 2
