"""Ray work of the anti-aliasing models: sample G-buffers, fragment attributes, shading.

Three Dr.Jit kernels, each chunked (at most :data:`CHUNK` rays a launch), on the scene's own
intersection engine (``scenes.backend.raycast``; ARCHITECTURE.md "One intersection engine"):

- :func:`trace_samples`: one primary ray through every sub-sample position of every pixel
  (the depth prepass of MSAA/ACAA/AGAA): hit or sky, shape and primitive, view depth and,
  on request, the geometric normal;
- :func:`fragment_attributes`: for a fragment (a primitive in a pixel) given by one of its
  samples, the attributes a pixel shader sees at the shading position (pixel centre or
  centroid): the position where the ray through that position meets the *triangle's plane*
  and the surface parameters extrapolated linearly from the sample's hit (``uv``, shading
  normal), as a rasterizer's attribute interpolation does beyond a triangle's edge; the
  albedo is evaluated at the extrapolated ``uv``;
- :func:`shade_points`: the oracle's shading (:func:`scenes.shading.phong.shade`) at those points,
  with an exact shadow ray from each (:func:`scenes.backend.raycast.shadow_ray_dr`, the oracle's own
  offsets) or with a given visibility, and optionally an unnormalized (filtered) normal:
  diffuse with the normal's length as a factor (the linear average of Lambert terms) and the
  specular exponent scaled by Toksvig's factor.

Values are float32 (Mitsuba's ``Float``), as a GPU computes them. The Dr.Jit side of each
(:func:`prepass_dr`, :func:`attributes_dr`, :func:`shade_dr`) is also callable on Dr.Jit
arrays, for models that chain them without NumPy round trips (:mod:`.agaa.kernels`,
:mod:`.acaa.trace`). ``target`` (a sub-scene) and ``scene.mi_scene`` are different Mitsuba
scenes: evaluate what one traced (``scenes.backend.kernels.evaluate_trace``) before the other
traces (one scene per kernel; OptiX silently disables the second trace).
"""

from __future__ import annotations

import math

import numpy as np

from ...scenes import backend
from ...scenes.backend.alpha_hit import loaded_alpha, occluded_alpha, scene_hit
from ...scenes.backend.raycast import (
    SHADOW_OFFSET,
    SHADOW_OFFSET_MESH,
    camera_rays_dr,
    shadow_ray_dr,
    shape_table,
)
from ...scenes.shading.materials import surface_dr
from ...scenes.shading.pbr import shade_gltf
from ...scenes.shading.phong import facing, receiver_mask, shade
from ..drjit import aligned, numpy_view
from . import pixel_dr as _pixel_dr

__all__ = [
    "CHUNK",
    "attributes_dr",
    "fragment_attributes",
    "prepass_dr",
    "sample_colors",
    "sample_points_dr",
    "sample_visibility_dr",
    "shade_dr",
    "shade_points",
    "to_numpy",
    "trace_samples",
    "view_depth",
]

#: Rays per Dr.Jit launch (bounded memory; ~0.5 GiB a launch at most).
CHUNK = 1 << 21


def to_numpy(a) -> np.ndarray:
    """NumPy view of an evaluated Dr.Jit array (a vector gives ``(3, N)``); every caller
    copies it into its own output at once."""
    return numpy_view(a)  # a vector component by component: no packing kernel per length


def view_depth(camera, p):
    """View depth (distance along the camera's forward axis, camera units) of Dr.Jit
    points ``p``, in float32. The camera's pose is opaque: every frame reuses the kernel."""
    mi = backend.mitsuba()
    import drjit as dr

    fwd = [dr.opaque(mi.Float, float(c)) for c in camera.forward]
    pos = [dr.opaque(mi.Float, float(c)) for c in camera.position]
    return (p.x - pos[0]) * fwd[0] + (p.y - pos[1]) * fwd[1] + (p.z - pos[2]) * fwd[2]


