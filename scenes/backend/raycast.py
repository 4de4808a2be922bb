"""Ray queries on a loaded scene: the one intersection engine of oracle and models.

Two levels:

- :func:`trace_film_dr` works on Dr.Jit arrays (the oracle's hot path): primary rays through
  film positions, the hit's G-buffer, the oracle's own shadow ray towards the chosen light and
  the shaded colour. Shadow rays are unbounded for directional lights and end at the light
  for point and spot lights (never Mitsuba's emitter sampling, whose directional emitters
  trust the scene's bounding box).
- :func:`trace_film` and :func:`intersect` take and return NumPy arrays,
  chunked so memory stays bounded; models use these to sample where a technique samples
  (MSAA sample positions, shadow-map texel centres from the light, ...).

**Alpha-tested shapes** (glTF ``MASK``, Mitsuba ``mask`` BSDFs; ``loaded.alpha``): every
query here (primary rays, the hard and area-light shadow rays, :func:`intersect`) passes
through the points their alpha test cuts out (:mod:`.alpha_hit`), so coverage, visibility,
soft visibility and colour see the cut-out surface.

**One Mitsuba scene per Dr.Jit kernel.** Every helper here traces ``loaded.mi_scene`` only
(primary, shadow and self-hit rays of one scene may share a kernel). Code that also traces
another ``mi.Scene`` (a sub-scene of some of the shapes, as ACAA's tie groups) must evaluate
one scene's results before tracing the other (:func:`.kernels.evaluate_trace`): on CUDA,
OptiX disables the second trace in a kernel and it returns no hits, silently.
:func:`.kernels.audit` checks the rule on the CPU.
"""

from __future__ import annotations

import numpy as np

from .. import backend
from ..shading.materials import surface_dr
from ..shading.pbr import shade_gltf
from ..shading.phong import facing, receiver_mask, shade
from .alpha_hit import closest_hit_alpha, loaded_alpha, occluded_alpha

__all__ = [
    "CHUNK",
    "intersect",
    "occluded_segment_dr",
    "shape_table",
    "trace_film",
    "trace_film_dr",
]

#: Rays per Dr.Jit launch in the NumPy-level helpers (bounded memory: ~0.5 GiB a launch).
CHUNK = 1 << 21


def shape_table(mi, dr, loaded):
    """Int32 array mapping Mitsuba shape registry ids to indices into ``loaded.shape_names``."""
    cache = loaded.memo.setdefault("shape_table", {})
    if "table" not in cache:
        shapes = loaded.mi_scene.shapes()
        reg = [int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in shapes]
        table = np.full(max(reg) + 2, -1, dtype=np.int32)
        table[reg] = np.arange(len(shapes), dtype=np.int32)
        cache["table"] = table
    return mi.Int32(cache["table"])


def camera_rays_dr(camera, x, y):
    """Mitsuba ``Ray3f`` through film positions ``x, y`` (Dr.Jit Float), as Mitsuba's sensor."""
    mi = backend.mitsuba()
    import drjit as dr

    (ox, oy, oz), (dx, dy, dz) = camera.local_ray(x, y)
    m = np.asarray(camera.to_world, dtype=np.float64)
    o_local = mi.Point3f(ox, oy, oz)
    d_local = mi.Vector3f(dx, dy, dz)
    # the pose is opaque (a value in memory, not a literal of the kernel): every camera
    # frame then reuses the compiled kernels instead of compiling its own
    r = [[dr.opaque(mi.Float, float(m[i, j])) for j in range(3)] for i in range(3)]
    t = [dr.opaque(mi.Float, float(m[i, 3])) for i in range(3)]
    d = mi.Vector3f(
        r[0][0] * d_local.x + r[0][1] * d_local.y + r[0][2] * d_local.z,
        r[1][0] * d_local.x + r[1][1] * d_local.y + r[1][2] * d_local.z,
        r[2][0] * d_local.x + r[2][1] * d_local.y + r[2][2] * d_local.z,
    )
    o = mi.Point3f(
        r[0][0] * o_local.x + r[0][1] * o_local.y + r[0][2] * o_local.z + t[0],
        r[1][0] * o_local.x + r[1][1] * o_local.y + r[1][2] * o_local.z + t[1],
        r[2][0] * o_local.x + r[2][1] * o_local.y + r[2][2] * o_local.z + t[2],
    )
    length = dr.norm(d)
    d = d / length
    if camera.kind == "perspective":
        scale = length / float(np.linalg.norm(m[:3, 2]))
        o = o + d * (camera.near * scale)
        maxt = (camera.far - camera.near) * scale
    else:
        maxt = dr.full(mi.Float, camera.far - camera.near, dr.width(x))
    return mi.Ray3f(o, d, maxt, 0.0, mi.Color0f())


