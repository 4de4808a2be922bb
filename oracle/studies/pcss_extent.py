"""PCSS's filter extent against the geometric penumbra, per preset and map field of view
(issue 45), measured on the model's own lookup (:func:`raster_models.shadowmaps.pcss_filter.
pcss_lookup`) over synthetic perspective maps: a blocker plane at distance ``t_b`` from the
light over a receiver plane at ``t_r``, both facing it.

- :func:`radius_factors`: the filter radius against the geometric penumbra *radius* (half the
  parallel-plane width ``L (t_r - t_b) / t_b`` of a disk light of diameter ``L``), over a grid
  of light sizes and blocker distances, at 30, 60 and 90 degree maps. ``nvidia`` reads its
  ``LIGHT_WORLD_SIZE`` as the light's full width and uses the parallel-plane *width* as the
  radius: 2 at every field of view. ``hdrp`` fixes its radius in map coordinates (the 4096
  fit), so against the geometry it scales with ``tan(fov / 2)``.
- :func:`transition_factors`: the 10-90 % width of the visibility across the straight edge of
  a half-plane blocker (the receivers' profile, averaged over rows; ``hdrp`` rotated per pixel
  by interleaved gradient noise as shipped) against the disk light's, ``0.687`` of its
  penumbra width (the circular segment's 10 % and 90 % points).

Run by ``raster-oracle soft-shadows`` (its record's ``extent`` entry)."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "BLOCKER_DISTANCES",
    "FOVS",
    "LIGHT_SIZES",
    "disk_light_transition",
    "extent_report",
    "radius_factors",
    "transition_factors",
]

#: Map fields of view (degrees), light sizes (full widths, m; HDRP's default shape radius
#: 0.025 is a size of 0.05) and blocker distances from the light (m; HDRP's fit stops at 7.5).
FOVS = (30.0, 60.0, 90.0)
LIGHT_SIZES = (0.05, 0.2, 0.5, 1.0, 2.0)
BLOCKER_DISTANCES = (1.0, 2.0, 3.0, 5.0, 7.5)
#: Receiver at twice the blocker's distance; far plane (HDRP: the light's range) far beyond.
RECEIVER_FACTOR, FAR = 2.0, 1000.0
NEAR = 0.05


def disk_light_transition() -> float:
    """10-90 % width of a disk light's penumbra over a straight edge, as a fraction of the
    penumbra's full width: the circular segment's area fraction ``(acos s - s sqrt(1 - s^2))
    / pi`` at 10 % and 90 %, ``s`` in radii."""
    from scipy.optimize import brentq

    def lit(s):
        return (math.acos(s) - s * math.sqrt(1.0 - s * s)) / math.pi

    s10 = brentq(lambda s: lit(s) - 0.1, -1.0, 1.0)
    return s10  # the 90 % point is -s10: the width is 2 s10 radii = s10 full widths


def _proj(fov: float, res: int):
    from ...raster_models.light_frame import Projection, make_frame

    frame = make_frame((0.0, -1.0, 0.0), [("x", (1.0, 0.0, 0.0))], (0.0, 10.0, 0.0))
    return Projection("persp", frame, (math.tan(math.radians(fov) / 2.0), NEAR, FAR), res)


def _map(proj, res: int, t_b: float, t_r: float, blocked):
    """A map holding the blocker plane where ``blocked(u, v)`` and the receiver elsewhere, and
    the receiver's stored depth."""
    from ...raster_models.shadowmaps.filters import upload_texels
    from ...raster_models.shadowmaps.records import MapData

    _, n, f = proj.extent
    c = (np.arange(res) + 0.5) / res
    u, v = np.meshgrid(c, c)
    inside = blocked(u, v)

    def stored(t):
        return f / (f - n) - f * n / (f - n) / t

    depth = np.where(inside, stored(t_b), stored(t_r)).astype(np.float32)
    data = MapData(depth, None, (0.0, 0.0), int(inside.sum()), 0.0, upload_texels(depth))
    return data, float(np.float32(stored(t_r)))  # the receiver's depth as the map holds it


