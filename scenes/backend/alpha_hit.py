"""Closest hits and shadow tests through alpha-tested surfaces (glTF ``MASK``): the alpha test
of the one intersection engine that the oracle and the models share.

A ray's closest hit on an alpha-tested shape counts only where the material's alpha test
keeps the point (:class:`scenes.shading.alpha.AlphaTable`); where it fails, the ray goes on
from the hit, in a bounded, deterministic Dr.Jit loop (``dr.while_loop``), until it meets a
kept point, an opaque shape, nothing, or the bound :data:`MAX_ALPHA_LAYERS`. The masks are
found from the hit's Mitsuba shape through a per-scene table indexed by the shape's registry
id (:class:`AlphaScene`), so one gather per hit selects the material whatever the number of
shapes.

Continuing a ray: the new origin is the hit point moved to the far side of the surface by
``offset * (1 + |n|.|p|)`` along the geometric normal (the origin offset of
:mod:`.raycast`'s shadow rays: :data:`PASS_OFFSET_MESH` for meshes, :data:`PASS_OFFSET` for
analytic shapes); a mesh hit on the very triangle the ray just left (rounding) is passed again
with twice the offset. The ray's remaining length shrinks by the distance travelled, and the
returned hit's ``t`` is measured from the first origin.

A ray still going after :data:`MAX_ALPHA_LAYERS` cut-out surfaces stops: the closest-hit query
returns the last surface it met as if it were kept and the shadow query calls the ray blocked
(deterministic; both report how many rays stopped so, ``exhausted``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..shading.alpha import ALPHA_ATTRIBUTE, AlphaTable

__all__ = [
    "MAX_ALPHA_LAYERS",
    "PASS_OFFSET",
    "PASS_OFFSET_MESH",
    "AlphaScene",
    "alpha_scene",
    "closest_hit_alpha",
    "loaded_alpha",
    "scene_hit",
    "occluded_alpha",
]

#: Cut-out surfaces a ray may pass before it stops (a ray through 200 m of leaf cards passes
#: a few dozen; the bound keeps the loop finite and its cost bounded).
MAX_ALPHA_LAYERS = 64
#: Origin offsets of a continued ray, times ``1 + |n|.|p|`` (as :mod:`.raycast`'s shadow rays:
#: four float32 ulps for meshes, sixteen for analytic shapes).
PASS_OFFSET_MESH = 2.0**-21
PASS_OFFSET = 2.0**-19


@dataclass
class AlphaScene:
    """The alpha masks of one Mitsuba scene: ``table`` and ``registry`` (Dr.Jit Int32: mask
    index per shape registry id, -1 opaque), ``vertex`` (a mask reads vertex alpha: every
    mesh of the scene then carries :data:`~scenes.shading.alpha.ALPHA_ATTRIBUTE`), ``bsdf``
    (a mask reads its shape's Mitsuba ``mask`` BSDF's opacity)."""

    table: AlphaTable
    registry: object
    vertex: bool
    bsdf: bool = False

    def mask_of(self, si, active):
        """Mask index (Int32, -1 opaque) of the shapes of hits ``si``."""
        import drjit as dr
        import mitsuba as mi

        reg = dr.reinterpret_array(mi.UInt32, si.shape)
        on = active & si.is_valid()
        n = dr.width(self.registry)
        m = dr.gather(mi.Int32, self.registry, dr.minimum(reg, n - 1), on & (reg < n))
        return dr.select(on & (reg < n), m, -1)

    def covered(self, si, active):
        """The alpha test at hits ``si`` (True on opaque shapes and where alpha >= cutoff)."""
        mask = self.mask_of(si, active)
        tested = active & (mask >= 0)
        va = op = None
        if self.vertex:
            va = si.shape.eval_attribute_1(ALPHA_ATTRIBUTE, si, tested)
        if self.bsdf:
            op = si.bsdf().eval_attribute_1("opacity", si, tested)
        return self.table.covered_dr(mask, si.uv, va, tested, op)


def alpha_scene(mi_scene, table: AlphaTable | None, memo: dict | None = None):
    """The :class:`AlphaScene` of ``mi_scene`` (its shapes in ``shape_names`` order) and
    ``table``, or None when no shape is alpha-tested (callers then take the plain queries,
    whose results are unchanged). Cached in ``memo`` when given."""
    if table is None or not table.any:
        return None
    # keyed by the Mitsuba scene: a scene whose objects move is rebuilt per frame
    cache = None if memo is None else memo.setdefault("alpha_scene", {})
    if cache is not None and id(mi_scene) in cache and cache[id(mi_scene)][0] is mi_scene:
        return cache[id(mi_scene)][1]
    import drjit as dr
    import mitsuba as mi

    reg = table.registry_table(mi, dr, mi_scene.shapes())
    out = AlphaScene(
        table,
        mi.Int32(reg),
        any(m.vertex_alpha for m in table.masks),
        any(m.bsdf_opacity for m in table.masks),
    )
    if cache is not None:
        cache[id(mi_scene)] = (mi_scene, out)
    return out


def loaded_alpha(loaded):
    """The :class:`AlphaScene` of a loaded scene (its ``alpha`` table, when it has one; cached
    in its ``memo``), or None."""
    table = getattr(loaded, "alpha", None)
    return alpha_scene(loaded.mi_scene, table, getattr(loaded, "memo", None))


def scene_hit(loaded, target, ray, flags, *, coherent: bool = True):
    """Closest hits of ``ray`` on ``target`` (``loaded.mi_scene``, or a sub-scene of some of
    its shapes): through alpha-tested surfaces when ``target`` is the loaded scene itself (a
    sub-scene's shapes have other registry ids: plain hits)."""
    alpha = loaded_alpha(loaded) if target is loaded.mi_scene else None
    return closest_hit_alpha(target, ray, alpha, flags=flags, coherent=coherent)[0]


def _far_side(si, d, boost):
    """The hit points of ``si`` moved through their surface along ``d`` (see the module)."""
    import drjit as dr

    ng = si.n
    offset = dr.select(si.shape.is_mesh(), PASS_OFFSET_MESH, PASS_OFFSET) * boost
    side = dr.select(dr.dot(ng, d) >= 0.0, 1.0, -1.0)
    return si.p + ng * (side * (1.0 + dr.dot(dr.abs(ng), dr.abs(si.p))) * offset)


def _again(si, last_shape, last_prim):
    """Where the hit is on the mesh triangle the ray has just passed (rounding)."""
    import drjit as dr
    import mitsuba as mi

    reg = dr.reinterpret_array(mi.UInt32, si.shape)
    return si.shape.is_mesh() & (reg == last_shape) & (si.prim_index == last_prim)


def closest_hit_alpha(
    scene,
    ray,
    alpha: AlphaScene | None,
    *,
    flags=None,
    coherent: bool = False,
    active=True,
    max_layers: int = MAX_ALPHA_LAYERS,
):
    """Closest kept hits of Dr.Jit rays ``ray`` (unit directions) on ``scene``.

    Returns ``(si, layers, exhausted)``: the ``SurfaceInteraction3f`` (``flags``, at least
    ``RayFlags.UV``; ``t`` from the ray's own origin), the number of continuations each ray
    took (UInt32: the cut-out surfaces it passed, and a rare re-hit of one) and where a ray
    stopped at ``max_layers`` continuations (Bool). With ``alpha`` None, one
    plain ``ray_intersect`` (the same bytes as without this function).
    """
    import drjit as dr
    import mitsuba as mi

    flags = mi.RayFlags.All if flags is None else flags
    active = mi.Bool(active)
    n = dr.width(ray.o)
    if alpha is None:
        si = scene.ray_intersect(ray, ray_flags=flags, coherent=coherent, active=active)
        return si, dr.zeros(mi.UInt32, n), dr.zeros(mi.Bool, n)
    flags = flags | mi.RayFlags.UV
    si0 = scene.ray_intersect(ray, ray_flags=flags, coherent=coherent, active=active)
    ok0 = alpha.covered(si0, active & si0.is_valid())
    pending = active & si0.is_valid() & ~ok0
    zero_u = dr.zeros(mi.UInt32, n)

    def body(si, t0, pending, layers, last_shape, last_prim, boost):
        again = _again(si, last_shape, last_prim)
        boost = dr.select(again, boost * 2.0, 1.0)
        last_shape = dr.select(pending, dr.reinterpret_array(mi.UInt32, si.shape), last_shape)
        last_prim = dr.select(pending, si.prim_index, last_prim)
        t_here = t0 + si.t
        o = _far_side(si, ray.d, boost)
        nxt = mi.Ray3f(o, ray.d, dr.maximum(ray.maxt - t_here, 0.0), 0.0, mi.Color0f())
        s2 = scene.ray_intersect(nxt, ray_flags=flags, coherent=False, active=pending)
        hit = pending & s2.is_valid()
        same = hit & _again(s2, last_shape, last_prim)
        kept = hit & ~same & alpha.covered(s2, hit & ~same)
        layers = dr.select(pending, layers + 1, layers)  # rounds, a re-hit included
        # a miss leaves the ray: its invalid interaction is the answer
        si = dr.select(pending, s2, si)
        t0 = dr.select(pending, t_here, t0)
        return si, t0, hit & ~kept, layers, last_shape, last_prim, boost

    state = (
        si0,
        dr.zeros(mi.Float, n),
        pending,
        zero_u,
        dr.zeros(mi.UInt32, n),
        dr.zeros(mi.UInt32, n),
        dr.full(mi.Float, 1.0, n),
    )
    si, t0, pending, layers, *_ = dr.while_loop(
        state=state,
        cond=lambda si, t0, pending, layers, *rest: pending & (layers < max_layers),
        body=body,
        labels=("si", "t0", "pending", "layers", "last_shape", "last_prim", "boost"),
    )
    si.t = dr.select(si.is_valid(), si.t + t0, si.t)
    return si, layers, pending


def occluded_alpha(
    scene, ray, alpha: AlphaScene | None, *, active=True, max_layers: int = MAX_ALPHA_LAYERS
):
    """Shadow test of Dr.Jit rays through alpha-tested surfaces: ``(blocked, exhausted)``
    (Bool): blocked where the segment meets a kept point of any surface (a ray stopped at
    ``max_layers`` counts as blocked). With ``alpha`` None, one plain ``ray_test``."""
    import drjit as dr
    import mitsuba as mi

    active = mi.Bool(active)
    n = dr.width(ray.o)
    if alpha is None:
        return scene.ray_test(ray, active), dr.zeros(mi.Bool, n)
    si, _, exhausted = closest_hit_alpha(
        scene,
        ray,
        alpha,
        flags=mi.RayFlags.UV,
        coherent=False,
        active=active,
        max_layers=max_layers,
    )
    return active & si.is_valid(), exhausted