#: Shadow-ray origins move off the surface by ``offset * (1 + |n|.|p|)`` along the light-side
#: geometric normal: the point's size along its normal bounds the rounding error of a hit
#: point across its surface (a ground plane at y = 0 1e5 units from the origin is exact in y,
#: whatever x and z are, so it gets an offset of 2^-21, not 0.05 units: a 0.08-unit kerb there
#: keeps its shadow). Meshes (hit points interpolated from float32 vertices) use
#: :data:`SHADOW_OFFSET_MESH` (four ulps); analytic shapes (hit points from ``o + t d``, whose
#: error follows the ray origin) use :data:`SHADOW_OFFSET` (sixteen ulps) and skip hits on
#: their own shape when they leave it outwards (:func:`occluded_from_dr`).
SHADOW_OFFSET_MESH = 2.0**-21
SHADOW_OFFSET = 2.0**-19


def _normal_scale(p, ng):
    """``1 + |n|.|p|``: the size of ``p`` along the normal, which bounds the rounding error
    of a hit point across its surface (PBRT's error bounds are per component: a ground plane
    at y = 0 1e5 units from the origin is exact in y, whatever x and z are)."""
    import drjit as dr

    return 1.0 + dr.dot(dr.abs(ng), dr.abs(p))


def shadow_ray_dr(light, p, ng, wl, offset=SHADOW_OFFSET):
    """The oracle's shadow ray from surface points ``p`` (geometric normal ``ng``) towards
    ``light``: unbounded for a directional light, ending just short of a point or spot light.
    The origin moves ``offset * (1 + |n|.|p|)`` along the light-side normal (``offset``: a
    float or a Dr.Jit ``Float`` per ray)."""
    mi = backend.mitsuba()
    import drjit as dr

    side = dr.select(dr.dot(ng, wl) >= 0.0, 1.0, -1.0)
    origin = p + ng * (side * _normal_scale(p, ng) * offset)
    if light.is_directional:
        return mi.Ray3f(origin, wl)
    to = mi.Point3f(*[float(c) for c in light.position]) - origin
    dist = dr.norm(to)
    # a sphere light's centre lies inside it: the ray stops at its surface (shadow_end)
    end = dist - light.shadow_end if light.shadow_end else dist
    return mi.Ray3f(origin, to / dist, end * (1.0 - 1e-5), 0.0, mi.Color0f())


#: Rounds of "skip a spurious hit on the ray's own analytic shape" (one is enough in practice:
#: the resumed ray starts on the far side of the spurious hit).
SELF_HIT_ROUNDS = 3


def _test(scene, ray, active, alpha, bound=None):
    """``scene.ray_test``, through alpha-tested surfaces when ``alpha`` (an
    :class:`.alpha_hit.AlphaScene`) is given; ``bound`` (a list): gets the rays that stopped
    at the layer bound (Bool)."""
    if alpha is None:
        return scene.ray_test(ray, active)
    blocked, exhausted = occluded_alpha(scene, ray, alpha, active=active)
    if bound is not None:
        bound.append(exhausted)
    return blocked


def _closest(scene, ray, flags, coherent, active, alpha, bound=None):
    """``scene.ray_intersect``: the closest hit kept by the alpha test when ``alpha`` is
    given (:func:`.alpha_hit.closest_hit_alpha`); ``bound`` as for :func:`_test`."""
    if alpha is None:
        return scene.ray_intersect(ray, flags, coherent, active)
    si, _, exhausted = closest_hit_alpha(
        scene, ray, alpha, flags=flags, coherent=coherent, active=active
    )
    if bound is not None:
        bound.append(exhausted)
    return si


def _has_analytic_shapes(scene) -> bool:
    """Whether ``scene`` (a Mitsuba scene) holds a non-mesh (analytic) shape."""
    return any(not sh.is_mesh() for sh in scene.shapes())


