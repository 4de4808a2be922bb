"""Area-light truth against closed forms: a straight occluder edge over a ground plane under
a rectangle and a disk light parallel to it (issue 38).

The occluder is the half-plane ``x < 0`` at height ``h``; the light, centred above the edge at
height ``H`` and facing down, is seen from the ground point ``(x, 0, z)`` where its points
``(X, H, Z)`` have ``X >= X_c = -x (H - h) / h``: a rectangle cut by one line (a disk: a
circular segment). So

- ``light_fraction``: rectangle ``(a - X_c) / 2a`` (linear across the penumbra), disk the
  circular segment ``(acos(c) - c sqrt(1 - c^2)) / pi`` with ``c = X_c / R``;
- ``soft_visibility``: the irradiance of the visible polygon over that of the whole light,
  both by Lambert's polygon formula (the disk's arc as a 2048-gon: relative error ~1e-6).

Under a sphere light (radius 0.4, centre 1.5 up) the visible directions are a cap (the cone
the sphere subtends) cut by the plane through the point and the edge: ``light_fraction`` (the
cap's visible share, uniform in solid angle) is the area of a spherical cap segment.

All are averaged over each pixel's footprint (16 x 16 film points per pixel, their ground
points from the camera's float64 rays) and compared with the reference on the penumbra's
pixels.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.catalogue.builtin import BuiltinScene
from raster_oracle.scenes.catalogue.factories import ground, mesh, sensor
from raster_oracle.scenes.geometry import meshes
from raster_oracle.scenes.shading.materials import diffuse

from raster_oracle import scenes

#: Light height, occluder height, rectangle half sizes (x, z), disk radius, sphere radius.
H, HO, A, B, R, RS = 1.5, 0.5, 0.6, 0.35, 0.6, 0.4
RADIANCE = 5.0
W, HT, SPP = 128, 64, 64
#: Film points per pixel side for the closed forms' pixel averages.
SUB = 16
#: Fraction of penumbra pixels that must lie within 4 standard errors (the issue's bar).
WITHIN = 0.999


def _scene(light: str):
    def factory(width, height):
        emitter = {"type": "area", "radiance": {"type": "rgb", "value": [RADIANCE] * 3}}
        m = np.eye(4)
        m[:3, 3] = (0.0, H, 0.0)
        # local +Z (the emitting side) turned to -Y; local x along world x
        m[:3, :3] = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
        if light == "rectangle":
            m[:3, 0] *= A
            m[:3, 1] *= B
        elif light == "disk":
            m[:3, :2] *= R
        else:
            m[:3, :3] = np.eye(3) * RS
        return {
            "type": "scene",
            "camera": sensor(
                width,
                height,
                origin=(1.6, 1.2, 0.0),
                target=(0.0, 0.0, 0.0),
                fov=32,
                near=0.05,
                far=50,
            ),
            "light": {"type": light, "to_world": m, "bsdf": diffuse(0.0), "emitter": emitter},
            "ground": ground(40.0, 0.5),
            "occluder": mesh(
                meshes.quad([[-20, HO, -20], [-20, HO, 20], [0, HO, 20], [0, HO, -20]]), 0.5
            ),
        }

    spec = BuiltinScene(f"edge-{light}", factory, "closed-form edge")
    return scenes.load(spec, width=W, height=HT)


def _ground_points(loaded):
    """Ground points of ``SUB x SUB`` film points per pixel: ``(HT, W, SUB * SUB, 3)``."""
    cam = loaded.camera
    off = (np.arange(SUB) + 0.5) / SUB
    oy, ox = np.meshgrid(off, off, indexing="ij")
    py, px = np.meshgrid(np.arange(HT), np.arange(W), indexing="ij")
    x = (px[..., None] + ox.ravel()).ravel()
    y = (py[..., None] + oy.ravel()).ravel()
    o, d, _ = cam.rays(x, y)
    t = -o[:, 1] / d[:, 1]
    pts = o + d * t[:, None]
    assert np.all(t > 0)
    return pts.reshape(HT, W, SUB * SUB, 3)


def _lambert(points, polys):
    """Irradiance / radiance at ground ``points`` (N, 3) (normal +Y) from polygons
    ``polys`` (N, V, 3) (or (V, 3) shared): Lambert's formula ``sum gamma_i n . N_i``,
    orientation-free (absolute value)."""
    polys = np.broadcast_to(polys, (len(points),) + polys.shape[-2:])
    r = polys - points[:, None, :]
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    r2 = np.roll(r, -1, axis=1)
    cross = np.cross(r, r2)
    norm = np.linalg.norm(cross, axis=-1)
    gamma = np.arctan2(norm, np.sum(r * r2, axis=-1))
    ny = np.where(norm > 0, cross[..., 1] / np.where(norm > 0, norm, 1.0), 0.0)
    return np.abs(np.sum(gamma * ny, axis=-1))


def _cut(x):
    """The light's visible part starts at ``X_c`` (light-local x)."""
    return -x * (H - HO) / HO


