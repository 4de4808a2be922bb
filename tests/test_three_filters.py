"""three.js r187's PCFShadowMap and VSMShadowMap (raster_models/shadowmaps/three_filters.py)
against a transcription written here from the GLSL, statement by statement, and closed-form
values (constant maps, the bleed remap)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.raster_models.shadowmaps import filters, three_filters

RNG = np.random.default_rng(187)
#: float16 storage of (mean, std): relative rounding of one half-float step.
HALF_ULP = 2.0**-10


def _fract(x):
    return x - np.floor(x)


def _ign_glsl(x, y):
    # fract( 52.9829189 * fract( dot( position, vec2( 0.06711056, 0.00583715 ) ) ) )
    return _fract(52.9829189 * _fract(x * 0.06711056 + y * 0.00583715))


def test_constants_are_r187s():
    assert three_filters.IGN == (0.06711056, 0.00583715, 52.9829189)
    assert three_filters.GOLDEN_ANGLE == 2.399963229728653
    assert three_filters.PCF_SAMPLES == 5
    assert three_filters.VSM_BLEED == (0.3, 0.65)
    assert three_filters.VSM_MIN_VARIANCE == 1e-7
    # the golden angle is pi (3 - sqrt 5)
    assert three_filters.GOLDEN_ANGLE == pytest.approx(math.pi * (3.0 - math.sqrt(5.0)), 1e-15)


def test_interleaved_gradient_noise_and_frag_coord():
    x, y = RNG.uniform(0, 2000, 1000), RNG.uniform(0, 2000, 1000)
    np.testing.assert_array_equal(three_filters.interleaved_gradient_noise(x, y), _ign_glsl(x, y))
    px, py = three_filters.frag_coord(4, 3)
    # lower-left origin: the top row of a 3-row image is gl_FragCoord.y = 2.5
    assert px.tolist()[:4] == [0.5, 1.5, 2.5, 3.5] and py.tolist()[:4] == [2.5] * 4
    assert py.tolist()[-1] == 0.5


def test_vogel_disk_radii_and_angles():
    for k in range(5):
        dx, dy = three_filters.vogel_disk(k, 5, 0.3)
        assert math.hypot(dx, dy) == pytest.approx(math.sqrt((k + 0.5) / 5.0), 1e-15)
        assert math.atan2(dy, dx) == pytest.approx(
            math.remainder(k * 2.399963229728653 + 0.3, 2 * math.pi), abs=1e-12
        )


def _pcf_glsl(depth, u, v, ref, radius, phi):
    """getShadow (PCF) of shadowmap_pars_fragment.glsl.js:150-191, one receiver at a time,
    with the model's texture orientation (v down: the disk's y flips)."""
    r = depth.shape[0]
    tex = filters.upload_texels(depth)
    total = 0.0
    for k in range(5):
        rr = math.sqrt((k + 0.5) / 5)
        theta = k * 2.399963229728653 + phi
        su = u + math.cos(theta) * rr * radius / r
        sv = v - math.sin(theta) * rr * radius / r
        total += float(filters.compare_bilinear(tex, np.array([su]), np.array([sv]), ref)[0])
    if not (0 <= u <= 1 and 0 <= v <= 1 and ref <= 1):
        return 1.0
    return total * 0.2


def test_pcf_matches_the_glsl_receiver_by_receiver(mi):
    depth = RNG.uniform(0.3, 0.7, (32, 32)).astype(np.float32)
    u, v = RNG.uniform(0.05, 0.95, 50), RNG.uniform(0.05, 0.95, 50)
    ref = RNG.uniform(0.3, 0.7, 50)
    phi = RNG.uniform(0, 2 * math.pi, 50)
    got = three_filters.lookup_pcf(filters.upload_texels(depth), u, v, ref, radius=2.0, phi=phi)
    want = [_pcf_glsl(depth, *a, 2.0, p) for *a, p in zip(u, v, ref, phi, strict=True)]
    np.testing.assert_allclose(got, want, atol=1e-12)
    # closed forms: a receiver in front of every texel is lit, behind every texel shadowed
    flat = filters.upload_texels(np.full((16, 16), 0.5, np.float32))
    ones = np.ones(3)
    lit = three_filters.lookup_pcf(flat, 0.5 * ones, 0.5 * ones, 0.4, radius=1.0, phi=ones)
    dark = three_filters.lookup_pcf(flat, 0.5 * ones, 0.5 * ones, 0.6, radius=1.0, phi=ones)
    assert lit.tolist() == [1.0] * 3 and dark.tolist() == [0.0] * 3
    # outside the map or beyond its far plane: lit without a lookup (frustumTest)
    out = three_filters.lookup_pcf(
        flat,
        np.array([1.2, 0.5]),
        np.array([0.5, 0.5]),
        np.array([0.6, 1.01]),
        radius=1.0,
        phi=np.zeros(2),
    )
    assert out.tolist() == [1.0, 1.0]


def _vsm_glsl(depth, radius, samples):
    """vsm.glsl.js's two passes, texel by texel (nearest depth reads, then bilinear RG16F
    reads along x), float16 storage between and after."""
    r = depth.shape[0]
    stride = 2.0 / (samples - 1)
    first = np.zeros((r, r, 2), np.float16)
    for j in range(r):
        for i in range(r):
            m = sq = 0.0
            for k in range(samples):
                y = j + 0.5 + (-1.0 + k * stride) * radius
                d = float(depth[min(max(int(math.floor(y)), 0), r - 1), i])
                m, sq = m + d, sq + d * d
            m, sq = m / samples, sq / samples
            first[j, i] = (m, math.sqrt(max(0.0, sq - m * m)))
    out = np.zeros((r, r, 2), np.float16)
    for j in range(r):
        for i in range(r):
            m = sq = 0.0
            for k in range(samples):
                x = i + (-1.0 + k * stride) * radius
                x0 = math.floor(x)
                f = round((x - x0) * 256) / 256
                a = first[j, min(max(x0, 0), r - 1)].astype(np.float64)
                b = first[j, min(max(x0 + 1, 0), r - 1)].astype(np.float64)
                mean, std = a * (1 - f) + b * f
                m, sq = m + mean, sq + std * std + mean * mean
            m, sq = m / samples, sq / samples
            out[j, i] = (m, math.sqrt(max(0.0, sq - m * m)))
    return out


def test_vsm_texture_matches_both_glsl_passes():
    depth = RNG.uniform(0.2, 0.8, (12, 12)).astype(np.float32)
    depth[:, 6:] = 0.9
    got = three_filters.vsm_texture(depth, radius=1.5, samples=8)
    np.testing.assert_array_equal(got, _vsm_glsl(depth, 1.5, 8))
    flat = three_filters.vsm_texture(np.full((8, 8), 0.25, np.float32), radius=4.0, samples=8)
    np.testing.assert_array_equal(flat[..., 0], np.float16(0.25))
    assert np.abs(flat[..., 1].astype(float)).max() <= 0.25 * HALF_ULP * 8
    assert three_filters.vsm_blur_offsets(8).tolist() == pytest.approx(
        [-1 + k * 2 / 7 for k in range(8)]
    )


def test_vsm_lookup_is_the_remapped_chebyshev_bound():
    mean, std = 0.5, 0.05
    tex = np.zeros((4, 4, 2), np.float16)
    tex[...] = (mean, std)
    m, s = float(np.float16(mean)), float(np.float16(std))
    z = np.array([0.45, 0.5, 0.55, 0.6, 0.9])
    got = three_filters.lookup_vsm(tex, np.full(5, 0.5), np.full(5, 0.5), z)
    var = s * s
    p = var / (var + (z - m) ** 2)
    want = np.where(z <= m, 1.0, np.clip((p - 0.3) / 0.65, 0, 1))
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert got[0] == 1.0 and got[-1] == 0.0  # far behind: the remap cuts the bleed to 0