def occluded_from_dr(scene, light, p, ng, wl, shape, active, *, alpha=None, bound=None):
    """True where the light is blocked from surface points ``p`` (geometric normal ``ng``,
    hit shape ``shape``: a Mitsuba ``ShapePtr``) in direction ``wl`` (Dr.Jit).

    One ``ray_test`` from the offset origin (:data:`SHADOW_OFFSET_MESH` for meshes,
    :data:`SHADOW_OFFSET` for analytic shapes). Analytic shapes (sphere, cylinder, disk,
    rectangle) are convex or flat with outward normals, so a ray leaving one on its outward
    side cannot meet it again: for those rays a hit on their own shape is rounding error
    (Mitsuba's cylinder intersection is less accurate than the offset: 30 % of the lit side
    of the `curved` scene's cylinder read as shadowed with the offset alone), and is skipped
    by resuming the ray from that hit. Rays leaving an analytic shape on its inner side
    (inside a sphere or tube) keep the plain test: the far wall may shadow them. With
    ``alpha`` (:func:`.alpha_hit.loaded_alpha`), alpha-tested surfaces block only where
    their alpha test keeps the point; ``bound`` (a list) then gets, per query, the rays that
    stopped at the layer bound (:data:`.alpha_hit.MAX_ALPHA_LAYERS`).
    """
    mi = backend.mitsuba()
    import drjit as dr

    mesh = shape.is_mesh()
    offset = dr.select(mesh, SHADOW_OFFSET_MESH, SHADOW_OFFSET)
    ray = shadow_ray_dr(light, p, ng, wl, offset)
    if not _has_analytic_shapes(scene):
        return _test(scene, ray, active, alpha, bound)
    pending = active & ~mesh & (dr.dot(ng, wl) > 0.0)
    blocked = _test(scene, ray, active & ~pending, alpha, bound)
    for _ in range(SELF_HIT_ROUNDS):
        si = _closest(scene, ray, mi.RayFlags.Minimal, False, pending, alpha, bound)
        hit = pending & si.is_valid()
        own = hit & (si.shape == shape)
        blocked |= hit & ~own
        pending = own
        ray = shadow_ray_dr(light, dr.select(own, si.p, ray.o), ng, wl, offset)
    return blocked


def occluded_segment_dr(
    scene, p, ng, shape, wl, dist, active, light_shape=None, recheck=None, *, alpha=None
):
    """True where the segment from surface points ``p`` (geometric normal ``ng``, hit shape
    ``shape``) along unit directions ``wl`` to the points ``p + wl * dist`` (on an area
    light) is blocked (Dr.Jit).

    The rays of :func:`occluded_from_dr` towards arbitrary end points: the same origin offset
    and the same skipping of spurious hits on the ray's own analytic shape; each ray ends just
    short of its end point (measured from its offset origin). With ``light_shape`` (the
    light's own Mitsuba shape), the blocked rays of ``recheck`` (all rays when None) find
    their closest hit again and a hit on the light ends them unblocked: near a sphere light's
    silhouette the end point's rounding error exceeds any margin (the ray grazes the sphere),
    so a margin alone would let the light shadow itself. The rays that need closest hits run
    in a symbolic loop (one intersection for most, a second after a spurious hit), not
    :data:`SELF_HIT_ROUNDS` unrolled intersections of every ray (which tripled the cost of an
    area light's samples). ``alpha``: as in :func:`occluded_from_dr`.
    """
    mi = backend.mitsuba()
    import drjit as dr

    mesh = shape.is_mesh()
    offset = dr.select(mesh, SHADOW_OFFSET_MESH, SHADOW_OFFSET)
    target = p + wl * dist
    side = dr.select(dr.dot(ng, wl) >= 0.0, 1.0, -1.0)
    outward = ~mesh & (dr.dot(ng, wl) > 0.0)

    def ray_from(q):
        origin = q + ng * (side * _normal_scale(q, ng) * offset)
        to = target - origin
        length = dr.norm(to)
        return mi.Ray3f(origin, to / length, length * (1.0 - 1e-5), 0.0, mi.Color0f())

    if light_shape is None and not _has_analytic_shapes(scene):
        return _test(scene, ray_from(p), active, alpha)
    pending = active & outward
    blocked = _test(scene, ray_from(p), active & ~pending, alpha)
    if light_shape is not None:  # blocked, perhaps by the light itself: look again
        light_ptr = mi.ShapePtr(light_shape)
        again = mi.Bool(blocked) if recheck is None else blocked & recheck
        blocked = blocked & ~again  # not in place: ``again`` may share its storage
        pending = pending | again

    def body(q, blocked, pending, rounds):
        si = _closest(scene, ray_from(q), mi.RayFlags.Minimal, False, pending, alpha)
        hit = pending & si.is_valid()
        if light_shape is not None:
            hit &= si.shape != light_ptr
        own = hit & (si.shape == shape) & outward  # a spurious hit on its own analytic shape
        return dr.select(own, si.p, q), blocked | (hit & ~own), own, rounds + 1

    _, blocked, _, _ = dr.while_loop(
        state=(mi.Point3f(p), blocked, pending, dr.zeros(mi.UInt32, dr.width(pending))),
        cond=lambda q, blocked, pending, rounds: pending & (rounds < SELF_HIT_ROUNDS),
        body=body,
        labels=("q", "blocked", "pending", "rounds"),
    )
    return blocked