def _rect_truth(pts):
    p = pts.reshape(-1, 3)
    xc = np.clip(_cut(p[:, 0]), -A, A)
    frac = (A - xc) / (2 * A)
    full = np.array([[-A, H, -B], [A, H, -B], [A, H, B], [-A, H, B]], float)
    vis = np.repeat(full[None], len(p), axis=0)
    vis[:, 0, 0] = xc
    vis[:, 3, 0] = xc
    soft = np.zeros(len(p))
    for s in range(0, len(p), 1 << 18):
        sl = slice(s, s + (1 << 18))
        soft[sl] = _lambert(p[sl], vis[sl]) / _lambert(p[sl], full)
    return soft.reshape(pts.shape[:-1]), frac.reshape(pts.shape[:-1])


def _disk_polygon(c, n=2048):
    """The disk's segment ``X >= c R`` as a polygon (arc of ``n`` points, then the chord)."""
    t0 = math.acos(max(-1.0, min(1.0, c)))
    phi = np.linspace(-t0, t0, n)
    return np.stack([R * np.cos(phi), np.full(n, H), R * np.sin(phi)], axis=-1)


def _disk_truth(pts):
    """Light fraction exactly; soft visibility from a table over (x, z) on a fine grid
    (Lambert of the 2048-gon segment; bilinear interpolation, error < 1e-4 at this size)."""
    p = pts.reshape(-1, 3)
    c = np.clip(_cut(p[:, 0]) / R, -1.0, 1.0)
    frac = (np.arccos(c) - c * np.sqrt(1 - c * c)) / math.pi
    xs = np.linspace(p[:, 0].min() - 1e-3, p[:, 0].max() + 1e-3, 801)
    zs = np.linspace(p[:, 2].min() - 1e-3, p[:, 2].max() + 1e-3, 41)
    full = _disk_polygon(-1.0)
    table = np.zeros((len(xs), len(zs)))
    for i, x in enumerate(xs):
        cc = _cut(x) / R
        if cc >= 1.0:
            continue
        q = np.stack([np.full(len(zs), x), np.zeros(len(zs)), zs], axis=-1)
        table[i] = _lambert(q, _disk_polygon(cc)) / _lambert(q, full)
    fx = np.interp(p[:, 0], xs, np.arange(len(xs)))
    fz = np.interp(p[:, 2], zs, np.arange(len(zs)))
    i0 = np.minimum(fx.astype(int), len(xs) - 2)
    j0 = np.minimum(fz.astype(int), len(zs) - 2)
    tx, tz = fx - i0, fz - j0
    soft = (
        table[i0, j0] * (1 - tx) * (1 - tz)
        + table[i0 + 1, j0] * tx * (1 - tz)
        + table[i0, j0 + 1] * (1 - tx) * tz
        + table[i0 + 1, j0 + 1] * tx * tz
    )
    return soft.reshape(pts.shape[:-1]), frac.reshape(pts.shape[:-1])


@pytest.fixture(scope="module", params=["rectangle", "disk"])
def case(request):
    loaded = _scene(request.param)
    pts = _ground_points(loaded)
    soft, frac = (_rect_truth if request.param == "rectangle" else _disk_truth)(pts)
    settings = ReferenceSettings(spp=SPP, channels=("soft", "visibility"))
    ch, stats = render_reference(loaded, settings, quiet=True)
    return request.param, loaded, soft.mean(axis=-1), frac.mean(axis=-1), ch, stats


def test_area_light_is_read(case):
    name, loaded, *_ = case
    light = loaded.light
    assert light.area == name and light.kind == "point"
    np.testing.assert_allclose(light.direction, (0, -1, 0), atol=1e-6)
    np.testing.assert_allclose(light.position, (0, H, 0), atol=1e-6)
    expect = (A, B) if name == "rectangle" else (R, R)
    np.testing.assert_allclose(light.half_size, expect, rtol=1e-6)
    area = 4 * A * B if name == "rectangle" else math.pi * R * R
    np.testing.assert_allclose(light.color, [RADIANCE * area] * 3, rtol=1e-6)


