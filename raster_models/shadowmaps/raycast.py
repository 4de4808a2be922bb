"""Rays through every texel centre of a shadow map, generated and cast on the Dr.Jit side.

A rasterizer with a depth test stores, per texel centre, the nearest surface along the
texel's ray: casting that ray gives the same answer (ARCHITECTURE.md, "One intersection
engine, two ways of sampling"). The rays of a map form an affine grid
(:meth:`Projection.grid_rays`), so they are built directly as Dr.Jit arrays from the texel
index, in float64 and rounded once to the engine's float32, instead of being shipped from
NumPy: for a 2048^2 map this is ~15x faster than :func:`scenes.backend.raycast.intersect`, which is
what makes 4 x 2048^2 maps at 1080p fit the benchmark budget. The scene, its Mitsuba variant
and the intersection engine are still the ones :mod:`scenes` loaded.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend
from ..drjit import numpy_view
from .depth_dr import stored_depth_dr
from .faces import first_hit

__all__ = ["GRID_CHUNK", "iter_grid"]

#: Texels per Dr.Jit launch (bounded memory: about 0.3 GiB a launch with normals).
GRID_CHUNK = 1 << 22


def iter_grid(
    scene,
    grid: dict,
    resolution: int,
    depth: tuple,
    *,
    normals: bool = False,
    store: tuple[str, float] | None = None,
    faces: str = "both",
    alpha: str = "test",
):
    """Cast one ray per texel centre of a ``resolution``-square map, in launches of
    :data:`GRID_CHUNK` texels, and yield ``(start, stop, chunk)`` per launch (flat texel
    range ``[start, stop)``, row-major). Memory stays bounded by the launch size at any map
    resolution.

    Parameters
    ----------
    scene : scenes.LoadedScene
    grid : the affine ray description of :meth:`Projection.grid_rays`.
    resolution : texels per side ``R``; texel ``(i, j)`` (column, row) has texture
        coordinates ``s = (i + 0.5) / R``, ``t = (j + 0.5) / R``.
    depth : how a hit becomes normalized depth, evaluated in float64: ``("ortho", c0, cs,
        ct, cd)`` for ``z = c0 + s cs + t ct + d cd`` (``d`` = hit distance along the unit
        direction), or ``("persp", a, b)`` for ``z = a - b / tau`` with light-view depth
        ``tau = z_start + d / |direction|``.
    normals : also give the geometric normal ``normal`` ``(n, 3)`` float32, hit distance
        ``t`` (``inf`` on a miss) and direction length ``dir_norm`` per texel (for the
        slope-scaled bias).
    store : ``(format, bias)`` (without ``normals``): the texels are finished in the same
        kernel (:func:`.depth_dr.stored_depth_dr`) and ``chunk`` holds ``stored`` (float32
        map texels, a view of the Dr.Jit array ``texels``) and ``covered`` (texels hit)
        instead of ``z``.
    faces : the faces the shadow pass keeps (:func:`.faces.first_hit`: ``both``, ``front``,
        ``back``).
    alpha : ``test``: alpha-tested casters are cut out; ``ignore``: whole (see
        :func:`.faces.first_hit`).

    ``chunk["z"]``: float64 normalized depth, unclamped, ``inf`` on a miss.
    """
    mi = backend.mitsuba()
    import drjit as dr

    r = int(resolution)
    n_total = r * r
    span = grid["z_end"] - grid["z_start"]
    f64 = mi.Float64

    def const(x):
        # Kernel parameters, not literals: one compiled kernel serves every map.
        return dr.opaque(f64, float(x))

    def vec(name):
        return [const(c) for c in np.asarray(grid[name], dtype=np.float64)]

    A, U, V, D, DS, DT = (vec(k) for k in ("A", "U", "V", "D", "DS", "DT"))
    along = bool(grid["origin_along_dir"])
    zs = const(grid["z_start"])
    coef = [const(c) for c in depth[1:]]
    r_u, inv_r, span_k = dr.opaque(mi.UInt32, r), const(1.0 / r), const(span)
    for start in range(0, n_total, GRID_CHUNK):
        stop = min(n_total, start + GRID_CHUNK)
        idx = dr.arange(mi.UInt32, start, stop)
        s = (f64(idx % r_u) + 0.5) * inv_r
        t = (f64(idx // r_u) + 0.5) * inv_r
        d = [D[k] + s * DS[k] + t * DT[k] for k in range(3)]
        dnorm = dr.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        o = [A[k] + s * U[k] + t * V[k] for k in range(3)]
        if along:
            o = [o[k] + d[k] * zs for k in range(3)]
        inv = 1.0 / dnorm
        ray = mi.Ray3f(
            mi.Point3f(mi.Float(o[0]), mi.Float(o[1]), mi.Float(o[2])),
            mi.Vector3f(mi.Float(d[0] * inv), mi.Float(d[1] * inv), mi.Float(d[2] * inv)),
        )
        ray.maxt = mi.Float(span_k * dnorm)
        valid, th, hit_n = first_hit(scene, ray, faces, normals=normals, alpha=alpha)
        dist = f64(dr.select(valid, th, 0.0))
        if depth[0] == "ortho":
            z = coef[0] + s * coef[1] + t * coef[2] + dist * coef[3]
        else:
            tau = zs + dist / dnorm
            z = coef[0] - coef[1] / dr.maximum(tau, 1e-300)
        z = dr.select(valid, z, dr.inf)
        if store is not None:
            texels, hit = stored_depth_dr(mi, z, store[0], store[1])
            # Both from one kernel (dr.count would evaluate ``hit`` in a kernel of its own,
            # casting every ray twice); counted in NumPy.
            dr.eval(texels, hit)
            covered = int(np.count_nonzero(hit.numpy()))
            chunk = {"stored": texels.numpy(), "covered": covered, "texels": texels}
            yield start, stop, chunk
            continue
        if normals:
            dr.eval(z, hit_n, dist, dnorm, valid)
            chunk = {
                "z": numpy_view(z),
                "normal": numpy_view(hit_n).T.astype(np.float32),
                "t": np.where(numpy_view(valid), numpy_view(dist), np.inf),
                "dir_norm": numpy_view(dnorm),
            }
        else:
            dr.eval(z)
            chunk = {"z": numpy_view(z)}
        yield start, stop, chunk