def shadow_occluded_dr(scene, light, si, wl, active, *, alpha=None, bound=None):
    """True where the light is blocked from the surface interaction ``si`` (Dr.Jit): see
    :func:`occluded_from_dr`."""
    return occluded_from_dr(
        scene, light, si.p, si.n, wl, si.shape, active, alpha=alpha, bound=bound
    )


def primary_flags(mi):
    """Surface data the primary hits of :func:`trace_film_dr` compute: UV (textured albedo)
    and the shading frame, not the position derivatives (``RayFlags.All`` less dPdUV), which
    nothing here reads; every output is the same bytes as with ``All`` (checked on city, thin,
    curved, plate, decal and foliage) and the colour reference is about 1 % faster."""
    return mi.RayFlags.UV | mi.RayFlags.ShadingFrame


def trace_film_dr(
    loaded, x, y, *, color: bool = True, camera=None, albedo: bool = True, keep_si: bool = False
):
    """Trace primary and shadow rays through film positions (Dr.Jit ``Float`` pixels).

    Returns a dict of Dr.Jit arrays: ``valid`` (hit geometry), ``lit`` (sees the light; True
    for sky), ``shape`` (Int32 shape index, -1 sky), ``depth`` (view depth, 0 sky),
    ``prim`` (Int32 primitive index within its shape: a mesh's face, -1 sky),
    ``position``, ``normal`` (facing the viewer), ``albedo`` (unless ``albedo`` and
    ``color`` are both False: tracing the BSDF call costs Python time on every launch even
    when nothing reads it) and, with ``color``, ``color`` (shaded linear RGB, 0 for sky).
    With ``keep_si``, also ``si`` (the primary hits' ``SurfaceInteraction3f``) and ``to_eye``
    (what an area light's samples start from, :mod:`oracle.reference.soft`). On a scene with
    alpha-tested shapes, also ``alpha_bound``: the sample's camera and shadow rays that
    stopped at the layer bound (Float, 0 or more).
    """
    mi = backend.mitsuba()
    import drjit as dr

    camera = camera or loaded.camera
    scene = loaded.mi_scene
    light = loaded.light
    ray = camera_rays_dr(camera, x, y)
    pbr = (
        loaded.pbr
    )  # glTF scenes: materials of scenes.shading.materials, BRDF of scenes.shading.pbr
    flags = primary_flags(mi)
    if pbr is not None and pbr.has_normal_textures:
        flags = mi.RayFlags.All  # dp/du: the normal texture's fallback tangent
    alpha = loaded_alpha(loaded)  # alpha-tested shapes (glTF MASK): cut out for every ray
    bound = []  # rays stopped at the layer bound (alpha-tested scenes)
    si = _closest(scene, ray, flags, True, True, alpha, bound)
    valid = si.is_valid()
    to_eye = -ray.d
    n = facing(si.sh_frame.n, to_eye)
    wl, dist = light.to_light(si.p)
    cos_l = dr.dot(n, wl)
    candidate = receiver_mask(valid=valid, cos_l=cos_l, to_light=wl, light=light)
    occluded_ = shadow_occluded_dr(scene, light, si, wl, candidate, alpha=alpha, bound=bound)
    lit = dr.select(valid, candidate & ~occluded_, True)
    fwd = [dr.opaque(mi.Float, float(c)) for c in camera.forward]  # opaque: kernel reuse
    pos = [dr.opaque(mi.Float, float(c)) for c in camera.position]
    depth = dr.select(
        valid,
        (si.p.x - pos[0]) * fwd[0] + (si.p.y - pos[1]) * fwd[1] + (si.p.z - pos[2]) * fwd[2],
        0.0,
    )
    shape_index = dr.gather(
        mi.Int32, shape_table(mi, dr, loaded), dr.reinterpret_array(mi.UInt32, si.shape)
    )
    shape_index = dr.select(valid, shape_index, -1)
    out = {
        "valid": valid,
        "lit": lit,
        "shape": shape_index,
        "prim": dr.select(valid, mi.Int32(si.prim_index), -1),
        "depth": depth,
        "position": si.p,
        "normal": n,
        "cos_l": cos_l,
        "shadow_tested": candidate,
    }
    if bound:
        out["alpha_bound"] = sum(dr.select(b, 1.0, 0.0) for b in bound)
    if keep_si:
        out["si"], out["to_eye"] = si, to_eye
    if pbr is not None and (albedo or color):
        mat = surface_dr(pbr, si, shape_index, n, to_eye, valid)
        out["albedo"] = dr.select(valid, mat["base_color"], 0.0)
    elif albedo or color:
        bsdf = si.bsdf(ray)
        out["albedo"] = dr.select(valid, bsdf.eval_diffuse_reflectance(si, valid), 0.0)
    if color and pbr is not None:
        vis = dr.select(lit & valid, 1.0, 0.0)
        rgb = shade_gltf(
            base_color=mat["base_color"],
            metallic=mat["metallic"],
            roughness=mat["roughness"],
            emissive=mat["emissive"],
            normal=mat["normal"],
            to_light=wl,
            to_eye=to_eye,
            irradiance_scale=light.irradiance_scale(wl, dist),
            visibility=vis,
            light=light,
        )
        out["color"] = dr.select(valid, rgb, 0.0)
    elif color:
        vis = dr.select(lit & valid, 1.0, 0.0)
        rgb = shade(
            albedo=out["albedo"],
            normal=n,
            to_light=wl,
            to_eye=to_eye,
            irradiance_scale=light.irradiance_scale(wl, dist),
            visibility=vis,
            light=light,
            specular=loaded.specular,
        )
        out["color"] = dr.select(valid, rgb, 0.0)
    return out