@pytest.mark.parametrize("channel", ["soft_visibility", "light_fraction"])
def test_soft_channels_match_closed_forms(case, channel):
    name, _, soft, frac, ch, _ = case
    truth = soft if channel == "soft_visibility" else frac
    penumbra = (frac > 1e-3) & (frac < 1 - 1e-3)
    assert penumbra.sum() > 0.3 * W * HT, "the penumbra must fill much of the image"
    err = ch[channel].astype(np.float64) - truth
    se = ch[f"{channel}_stderr"].astype(np.float64)
    z = np.abs(err[penumbra]) / se[penumbra]
    assert np.mean(z <= 4.0) >= WITHIN, f"{name} {channel}: {np.sort(z)[-10:]}"
    # the standard errors are those of a useful truth, and the errors are of their size
    assert np.median(se[penumbra]) < 0.03
    assert np.sqrt(np.mean(err[penumbra] ** 2)) < 2.0 * np.sqrt(np.mean(se[penumbra] ** 2))
    # outside the penumbra: exactly lit or exactly in the umbra
    lit, umbra = frac >= 1 - 1e-9, frac <= 1e-9
    far = lit & np.roll(lit, 1, 1) & np.roll(lit, -1, 1) & np.roll(lit, 1, 0) & np.roll(lit, -1, 0)
    assert np.all(ch[channel][far] == 1.0)
    dark = umbra & np.roll(umbra, 1, 1) & np.roll(umbra, -1, 1)
    dark &= np.roll(umbra, 1, 0) & np.roll(umbra, -1, 0)
    assert np.all(ch[channel][dark] == 0.0)


def test_the_two_channels_differ_where_the_weights_do(case):
    """Cosine and distance weighting moves soft visibility off the area fraction; where the
    closed forms part by more than 3 standard errors, the reference's channels part the same
    way (a test of the weighting, not of noise). Under the rectangle, whose long side lies
    across the edge, they part on hundreds of pixels; under the disk on a few."""
    name, _, soft, frac, ch, _ = case
    gap = soft - frac
    se = np.hypot(ch["soft_visibility_stderr"], ch["light_fraction_stderr"])
    apart = np.abs(gap) > 3 * se
    assert apart.sum() > (200 if name == "rectangle" else 0)
    measured = (ch["soft_visibility"] - ch["light_fraction"])[apart]
    assert np.mean(np.sign(measured) == np.sign(gap[apart])) > 0.95


def _cap_segment(alpha, beta):
    """Solid angle of the part of a spherical cap (angular radius ``alpha``) beyond a great
    circle at angular distance ``0 <= beta <= alpha`` from its centre:
    ``2 acos(sin b / sin a) - 2 cos a acos(tan b / tan a)`` (half the cap at ``b = 0``)."""
    sa = np.clip(np.sin(beta) / np.sin(alpha), -1, 1)
    ta = np.clip(np.tan(beta) / np.tan(alpha), -1, 1)
    return 2 * np.arccos(sa) - 2 * np.cos(alpha) * np.arccos(ta)


def _sphere_fraction(pts):
    """Visible share of the sphere's cone: directions ``d`` with ``d . (HO, x, 0) >= 0`` pass
    the occluder's height at ``x >= 0``; the cone's axis lies ``beta`` from that plane."""
    p = pts.reshape(-1, 3)
    to = np.array([0.0, H, 0.0]) - p
    d = np.linalg.norm(to, axis=-1)
    alpha = np.arcsin(RS / d)
    nv = np.stack([np.full(len(p), HO), p[:, 0], np.zeros(len(p))], -1)
    nv /= np.linalg.norm(nv, axis=-1, keepdims=True)
    beta = np.arcsin(np.clip(np.sum(to / d[:, None] * nv, -1), -1, 1))
    cap = 2 * math.pi * (1 - np.cos(alpha))
    part = _cap_segment(alpha, np.minimum(np.abs(beta), alpha))
    frac = np.where(beta >= 0, 1 - part / cap, part / cap)
    return frac.reshape(pts.shape[:-1])


def test_sphere_light_fraction_matches_the_cap_segment():
    loaded = _scene("sphere")
    assert loaded.light.area == "sphere"
    frac = _sphere_fraction(_ground_points(loaded)).mean(axis=-1)
    settings = ReferenceSettings(spp=SPP, channels=("soft",))
    ch, _ = render_reference(loaded, settings, quiet=True)
    penumbra = (frac > 1e-3) & (frac < 1 - 1e-3)
    assert penumbra.sum() > 0.3 * W * HT
    err = ch["light_fraction"].astype(np.float64) - frac
    z = np.abs(err[penumbra]) / ch["light_fraction_stderr"][penumbra]
    # 99.92 % here; the few beyond are tail pixels (true fraction ~0.01: a sliver of the cap
    # at its rim) where 2 of ~11 expected lit light samples make the sample standard error
    # too small, so this extra case (not the bar) gets a looser 99.8 %
    assert np.mean(z <= 4.0) >= 0.998, np.sort(z)[-10:]
    assert np.median(ch["light_fraction_stderr"][penumbra]) < 0.03
    # the irradiance share differs (cosine weighting) but is a share too
    soft = ch["soft_visibility"][penumbra]
    assert np.all((soft >= 0) & (soft <= 1))
