"""Coherent shadow maps' rendering: the first (and second) surface of every texel of every
map, traced by Mitsuba in Dr.Jit kernels over the maps' ray grids
(:func:`raster_models.coherent.rays.ray_table`), and the texels' visibility intervals
computed in the same kernels (:func:`raster_models.coherent.kernels.intervals`).

Depths are normalized over the bounding sphere's diameter, ``[0, 1]`` from the sphere's near
plane along the map's direction; ``inf``: no surface.

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
"""

from __future__ import annotations

import numpy as np

from .kernels import intervals
from .rays import ray_table

__all__ = [
    "RECORD_CHUNK",
    "SPREAD_GUARD",
    "SURFACE_CHUNK",
    "first_surface",
    "render_intervals",
    "stored_depth",
    "surface_chunks",
    "surfaces",
]

#: Texels per Dr.Jit launch of the map kernel of :func:`render_intervals`. The kernel
#: keeps no per-texel arrays of its own (the surface interactions stay in registers) and
#: writes two float32 bounds per texel: peak memory does not grow with the launch
#: (measured at the defaults), while every launch costs its tracing and a synchronisation
#: (a quarter of the render time at 1 << 20).
SURFACE_CHUNK = 1 << 24

#: Texels per launch of :func:`surfaces`, whose NumPy records hold 32 bytes a texel
#: (128 MiB a launch).
RECORD_CHUNK = 1 << 22

#: Safety factor on the depth spreads of :func:`render_intervals`: curved surfaces bend
#: away from their tangent plane within a texel (1.01 left one mismatching receiver on
#: ``curved`` at 1024 maps of 64^2; 1.5 none on the built-in scenes).
SPREAD_GUARD = 1.5


def surface_chunks(scene, projs, ids, *, second: bool, chunk: int | None = None):
    """The Dr.Jit side of :func:`surfaces`: yields ``(start, stop, record)`` per chunk of at
    most ``chunk`` texels (default :data:`SURFACE_CHUNK`) with ``record`` holding
    unevaluated Dr.Jit Float64 arrays."""
    from ...scenes import backend

    mi = backend.mitsuba()
    import drjit as dr

    chunk = SURFACE_CHUNK if chunk is None else chunk
    r = projs.resolution
    rr = r * r
    k = len(ids)
    params = ray_table(projs, ids)
    f64 = mi.Float64
    cols = [f64(np.ascontiguousarray(params[:, c])) for c in range(13)]
    total = k * rr
    # Literal divisors: the compiler turns the per-texel divisions into multiplications
    # and shifts (one kernel per map resolution).
    r_u, rr_u = r, rr
    inv_r = dr.opaque(f64, 1.0 / r)
    half_inv_r = dr.opaque(f64, 0.5 / r)

    def spread(n, g, span):
        nf = [f64(n[i]) for i in range(3)]
        nu = dr.abs(nf[0] * g[3] + nf[1] * g[4] + nf[2] * g[5])
        nv = dr.abs(nf[0] * g[6] + nf[1] * g[7] + nf[2] * g[8])
        nd = dr.abs(nf[0] * g[9] + nf[1] * g[10] + nf[2] * g[11])
        return dr.select(nd > 1e-12, (nu + nv) * half_inv_r / (nd * span), dr.inf)

    for start in range(0, total, chunk):
        stop = min(total, start + chunk)
        # The chunk offset is a kernel parameter: one compiled kernel serves every chunk.
        idx = dr.arange(mi.UInt32, stop - start) + dr.opaque(mi.UInt32, start)
        mid = idx // rr_u
        tex = idx - mid * rr_u
        row = tex // r_u
        s = (f64(tex - row * r_u) + 0.5) * inv_r
        t = (f64(row) + 0.5) * inv_r
        g = [dr.gather(f64, c, mid) for c in cols]
        o = [g[i] + s * g[3 + i] + t * g[6 + i] for i in range(3)]
        span = g[12]
        ray = mi.Ray3f(
            mi.Point3f(mi.Float(o[0]), mi.Float(o[1]), mi.Float(o[2])),
            mi.Vector3f(mi.Float(g[9]), mi.Float(g[10]), mi.Float(g[11])),
        )
        ray.maxt = mi.Float(span)
        if second:
            si = scene.mi_scene.ray_intersect(ray, mi.RayFlags.Minimal, coherent=True)
            valid = si.is_valid()
            t1 = f64(si.t)
            ray2 = si.spawn_ray(ray.d)
            ray2.maxt = dr.maximum(mi.Float(span - t1), 0.0)
            si2 = scene.mi_scene.ray_intersect(
                ray2, mi.RayFlags.Minimal, coherent=False, active=valid
            )
            valid2 = valid & si2.is_valid()
            out = {
                "z1": dr.select(valid, t1 / span, dr.inf),
                "z2": dr.select(valid2, (t1 + f64(si2.t)) / span, dr.inf),
                "dz1": dr.select(valid, spread(si.n, g, span), 0.0),
                "dz2": dr.select(valid2, spread(si2.n, g, span), 0.0),
            }
        else:
            pi = scene.mi_scene.ray_intersect_preliminary(ray, coherent=True)
            out = {"z1": dr.select(pi.is_valid(), f64(pi.t) / span, dr.inf)}
        yield start, stop, out


