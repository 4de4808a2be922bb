"""Which faces an engine renders into its shadow map, and which way its normal offset points.

- :func:`first_hit`: the nearest hit along shadow-map rays of a face the shadow pass keeps
  (``caster_faces``): ``both`` (no culling), ``front`` (the geometric normal as wound faces
  the light: ``n . d < 0`` for a ray travelling from the light) or ``back`` (the opposite
  side, three.js's ``shadowSide`` default for single-sided materials). Culled hits are
  stepped over, a layer at a time, as a rasterizer with face culling never sees them.
- Alpha-tested casters (glTF ``MASK``): with ``alpha="test"`` a hit the alpha test cuts out
  (:mod:`scenes.backend.alpha_hit`, the truth's own test at the texel centre's hit) is
  stepped over as a culled one; ``"ignore"`` keeps it (the opaque-quad shadow of engines
  whose depth pass drops the alpha test).
- :func:`wound_normals`: the visible surface's normal as its triangle is wound (not turned
  towards the camera), the direction an engine that offsets along the vertex normal uses
  (three.js ``shadowmap_vertex``): on the back of a double-sided surface it points away
  from the camera and the light.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend
from ...scenes.backend.alpha_hit import closest_hit_alpha, loaded_alpha

__all__ = ["CULL_LAYERS", "first_hit", "wound_normals"]

#: Culled layers a ray steps over at most; a ray still on a culled face after them misses
#: (no scene here stacks that many surfaces along one shadow-map texel).
CULL_LAYERS = 64

#: Relative step past a culled hit (of the distance travelled, plus an absolute floor).
STEP_REL = 1e-6


def first_hit(scene, ray, faces: str, *, normals: bool, alpha: str = "test"):
    """``(valid, t, n)`` of the nearest kept hit of ``ray`` (a Mitsuba ``Ray3f`` whose
    ``maxt`` bounds the search): Dr.Jit mask, distance along the (unit) direction and the
    geometric normal (``None`` unless ``normals``; ``both`` faces: Mitsuba's own hit)."""
    mi = backend.mitsuba()
    import drjit as dr

    cut = loaded_alpha(scene) if alpha == "test" else None
    if faces == "both" and cut is not None:
        si, _, _ = closest_hit_alpha(
            scene.mi_scene, ray, cut, flags=mi.RayFlags.Minimal, coherent=True
        )
        return si.is_valid(), si.t, (si.n if normals else None)
    if faces == "both":
        if normals:
            si = scene.mi_scene.ray_intersect(ray, mi.RayFlags.Minimal, coherent=True)
            return si.is_valid(), si.t, si.n
        pi = scene.mi_scene.ray_intersect_preliminary(ray, coherent=True)
        return pi.is_valid(), pi.t, None
    o, d, maxt = mi.Point3f(ray.o), mi.Vector3f(ray.d), mi.Float(ray.maxt)
    width = dr.width(maxt)
    travelled = dr.zeros(mi.Float, width)
    found = dr.zeros(mi.Bool, width)
    active = dr.full(mi.Bool, True, width)
    t_out = dr.zeros(mi.Float, width)
    n_out = dr.zeros(mi.Vector3f, width)
    for _ in range(CULL_LAYERS):
        r = mi.Ray3f(o + d * travelled, d)
        r.maxt = dr.maximum(maxt - travelled, 0.0)
        flags = mi.RayFlags.Minimal if cut is None else mi.RayFlags.UV
        si = scene.mi_scene.ray_intersect(r, flags, active)
        hit = active & si.is_valid()
        front = dr.dot(si.n, d) < 0.0
        keep = hit & (front if faces == "front" else ~front)
        if cut is not None:
            keep &= cut.covered(si, keep)
        t_out = dr.select(keep, travelled + si.t, t_out)
        n_out = dr.select(keep, si.n, n_out)
        found |= keep
        active = hit & ~keep
        travelled = dr.select(active, travelled + si.t * (1.0 + STEP_REL) + STEP_REL, travelled)
        dr.eval(t_out, n_out, found, active, travelled)
        if not dr.any(active):
            break
    return found, t_out, (n_out if normals else None)


def wound_normals(scene, gbuf) -> np.ndarray:
    """``(N, 3)`` normals of the G-buffer's surfaces as wound: ``gbuf.normal`` (turned to
    the camera) where the camera sees the front face, its negation where it sees the back.

    One short ray per valid pixel from just above the surface (``gbuf.normal`` side) back
    onto it gives the geometric normal as wound."""
    from ...scenes.backend.raycast import intersect

    normal = np.asarray(gbuf.normal, dtype=np.float64)
    out = normal.copy()
    idx = np.nonzero(gbuf.valid)[0]
    if not len(idx):
        return out
    p = np.asarray(gbuf.position, dtype=np.float64)[idx]
    n = normal[idx]
    eps = 1e-4 * (1.0 + np.abs(p).max(axis=1))
    hits = intersect(scene, p + n * eps[:, None], -n, tmax=3.0 * eps)
    ng = np.asarray(hits["normal"], dtype=np.float64)
    # The visible side faces the camera: as wound it is the front where ng agrees with n.
    back = hits["valid"] & (np.sum(ng * n, axis=1) < 0.0)
    out[idx[back]] = -n[back]
    return out