def trace_samples(
    scene,
    offsets: np.ndarray,
    *,
    normals: bool = False,
    group: bool = False,
    keep: tuple = ("valid", "shape", "prim", "depth", "first"),
) -> dict:
    """Nearest surface at every sub-sample of every pixel (a depth prepass).

    Parameters
    ----------
    scene : scenes.LoadedScene
    offsets : ``(N, 2)`` sample positions in the pixel (y down, see :mod:`.samples`).
    normals : also return the geometric normal turned towards the viewer.
    group : also return ``first`` ((P, N) int8): the first sample of the pixel with the same
        (shape, primitive), ``N`` for sky (:func:`.pixel_dr.first_of_key`), and the fragment
        bookkeeping of :func:`.pixel_dr.fragments_of` (``rep``, ``of``, ``count``).
    keep : which of ``valid``, ``shape``, ``prim``, ``depth`` (and with ``group``,
        ``first``) to copy back to NumPy (the per-pixel kernels read them on the Dr.Jit side
        either way).

    Returns
    -------
    dict of ``(P, N)`` arrays: ``valid`` (bool), ``shape`` (int32, index into
    ``scene.shape_names``, -1 sky), ``prim`` (int64, -1 sky), ``depth`` (float32 view
    depth, 0 sky) and with ``normals`` ``normal`` ``(P, N, 3)``; with ``group`` the
    fragment bookkeeping.
    """
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    offs = np.asarray(offsets, dtype=np.float32).reshape(-1, 2)
    n = len(offs)
    n_pix = cam.width * cam.height
    total = n_pix * n
    dtypes = {"valid": bool, "shape": np.int32, "prim": np.int64, "depth": np.float32}
    out = {key: np.empty(total, dtypes[key]) for key in keep if key in dtypes}
    if normals:
        out["normal"] = np.empty((total, 3), np.float32)
    if group:
        if "first" in keep:
            out["first"] = np.empty(total, np.int8)
        out["rep"] = np.empty(total, bool)
        out["of"] = np.empty(total, np.int32)
        out["count"] = np.empty(total, np.int8)
    n_frag = 0
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    table = shape_table(mi, dr, scene)
    step = max(n, (CHUNK // n) * n)
    for start in range(0, total, step):
        stop = min(total, start + step)
        # an opaque offset: one kernel for every launch, not one per start
        pix = dr.arange(mi.UInt32, (stop - start) // n) + dr.opaque(mi.UInt32, start // n)
        valid, depth, prim, shape, nrm, extra = prepass_dr(
            scene,
            scene.mi_scene,
            table,
            ox,
            oy,
            pix,
            n,
            normals=normals,
            group=group,
            frag_offset=n_frag,
        )
        del extra["local"], extra["s"]
        sl = slice(start, stop)
        if "valid" in out or "prim" in out:
            v = to_numpy(valid)
        if "valid" in out:
            out["valid"][sl] = v
        if "depth" in out:
            out["depth"][sl] = to_numpy(depth)
        if "shape" in out:
            out["shape"][sl] = to_numpy(shape)
        if "prim" in out:
            out["prim"][sl] = np.where(v, to_numpy(prim).astype(np.int64), -1)
        if normals:
            out["normal"][sl] = to_numpy(nrm).T
        for key, val in extra.items():
            if key in out:
                out[key][sl] = to_numpy(val)
        if group:
            n_frag += int(np.count_nonzero(out["rep"][sl]))
    res = {k: v.reshape((n_pix, n) + v.shape[1:]) for k, v in out.items()}
    return res


def prepass_dr(scene, target, table, ox, oy, pix, n: int, *, normals, group, frag_offset=0):
    """One launch of the prepass on the Dr.Jit side: ``n`` lanes a pixel, pixel ``i`` of the
    launch being ``pix[i]`` (UInt32, row-major); ``ox``, ``oy`` the sample offsets (Float);
    ``target`` the Mitsuba scene intersected, ``table`` :func:`scenes.backend.raycast.shape_table`.

    Returns ``(valid, depth, prim, shape, nrm, extra)``: Dr.Jit arrays as described in
    :func:`trace_samples` (``nrm`` None unless ``normals``), ``extra`` the per-pixel results
    of ``group`` (fragment ids from ``frag_offset``), all evaluated; ``extra`` also holds
    ``local`` and ``s`` (each lane's pixel within the launch and sample slot) unevaluated.
    """
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    w = cam.width
    idx = dr.arange(mi.UInt32, dr.width(pix) * n)
    local = idx // n
    s = idx - local * n
    pix = dr.gather(mi.UInt32, pix, local)
    x = mi.Float(pix % w) + dr.gather(mi.Float, ox, s)
    y = mi.Float(pix // w) + dr.gather(mi.Float, oy, s)
    ray = camera_rays_dr(cam, x, y)
    nrm = None
    cut = target is scene.mi_scene and loaded_alpha(scene) is not None  # glTF MASK
    if normals or cut:
        si = scene_hit(scene, target, ray, mi.RayFlags.Minimal)
        valid, t, prim, shape_ptr = si.is_valid(), si.t, si.prim_index, si.shape
        if normals:
            nrm = dr.select(valid, facing(si.n, -ray.d), mi.Vector3f(0.0))
    else:
        pi = target.ray_intersect_preliminary(ray, coherent=True)
        valid, t, prim, shape_ptr = pi.is_valid(), pi.t, pi.prim_index, pi.shape
    depth = dr.select(valid, view_depth(cam, ray.o + ray.d * t), 0.0)
    # masked: a preliminary intersection leaves the shape of a miss undefined
    ids = dr.select(valid, dr.reinterpret_array(mi.UInt32, shape_ptr), 0)
    shape = dr.select(valid, dr.gather(mi.Int32, table, ids, valid), -1)
    extra = {}
    if group:
        # one tracing kernel; the per-pixel kernels then gather from stored arrays
        dr.eval(valid, depth, prim, shape)
        per_slot = _pixel_dr.first_of_key(
            mi,
            dr,
            _pixel_dr.slots(mi, dr, mi.Bool, valid, n),
            _pixel_dr.slots(mi, dr, mi.Int32, shape, n),
            _pixel_dr.slots(mi, dr, mi.UInt32, prim, n),
        )
        extra["first"] = _pixel_dr.to_sample_lanes(mi, dr, per_slot)
        extra.update(
            _pixel_dr.fragments_of(
                mi, dr, valid, extra["first"], local, n, s, dr.opaque(mi.UInt32, frag_offset)
            )
        )
    dr.eval(valid, depth, prim, shape, *([nrm] if nrm is not None else []), *extra.values())
    extra["local"], extra["s"] = local, s
    return valid, depth, prim, shape, nrm, extra


#: The (F, 3) attributes of :func:`fragment_attributes`.
_VECTOR_ATTRIBUTES = ("position", "normal", "geo_normal", "albedo", "to_eye")
#: The further (F, 3) attributes on a glTF scene: (metallic, roughness, 0) and emissive.
_PBR_ATTRIBUTES = ("material", "emissive")


def _vector_keys(scene) -> tuple[str, ...]:
    return _VECTOR_ATTRIBUTES + (_PBR_ATTRIBUTES if scene.pbr is not None else ())


def fragment_attributes(scene, sx, sy, cx, cy, *, mi_scene=None) -> dict:
    """What a pixel shader sees for fragments given by one covered sample each.

    Parameters
    ----------
    sx, sy : film positions of a sample the fragment covers (its primitive is found again by
        the ray through it; ``mi_scene`` restricts the search to one shape, for fragments
        that are not the nearest surface there).
    cx, cy : film positions where the fragment is shaded (pixel centre, or centroid).

    Returns
    -------
    dict of NumPy arrays (F rows): ``valid``, ``position`` (on the primitive's plane, under
    ``(cx, cy)``), ``normal`` (shading normal extrapolated to that point, unit, facing the
    viewer), ``geo_normal``, ``albedo``, ``to_eye``, ``offset`` (the oracle's shadow-ray
    offset for the shape type), ``depth`` (view depth of ``position``); ``float32``. On a glTF
    scene also ``material`` ((metallic, roughness, 0)) and ``emissive``, evaluated at the
    extrapolated ``uv``, ``albedo`` is the base colour and ``normal`` is bent by the normal
    texture.
    """
    mi = backend.mitsuba()
    import drjit as dr

    target = mi_scene if mi_scene is not None else scene.mi_scene
    sx, sy, cx, cy = (np.asarray(a, np.float32).ravel() for a in (sx, sy, cx, cy))
    total = len(sx)
    out = {
        "valid": np.zeros(total, bool),
        "depth": np.zeros(total, np.float32),
        "offset": np.zeros(total, np.float32),
    }
    # Vectors are (F, 3) views of planar (3, F) storage: Dr.Jit's own layout, so neither the
    # copy out of Dr.Jit nor :func:`shade_points`' copy back in interleaves or gathers.
    planar = {k: np.zeros((3, total), np.float32) for k in _vector_keys(scene)}
    for start in range(0, total, CHUNK):
        sl = slice(start, min(total, start + CHUNK))
        vals = attributes_dr(scene, target, *(mi.Float(a[sl]) for a in (sx, sy, cx, cy)))
        valid = vals["valid"]
        dr.eval(*vals.values())
        v = to_numpy(valid)
        for key, val in vals.items():
            arr = to_numpy(val)
            if key in planar:
                planar[key][:, sl] = np.where(v, arr, 0)
            elif key == "valid":
                out[key][sl] = arr
            else:
                out[key][sl] = np.where(v, arr, 0)
    out.update({k: a.T for k, a in planar.items()})
    return out


def attributes_dr(scene, target, sx, sy, cx, cy) -> dict:
    """The Dr.Jit side of :func:`fragment_attributes` for film positions given as Float
    arrays; the values are unevaluated and not zeroed where ``valid`` is false."""
    mi = backend.mitsuba()
    import drjit as dr

    cam = scene.camera
    ray_s = camera_rays_dr(cam, sx, sy)
    si = scene_hit(scene, target, ray_s, mi.RayFlags.All)
    valid = si.is_valid()
    ray_c = camera_rays_dr(cam, cx, cy)
    ng = si.n
    den = dr.dot(ng, ray_c.d)
    ok = dr.abs(den) > 1e-12
    tc = dr.dot(ng, si.p - ray_c.o) / dr.select(ok, den, 1.0)
    xc = dr.select(ok, ray_c.o + ray_c.d * tc, si.p)
    # ``o + t d`` carries the rounding error of the ray's origin and length (several times
    # the mesh shadow offset, which is scaled by |p|: a tilted wall shadowed itself). One
    # step back onto the plane by the point's own measured distance leaves an error of the
    # order of |p|'s ulps, which the mesh offset covers, as it does for the hit itself.
    xc = xc + ng * dr.dot(ng, si.p - xc)
    delta = xc - si.p
    a11, a12, a22 = (
        dr.dot(si.dp_du, si.dp_du),
        dr.dot(si.dp_du, si.dp_dv),
        dr.dot(si.dp_dv, si.dp_dv),
    )
    b1, b2 = dr.dot(delta, si.dp_du), dr.dot(delta, si.dp_dv)
    det = a11 * a22 - a12 * a12
    good = det > 1e-12 * a11 * a22
    inv = dr.select(good, 1.0 / det, 0.0)
    du = (a22 * b1 - a12 * b2) * inv
    dv = (a11 * b2 - a12 * b1) * inv
    ns = dr.normalize(si.sh_frame.n + si.dn_du * du + si.dn_dv * dv)
    to_eye = -ray_c.d
    ns = facing(ns, to_eye)
    si.uv = si.uv + mi.Point2f(du, dv)
    si.p = xc
    pbr_vals = {}
    if scene.pbr is not None:  # glTF material at the extrapolated uv (scenes.shading.materials)
        shape = dr.gather(
            mi.Int32, shape_table(mi, dr, scene), dr.reinterpret_array(mi.UInt32, si.shape)
        )
        mat = surface_dr(scene.pbr, si, shape, ns, to_eye, valid)
        albedo, ns = dr.select(valid, mat["base_color"], 0.0), mat["normal"]
        pbr_vals = {
            "material": mi.Vector3f(mat["metallic"], mat["roughness"], 0.0),
            "emissive": mi.Vector3f(mat["emissive"].x, mat["emissive"].y, mat["emissive"].z),
        }
    else:
        bsdf = si.bsdf(ray_s)
        albedo = dr.select(valid, bsdf.eval_diffuse_reflectance(si, valid), 0.0)
    offset = dr.select(si.shape.is_mesh(), SHADOW_OFFSET_MESH, SHADOW_OFFSET)
    depth = view_depth(cam, xc)
    vals = {
        "valid": valid,
        "position": xc,
        "normal": ns,
        "geo_normal": facing(ng, to_eye),
        "albedo": albedo,
        "to_eye": to_eye,
        "offset": offset,
        "depth": depth,
        **pbr_vals,
    }
    return vals


def shade_points(scene, attrs: dict, *, visibility=None, filtered_normal: bool = False):
    """Shade surface points with the oracle's model (:func:`scenes.shading.phong.shade`).

    Parameters
    ----------
    attrs : ``position``, ``normal``, ``geo_normal``, ``albedo``, ``to_eye``, ``offset``
        ``(F, ...)`` arrays (as from :func:`fragment_attributes`); ``valid`` rows only shaded.
    visibility : ``(F,)`` light visibility in [0, 1] from a shadow technique; default: one
        exact shadow ray from each point (the oracle's ray, offsets and light tests).
    filtered_normal : ``normal`` is an average of unit normals (length <= 1): the diffuse
        term uses it unnormalized (the average of the fragments' Lambert terms where they
        all face the light) and the specular exponent ``s`` becomes ``ft * s`` with
        Toksvig's ``ft = |n| / (|n| + s (1 - |n|))``.

    Returns
    -------
    rgb : ``(F, 3)`` float32 linear radiance (0 where not valid).
    shadow_rays : number of shadow rays cast.
    """
    mi = backend.mitsuba()
    import drjit as dr

    total = len(attrs["position"])
    rgb_out = np.zeros((total, 3), np.float32)
    rays = 0
    valid_all = np.asarray(attrs.get("valid", np.ones(total, bool)), bool)

    def vec(key, sl):
        a = np.asarray(attrs[key][sl], np.float32)
        return mi.Vector3f(*(mi.Float(aligned(a[:, i])) for i in range(3)))

    for start in range(0, total, CHUNK):
        sl = slice(start, min(total, start + CHUNK))
        valid = mi.Bool(aligned(valid_all[sl], bool))  # aligned: one kernel, any address
        p = mi.Point3f(vec("position", sl))
        n = vec("normal", sl)
        ng = vec("geo_normal", sl)
        albedo = mi.Color3f(vec("albedo", sl))
        to_eye = vec("to_eye", sl)
        offset = vis = None
        if visibility is None:
            offset = mi.Float(aligned(attrs["offset"][sl]))
        else:
            vis = mi.Float(aligned(visibility[sl]))
        pbr = {}
        if scene.pbr is not None and "material" in attrs:
            pbr = {"material": vec("material", sl), "emissive": mi.Color3f(vec("emissive", sl))}
        rgb, candidate = shade_dr(
            scene,
            valid,
            p,
            n,
            ng,
            albedo,
            to_eye,
            offset=offset,
            visibility=vis,
            filtered_normal=filtered_normal,
            **pbr,
        )
        count = dr.count(candidate) if visibility is None else None
        if count is not None:
            dr.eval(rgb, count)
            rays += int(count[0])
        else:
            dr.eval(rgb)
        rgb_out[sl] = to_numpy(rgb).T
    return rgb_out, rays


def shade_dr(
    scene,
    valid,
    p,
    n,
    ng,
    albedo,
    to_eye,
    *,
    offset=None,
    visibility=None,
    filtered_normal: bool = False,
    material=None,
    emissive=None,
):
    """The Dr.Jit side of :func:`shade_points` on Dr.Jit arrays (``offset`` for the exact
    shadow ray when ``visibility`` is None). Returns ``(rgb, candidate)``: the Color3f
    radiance (0 where not ``valid``) and the lanes given a shadow test (unevaluated).

    On a glTF scene, ``material`` ((metallic, roughness, 0), Vector3f) and ``emissive``
    (Color3f) select the glTF BRDF (:func:`scenes.shading.pbr.shade_gltf`) with ``albedo`` as the
    base colour; a filtered normal is then used normalized (its length scales the result,
    the linear average of the fragments' cosine terms where they all face the light)."""
    mi = backend.mitsuba()
    import drjit as dr

    light = scene.light
    spec = scene.specular
    wl, dist = light.to_light(p)
    if filtered_normal:
        length = dr.norm(n)
        nh = n / dr.maximum(length, 1e-30)
    else:
        length, nh = mi.Float(1.0), n
    cos_l = dr.dot(nh, wl)
    candidate = receiver_mask(valid=valid, cos_l=cos_l, to_light=wl, light=light)
    if visibility is None:
        ray = shadow_ray_dr(light, p, ng, wl, offset)
        occ, _ = occluded_alpha(scene.mi_scene, ray, loaded_alpha(scene), active=candidate)
        vis = dr.select(candidate & ~occ, 1.0, 0.0)
    else:
        vis = dr.select(candidate, visibility, 0.0)
    irr = light.irradiance_scale(wl, dist)
    if scene.pbr is not None and material is not None:
        rgb = shade_gltf(
            base_color=albedo,
            metallic=material.x,
            roughness=material.y,
            emissive=mi.Color3f(0.0),
            normal=nh,
            to_light=wl,
            to_eye=to_eye,
            irradiance_scale=irr * length if filtered_normal else irr,
            visibility=vis,
            light=light,
        )
        return dr.select(valid, rgb + emissive, 0.0), candidate
    rgb = shade(
        albedo=albedo * length if filtered_normal else albedo,
        normal=nh,
        to_light=wl,
        to_eye=to_eye,
        irradiance_scale=irr,
        visibility=vis,
        light=light,
        specular=None if filtered_normal else spec,
    )
    if filtered_normal and spec is not None and spec.ks > 0.0:
        s = spec.shininess
        ft = length / (length + s * (1.0 - length))
        s_eff = ft * s
        h = dr.normalize(wl + to_eye)
        cos_h = dr.maximum(dr.dot(nh, h), 0.0)
        lobe = spec.ks * (s_eff + 8.0) / (8.0 * math.pi) * dr.power(cos_h, s_eff)
        rgb = rgb + mi.Color3f(*light.color) * (lobe * irr * dr.maximum(cos_l, 0) * vis)
    rgb = dr.select(valid, rgb, 0.0)
    return rgb, candidate


def sample_visibility_dr(scene, x, y):
    """The oracle's light visibility at the surface each sample ray meets (film positions
    ``x``, ``y``: Dr.Jit Float pixels): :func:`scenes.backend.raycast.trace_film_dr`'s ``lit`` on
    the hit itself (its own point, shading normal and mesh shadow offset), 0 on sky.
    Returns ``(visibility, tested)``: Float in {0, 1} and the Bool lanes given a shadow
    ray (unevaluated)."""
    mi = backend.mitsuba()
    import drjit as dr

    from ...scenes.backend.raycast import trace_film_dr

    res = trace_film_dr(scene, x, y, color=False, albedo=False)
    vis = dr.select(res["valid"] & res["lit"], mi.Float(1.0), mi.Float(0.0))
    return vis, res["shadow_tested"]


def sample_points_dr(scene, x, y) -> dict:
    """The surface point each sample ray meets (film positions ``x``, ``y``), as a shadow
    technique reads it: ``valid``, ``position`` (the hit), ``normal`` (shading) and
    ``geo_normal`` facing the viewer, view ``depth``; Dr.Jit values, unevaluated."""
    mi = backend.mitsuba()
    import drjit as dr

    ray = camera_rays_dr(scene.camera, x, y)
    si = scene_hit(scene, scene.mi_scene, ray, mi.RayFlags.All)
    valid = si.is_valid()
    to_eye = -ray.d
    return {
        "valid": valid,
        "position": si.p,
        "normal": dr.select(valid, facing(si.sh_frame.n, to_eye), mi.Vector3f(0.0, 0.0, 1.0)),
        "geo_normal": dr.select(valid, facing(si.n, to_eye), mi.Vector3f(0.0, 0.0, 1.0)),
        "depth": dr.select(valid, view_depth(scene.camera, si.p), 0.0),
    }


def sample_colors(scene, offsets: np.ndarray) -> tuple[dict, int]:
    """Every sample shaded where it lies (supersampling): the oracle's own
    :func:`scenes.backend.raycast.trace_film_dr` at each sub-sample position.

    Returns ``({"valid": (P, N), "shape": (P, N), "color": (P, N, 3)}, shadow_rays)``;
    ``color`` is a view of planar ``(3, P, N)`` storage (the layout Dr.Jit hands over: no
    interleaving copy).
    """
    mi = backend.mitsuba()
    import drjit as dr

    from ...scenes.backend.raycast import trace_film_dr

    cam = scene.camera
    w = cam.width
    offs = np.asarray(offsets, dtype=np.float32).reshape(-1, 2)
    n = len(offs)
    n_pix = cam.width * cam.height
    total = n_pix * n
    valid_out = np.empty(total, bool)
    planar = np.empty((3, total), np.float32)
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    step = max(n, (CHUNK // n) * n)
    rays = 0
    for start in range(0, total, step):
        stop = min(total, start + step)
        idx = dr.arange(mi.UInt32, start, stop)
        pix = idx // n
        s = idx - pix * n
        x = mi.Float(pix % w) + dr.gather(mi.Float, ox, s)
        y = mi.Float(pix // w) + dr.gather(mi.Float, oy, s)
        res = trace_film_dr(scene, x, y, color=True)
        count = dr.count(res["shadow_tested"])
        dr.eval(res["valid"], res["color"], count)
        valid_out[start:stop] = to_numpy(res["valid"])
        planar[:, start:stop] = to_numpy(res["color"])
        rays += int(count[0])
    return {
        "valid": valid_out.reshape(n_pix, n),
        "color": np.moveaxis(planar.reshape(3, n_pix, n), 0, -1),
    }, rays