def surfaces(scene, projs, ids, *, second: bool):
    """First (and second) surfaces of every texel of maps ``ids``, batched over maps.

    Rays are those of :meth:`Projection.grid_rays` (texel centres, from the sphere's near
    plane along the map's direction). Yields ``(start, stop, record)`` per chunk of the
    flattened ``(len(ids), R^2)`` texels; ``record`` holds ``z1`` (and ``z2``): depth
    normalized over the sphere's diameter (``inf``: no surface), and with ``second`` the
    half-footprint depth spreads ``dz1``, ``dz2``: how far the depth of the hit surface's
    plane moves from the texel centre to a texel corner, ``(|n.U| + |n.V|) / (2 r |n.D|)``
    in normalized depth (``inf`` for a surface seen edge-on). The second surface is found by
    continuing from the first hit with Mitsuba's ``spawn_ray`` (its self-intersection
    offset).
    """
    import drjit as dr

    for start, stop, out in surface_chunks(scene, projs, ids, second=second, chunk=RECORD_CHUNK):
        dr.eval(*out.values())
        yield start, stop, {key: val.numpy() for key, val in out.items()}


def first_surface(scene, projs, ids) -> np.ndarray:
    """First-surface depth ``(len(ids), R^2)`` (see :func:`surfaces`)."""
    rr = projs.resolution**2
    z1 = np.empty(len(ids) * rr, dtype=np.float64)
    for start, stop, rec in surfaces(scene, projs, ids, second=False):
        z1[start:stop] = rec["z1"]
    return z1.reshape(len(ids), rr)


def render_intervals(scene, projs, ids, bias: float, *, footprint: bool = True):
    """Visibility intervals ``(lo, hi)`` of every texel of maps ``ids``: flat Dr.Jit Float32
    arrays of ``len(ids) * R^2`` values (map-major), computed inside the rendering kernel
    chunk by chunk by :func:`raster_models.coherent.kernels.intervals` (see there;
    ``footprint=False``: texel centres only, spreads 0)."""
    from ...scenes import backend

    mi = backend.mitsuba()
    import drjit as dr

    total = len(ids) * projs.resolution**2
    lo = hi = None
    for start, stop, rec in surface_chunks(scene, projs, ids, second=True):
        spreads = {"dz1": rec["dz1"], "dz2": rec["dz2"]} if footprint else {}
        c_lo, c_hi = intervals(rec["z1"], rec["z2"], bias, SPREAD_GUARD, **spreads)
        if stop - start == total:  # one launch: the kernel's outputs are the arrays
            lo, hi = c_lo, c_hi
        else:
            if lo is None:
                lo, hi = dr.empty(mi.Float, total), dr.empty(mi.Float, total)
            idx = dr.arange(mi.UInt32, start, stop)
            dr.scatter(lo, c_lo, idx)
            dr.scatter(hi, c_hi, idx)
        dr.eval(lo, hi)
    return lo, hi


def stored_depth(z1: np.ndarray) -> np.ndarray:
    """Stored depth: float32 of the first surface, 1 (cleared) where no surface."""
    return np.where(np.isfinite(z1), z1, 1.0).astype(np.float32)