def _params(preset: str, size: float, res: int, **kw):
    from ...raster_models.shadowmaps.pcss import PcssParams, resolved

    p = PcssParams(preset=preset, light_size=size, light_range=FAR, resolution=res, **kw)
    return resolved(p, None)


def _band(u, v):
    return np.abs(u - 0.5) < 0.4


def _half_plane(u, v):
    return u < 0.5


def radius_factors(preset: str, fov: float, *, res: int = 512, **kw) -> dict:
    """Filter radius / geometric penumbra radius over :data:`LIGHT_SIZES` x
    :data:`BLOCKER_DISTANCES` at a ``fov`` map: ``min``, ``max`` and the ``grid`` rows;
    ``kw``: further ``pcss`` parameters."""
    from ...raster_models.shadowmaps.pcss_filter import pcss_lookup

    proj = _proj(fov, res)
    rows = []
    for t_b in BLOCKER_DISTANCES:
        t_r = RECEIVER_FACTOR * t_b
        data, z_r = _map(proj, res, t_b, t_r, _band)
        z = np.array([z_r])
        for size in LIGHT_SIZES:
            p = _params(preset, size, res, rotation="none", **kw)
            _, radius, _ = pcss_lookup(data, proj, np.array([0.5]), np.array([0.5]), z, z, p)
            geo = 0.5 * size * (t_r - t_b) / t_b / (2.0 * t_r * proj.extent[0])
            rows.append({"light_size": size, "blocker_distance": t_b, "factor": radius[0] / geo})
    factors = [r["factor"] for r in rows]
    return {"min": float(min(factors)), "max": float(max(factors)), "grid": rows}


def _profile_width(x, vis) -> float:
    """10-90 % width of a visibility profile rising along ``x`` (linear interpolation)."""
    return float(np.interp(0.9, vis, x) - np.interp(0.1, vis, x))


def transition_factors(preset: str, fov: float, *, res: int = 2048, **kw) -> dict:
    """10-90 % width across a half-plane blocker's edge against the disk light's (light
    size 1 m, blocker 3 m and receiver 5 m from the light: ``soft-contact``'s plate)."""
    from ...raster_models.shadowmaps.pcss_filter import interleaved_gradient_noise, pcss_lookup

    t_b, t_r, size = 3.0, 5.0, 1.0
    proj = _proj(fov, res)
    data, z_r = _map(proj, res, t_b, t_r, _half_plane)
    per_uv = 2.0 * t_r * proj.extent[0]  # world units per map unit at the receiver
    width = size * (t_r - t_b) / t_b
    half = 1.5 * width / per_uv
    x = np.linspace(0.5 - half, 0.5 + half, 601)
    rows = 64
    u = np.tile(x, rows)
    v = np.repeat(0.5 + (np.arange(rows) - rows / 2) / res, x.size)
    p = _params(preset, size, res, **kw)
    rotation = None
    if p.rotation == "ign":
        px, py = np.tile(np.arange(x.size), rows), np.repeat(np.arange(rows), x.size)
        rotation = interleaved_gradient_noise(px, py) * 2.0 * math.pi
    z = np.full(u.shape, z_r)
    vis, _, _ = pcss_lookup(data, proj, u, v, z, z, p, rotation)
    profile = np.maximum.accumulate(vis.reshape(rows, x.size).mean(axis=0))
    measured = _profile_width(x, profile) * per_uv
    geometric = disk_light_transition() * width
    return {"measured_m": measured, "geometric_m": geometric, "factor": measured / geometric}


def extent_report() -> dict:
    """Both measurements for ``nvidia`` (as shipped and at ``radius_scale`` 0.5) and ``hdrp``
    at every field of view of :data:`FOVS`."""
    out = {"fovs": list(FOVS), "presets": {}}
    for label, preset, kw in (
        ("nvidia", "nvidia", {}),
        ("nvidia, radius_scale=0.5", "nvidia", {"radius_scale": 0.5}),
        ("hdrp", "hdrp", {}),
    ):
        out["presets"][label] = {
            str(int(fov)): {
                "radius": radius_factors(preset, fov, **kw),
                "transition": transition_factors(preset, fov, **kw),
            }
            for fov in FOVS
        }
    return out
