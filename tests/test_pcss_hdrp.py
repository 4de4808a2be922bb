"""HDRP 10.10.1's PCSS softness mapping (issue 45): the ``hdrp`` preset's filter extent against
an independent transcription of the source's formula, at 30, 60 and 90 degree maps.

The formula is written here from the published package (needle-mirror/com.unity.render-
pipelines.high-definition, tag 10.10.1 = 6328cc84c83b4143a5939859d76f9ccdc7a5b08f), with
HDRP's own quantities: the reversed-Z device depth ``d = n (f - t) / (t (f - n))``,
``zBufferParam`` and ``LinearEyeDepth``, the atlas of the 4096 fit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.raster_models.light_frame import Projection, make_frame
from raster_oracle.raster_models.shadowmaps import pcss_filter, pcss_hdrp
from raster_oracle.raster_models.shadowmaps.filters import upload_texels
from raster_oracle.raster_models.shadowmaps.pcss import PcssParams, resolved
from raster_oracle.raster_models.shadowmaps.records import MapData

NEAR, FAR, RES = 0.5, 20.0, 512


def _hdrp_filter_uv(shape_radius, res, t_receiver_dev, t_blocker_dev, n, f, atlas=8192):
    """SampleShadow_PCSS's filterSize for a perspective map, as an offset in the map's own
    [0, 1] coordinates, from device depths (reversed Z) of the receiver and the blocker."""
    # HDAdditionalLightData.cs:2272, :2347-2354, :2376
    zbuf = ((f - n) / n, 1.0, (f - n) / (n * f), 1.0 / f)
    x = shape_radius
    soft = 0.02403461 + 3.452916 * x - 1.362672 * x**2 + 0.6700115 * x**3 + 0.2159474 * x**4
    soft = soft / 100.0 * (res / 512)
    min_filter = 0.1 * 0.001
    # HDShadowSampling.hlsl:303-334; the map is a res x res viewport of an atlas x atlas atlas
    atlas_res_factor = 4096 * (1.0 / atlas)
    max_soft = 0.04 * (res / 512)
    dist = 1.0 / (zbuf[2] * t_blocker_dev + zbuf[3])
    dist = min(dist, 7.5)
    d2 = dist * dist
    scale = (
        3.298300241
        - 2.001364639 * dist
        + 0.4967311427 * d2
        - 0.05464058455 * dist * d2
        + 0.0021974 * d2 * d2
    )
    soft = min(soft * scale, max_soft)
    size = soft * abs((t_receiver_dev - t_blocker_dev) / t_blocker_dev)  # HDPCSS.hlsl:96-99
    size = max(size, min_filter) * atlas_res_factor  # atlas coordinates
    return size * atlas / res  # the map's own coordinates


def _device(t, n, f):
    return n * (f - t) / (t * (f - n))


def _proj(fov_deg):
    frame = make_frame((0.0, -1.0, 0.0), [("x", (1.0, 0.0, 0.0))], (0.0, 10.0, 0.0))
    return Projection("persp", frame, (math.tan(math.radians(fov_deg) / 2), NEAR, FAR), RES)


def _flat_blocker(proj, t_blocker, t_ground):
    """A blocker plane covering the middle half of the map over a ground plane (stored
    depth: D3D's standard 0-at-near depth, float32)."""
    c = (np.arange(RES) + 0.5) / RES
    inside = (np.abs(c[:, None] - 0.5) < 0.25) & (np.abs(c[None, :] - 0.5) < 0.25)
    _, n, f = proj.extent

    def stored(t):
        return f / (f - n) - f * n / (f - n) / t

    depth = np.where(inside, stored(t_blocker), stored(t_ground)).astype(np.float32)
    return MapData(depth, None, (0.0, 0.0), int(inside.sum()), 0.0, upload_texels(depth))


CASES = [(0.025, 1.0), (0.25, 3.0), (0.5, 3.0), (0.5, 6.0), (1.0, 9.0)]


@pytest.mark.parametrize("fov", [30.0, 60.0, 90.0])
def test_hdrp_filter_extent_is_the_sources_formula(fov):
    proj = _proj(fov)
    t_ground = 12.0
    factors = []
    for shape, t_blocker in CASES:
        data = _flat_blocker(proj, t_blocker, t_ground)
        p = resolved(
            PcssParams(preset="hdrp", light_size=2 * shape, resolution=RES, rotation="none"),
            None,
        )
        u = v = np.array([0.5])
        z = np.array([float(data.depth[0, 0])])  # the ground under the blocker's middle
        ref = z - 1e-7
        vis, radius, zb = pcss_filter.pcss_lookup(data, proj, u, v, z, ref, p)
        assert zb[0] == pytest.approx(t_blocker, rel=1e-4)  # LinearEyeDepth of the blocker
        blocker_dev = 1.0 - float(data.depth[RES // 2, RES // 2])
        want = _hdrp_filter_uv(shape, RES, 1.0 - float(ref[0]), blocker_dev, NEAR, FAR)
        assert radius[0] == pytest.approx(want, rel=0.01)
        # against the geometric penumbra radius of a disk light of that radius, in map units
        geo = shape * (t_ground - t_blocker) / t_blocker / (2 * t_ground * proj.extent[0])
        factors.append(radius[0] / geo)
    # HDRP's extent is fixed in map coordinates: against geometry it scales with tan(fov/2)
    for (shape, t_blocker), k in zip(CASES, factors, strict=True):
        at_90 = k / proj.extent[0]
        dev_b, dev_r = _device(t_blocker, NEAR, FAR), _device(t_ground, NEAR, FAR)
        want = _hdrp_filter_uv(shape, RES, dev_r, dev_b, NEAR, FAR)
        geo_90 = shape * (t_ground - t_blocker) / t_blocker / (2 * t_ground)
        assert at_90 == pytest.approx(want / geo_90, rel=0.01)


def test_search_radius_and_minimum_are_resolution_free_in_the_fits_atlas():
    # the blocker search covers min(softness + 1e-6, 0.04 R / 512) of the 4096 atlas
    for res in (512, 2048):
        s = pcss_hdrp.softness(0.5, res)
        assert pcss_hdrp.search_radius_uv(0.5, res) == pytest.approx(
            min(s + 1e-6, 0.04 * res / 512) * 4096 / res, rel=1e-12
        )
        assert pcss_hdrp.min_filter_uv(res) == pytest.approx(1e-4 * 4096 / res, rel=1e-12)
    # a large shape radius hits the cap: 0.04 x 8 = 0.32 of the map
    assert pcss_hdrp.search_radius_uv(5.0, 1024) == pytest.approx(0.32, rel=1e-12)
    # the distance fit stops at 7.5 m
    assert pcss_hdrp.distance_scale(9.0) == pcss_hdrp.distance_scale(7.5)


def test_device_ratio_is_the_reversed_z_quotient():
    # far plane far away: (t_r - t_b) / t_r; at the far plane the device depth vanishes
    assert pcss_hdrp.device_ratio(5.0, 3.0, 1e12) == pytest.approx(0.4, rel=1e-9)
    assert pcss_hdrp.device_ratio(5.0, 3.0, 5.0) == pytest.approx(1.0, rel=1e-12)
    n, f = 0.1, 10.0
    want = abs((_device(5.0, n, f) - _device(3.0, n, f)) / _device(3.0, n, f))
    assert pcss_hdrp.device_ratio(5.0, 3.0, f) == pytest.approx(want, rel=1e-12)


def test_extent_factors_of_the_presets():
    from raster_oracle.oracle.studies import pcss_extent

    # NVIDIA's radius is the parallel-plane width: twice the geometric radius at any fov
    for fov in (30.0, 90.0):
        nv = pcss_extent.radius_factors("nvidia", fov, res=128)
        assert nv["min"] == pytest.approx(2.0, rel=1e-3)
        assert nv["max"] == pytest.approx(2.0, rel=1e-3)
    # HDRP's is fixed in map coordinates: its factor scales with tan(fov / 2)
    h30 = pcss_extent.radius_factors("hdrp", 30.0, res=128)
    h90 = pcss_extent.radius_factors("hdrp", 90.0, res=128)
    for a, b in zip(h30["grid"], h90["grid"], strict=True):
        assert a["factor"] / b["factor"] == pytest.approx(math.tan(math.radians(15.0)), rel=1e-3)
    # the disk light's 10-90 % transition: the circular segment's 10 % point
    s = pcss_extent.disk_light_transition()
    assert (math.acos(s) - s * math.sqrt(1 - s * s)) / math.pi == pytest.approx(0.1, abs=1e-9)


def test_directional_lights_say_they_keep_the_angular_model():
    from raster_oracle import raster_models, scenes

    sun = scenes.load("stacked-casters", width=16, height=9)
    res = raster_models.run("pcss", sun, resolution=64, preset="hdrp")
    assert res.diagnostics["pcss"]["softness_applied"] == "physical (directional light)"
    spot = scenes.load("spot", width=16, height=9)
    res = raster_models.run("pcss", spot, resolution=64, preset="hdrp")
    assert "softness_applied" not in res.diagnostics["pcss"]
    assert res.diagnostics["pcss"]["light_size"] == pytest.approx(0.05)  # shape radius 0.025