def trace_film(loaded, x: np.ndarray, y: np.ndarray, *, camera=None, color: bool = False):
    """NumPy G-buffer at film positions ``x, y`` (pixels), chunked.

    Returns a dict of NumPy arrays of ``len(x)``: ``valid`` (bool), ``lit`` (bool), ``shape``
    (int32), ``depth`` (float32), ``position``/``normal``/``albedo`` ((N, 3) float32),
    ``cos_l`` and, with ``color``, ``color`` ((N, 3) float32).
    """
    mi = backend.mitsuba()
    x = np.asarray(x, dtype=np.float32).ravel()
    y = np.asarray(y, dtype=np.float32).ravel()
    parts: dict[str, list] = {}
    for start in range(0, len(x), CHUNK):
        sl = slice(start, start + CHUNK)
        res = trace_film_dr(loaded, mi.Float(x[sl]), mi.Float(y[sl]), color=color, camera=camera)
        for k, v in res.items():
            arr = np.array(v)
            if arr.ndim == 2 and arr.shape[0] == 3:
                arr = arr.T
            parts.setdefault(k, []).append(arr)
    if not parts:
        return {}
    return {k: np.concatenate(v) for k, v in parts.items()}


def intersect(loaded, origins: np.ndarray, directions: np.ndarray, *, tmax=None):
    """Closest hits of arbitrary rays (NumPy ``(N, 3)``), chunked.

    Returns ``valid`` (bool), ``t`` (float32, inf on miss), ``position`` and geometric
    ``normal`` ((N, 3) float32), ``shape`` (int32, -1 on miss).
    """
    mi = backend.mitsuba()
    import drjit as dr

    o = np.asarray(origins, dtype=np.float32).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
    tm = None if tmax is None else np.broadcast_to(np.asarray(tmax, np.float32), (len(o),))
    table = shape_table(mi, dr, loaded)
    alpha = loaded_alpha(loaded)
    out: dict[str, list] = {"valid": [], "t": [], "position": [], "normal": [], "shape": []}
    for start in range(0, len(o), CHUNK):
        sl = slice(start, start + CHUNK)
        ray = mi.Ray3f(
            mi.Point3f(*(mi.Float(o[sl, i]) for i in range(3))),
            mi.Vector3f(*(mi.Float(d[sl, i]) for i in range(3))),
        )
        if tm is not None:
            ray.maxt = mi.Float(np.ascontiguousarray(tm[sl]))
        si = _closest(loaded.mi_scene, ray, mi.RayFlags.All, False, True, alpha)
        valid = si.is_valid()
        shape = dr.select(
            valid, dr.gather(mi.Int32, table, dr.reinterpret_array(mi.UInt32, si.shape)), -1
        )
        out["valid"].append(np.array(valid))
        out["t"].append(np.where(np.array(valid), np.array(si.t), np.inf).astype(np.float32))
        out["position"].append(np.array(si.p).T)
        out["normal"].append(np.array(si.n).T)
        out["shape"].append(np.array(shape))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
