"""The rays of ``rtshadows``: the blue-noise tile's spectrum, AMD's cone rays and NRD's packed
penumbra against a direct per-pixel transcription of the pinned sources, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.raster_models.rtshadows import bluenoise, rays

F32 = np.float32


@pytest.fixture(scope="module")
def tile():
    return bluenoise.blue_noise_tile()


def test_tile_is_a_permutation_per_channel(tile):
    assert tile.shape == (128, 128, 2) and tile.dtype == np.float32
    for c in range(2):
        ranks = np.sort((tile[..., c].astype(np.float64) * 16384 - 0.5).round().astype(int).ravel())
        assert np.array_equal(ranks, np.arange(16384))
    assert not np.array_equal(tile[..., 0], tile[..., 1])


def test_tile_spectrum_is_blue(tile):
    """Blue noise: almost no power at low frequencies (white noise: the mean everywhere)."""
    f = np.fft.fftfreq(128)
    fr = np.hypot(*np.meshgrid(f, f))
    white = np.random.default_rng(0).permutation(16384).reshape(128, 128) / 16384.0
    for img, blue in ((tile[..., 0], True), (tile[..., 1], True), (white, False)):
        p = np.abs(np.fft.fft2(img - img.mean())) ** 2
        low = p[(fr > 0) & (fr < 0.1)].mean() / p[fr > 0].mean()
        # void and cluster: ~2e-4 here; white noise ~1 (its spectrum is flat)
        assert (low < 0.01) if blue else (low > 0.5)


def test_shipped_ranks_are_the_generators_output_byte_for_byte():
    """The shipped tile is void and cluster's output at the module's constants, not data of
    its own: regenerated here and compared byte for byte (and its checksum pinned)."""
    import hashlib

    raw = bluenoise.RANKS_FILE.read_bytes()
    assert hashlib.sha256(raw).hexdigest() == bluenoise.RANKS_SHA256
    made = np.stack(
        [bluenoise.void_and_cluster(bluenoise.TILE, seed=bluenoise.SEED + c) for c in range(2)],
        axis=-1,
    )
    assert made.astype("<u2").tobytes() == raw
    assert np.array_equal(bluenoise.tile_ranks(), made)


def test_a_changed_ranks_file_is_refused(tmp_path, monkeypatch):
    bad = tmp_path / "bluenoise_ranks.u16"
    raw = bytearray(bluenoise.RANKS_FILE.read_bytes())
    raw[0] ^= 1
    bad.write_bytes(bytes(raw))
    monkeypatch.setattr(bluenoise, "RANKS_FILE", bad)
    with pytest.raises(RuntimeError, match="checksum"):
        bluenoise.tile_ranks()


def test_tile_is_reproducible():
    a = bluenoise.void_and_cluster(32, seed=3)
    assert np.array_equal(a, bluenoise.void_and_cluster(32, seed=3))
    assert not np.array_equal(a, bluenoise.void_and_cluster(32, seed=4))


def _cone_scalar(s0, s1, n, radius):
    """raytracingcommon.hlsl:130-173 MapToCone + traceshadows.hlsl:99 normalize, one pixel,
    float32 scalars, line by line."""
    ox, oy = F32(2.0) * s0 - F32(1.0), F32(2.0) * s1 - F32(1.0)
    if ox == 0 and oy == 0:
        d = n
    else:
        if abs(ox) > abs(oy):
            r, theta = ox, (F32(3.14159265358979) / F32(4.0)) * (oy / ox)
        else:
            r = oy
            theta = (F32(3.14159265358979) / F32(2.0)) * (F32(1.0) - F32(0.5) * (ox / oy))
        u = F32(radius) * r * np.cos(F32(theta))
        v = F32(radius) * r * np.sin(F32(theta))
        up = np.array([0, 0, 1], F32) if abs(n[2]) < F32(0.99999) else np.array([1, 0, 0], F32)
        t0 = np.cross(up, n).astype(F32)
        t0 = (t0 / np.sqrt(F32(t0[0] * t0[0] + t0[1] * t0[1] + t0[2] * t0[2]))).astype(F32)
        t1 = np.cross(n, t0).astype(F32)
        d = (n + u * t0 + v * t1).astype(F32)
    return (d / np.sqrt(F32(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]))).astype(F32)


def test_cone_rays_equal_the_transcription_bit_for_bit(tile):
    frame, angle = 7, math.radians(8.0)
    radius = rays.sun_size(angle)
    light_dir = np.array([0.3, -1.0, 0.2], F32) / F32(np.linalg.norm([0.3, -1.0, 0.2]))
    py, px = np.mgrid[0:24, 120:136]  # crosses the tile's wrap at x = 128
    px, py = px.ravel(), py.ravel()
    noise = rays.pixel_noise(px, py, frame)
    got = rays.cone_directions(light_dir, noise, radius)
    phase = F32(F32(frame & 0xFF) * F32(1.6180339887))
    for i in range(px.size):
        texel = tile[py[i] % 128, px[i] % 128]
        s = [
            np.fmod(F32(int(texel[c] * F32(255.0))) / F32(255.0) + phase, F32(1.0)) for c in (0, 1)
        ]
        assert np.array_equal(noise[i], np.array(s, F32))
        want = _cone_scalar(s[0], s[1], (-light_dir).astype(F32), radius)
        assert np.array_equal(got[i], want), i


def test_cone_rays_fill_the_cone():
    radius = rays.sun_size(math.radians(10.0))
    s = np.random.default_rng(1).random((20000, 2)).astype(F32)
    d = rays.cone_directions(np.array([0, -1, 0], F32), s, radius)
    cos = d @ np.array([0, 1, 0], F32)
    tan = np.sqrt(np.maximum(1 - cos.astype(np.float64) ** 2, 0)) / cos
    assert tan.max() <= float(radius) * (1 + 1e-5)
    # uniform on the disk of radius tan: the mean squared radius is radius^2 / 2
    assert abs(np.mean(tan**2) / float(radius) ** 2 - 0.5) < 0.01


def test_noise_phase_is_the_golden_ratio_and_wraps():
    assert rays.noise_phase(1) == F32(1.6180339887)
    assert rays.noise_phase(256) == 0.0 and rays.noise_phase(257) == rays.noise_phase(1)


def test_packed_penumbra_closed_forms():
    sun = rays.pack_penumbra_sun(np.array([2.0, 0.0, 65504.0, 1e9], F32), 0.1)
    assert np.allclose(sun[:2], [0.1, 0.0]) and sun[2] == sun[3] == F32(65504.0)
    local = rays.pack_penumbra_local(
        np.array([1.0, 3.0, 70000.0], F32), np.array([3.0] * 3, F32), 1.0
    )
    assert np.isclose(local[0], 0.25) and local[1] == F32(32768.0) and local[2] == F32(65504.0)
    assert rays.pack_penumbra_sun(np.array([1e9], F32), 1e6)[0] == F32(65504.0)
    assert rays.pack_penumbra_sun(np.array([60000.0], F32), 10.0)[0] == F32(32768.0)
