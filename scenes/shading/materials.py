"""Materials: the Mitsuba diffuse material of the built-in scenes (:func:`diffuse`) and the
glTF metallic-roughness materials of a loaded scene (factors, textures, per-hit evaluation).

The one owner of material data: the glTF reader (:mod:`scenes.formats.gltf`) builds these
records and the intersection engine (:mod:`scenes.backend.raycast`) evaluates them at hits.

A :class:`PbrMaterials` table holds every material of a glTF scene and the shape -> material
map (shape index as in ``LoadedScene.shape_names``). :meth:`PbrMaterials.evaluate_dr` gives,
at surface hits (Dr.Jit arrays), the parameters the BRDF of :mod:`scenes.shading.pbr` takes:

- base colour: ``baseColorFactor`` times the base colour texture (sRGB decoded to linear
  before filtering, as a GPU's sRGB formats do);
- metallic and roughness: the factors times the texture's B and G channels (linear);
- emissive: ``emissiveFactor`` (times ``KHR_materials_emissive_strength``) times the
  emissive texture (sRGB);
- the normal texture's tangent-space normal (linear, ``2 t - 1``, x and y scaled by the
  texture's ``scale``), applied by :func:`perturb_normal_dr`.

Textures are sampled at the hit's ``TEXCOORD_0`` with the sampler's magnification filter
(bilinear or nearest) and wrap mode and no mipmaps: the oracle integrates the pixel with its
sub-pixel samples, so the truth is the texture itself, box filtered over the pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "PbrMaterial",
    "PbrMaterials",
    "Texture",
    "diffuse",
    "perturb_normal_dr",
    "surface_dr",
]


def diffuse(rgb) -> dict:
    """Two-sided diffuse material of albedo ``rgb`` (a scalar or 3 linear values): the
    Mitsuba dictionary of every built-in scene's shapes and of a glTF mesh's Mitsuba view."""
    rgb = [float(c) for c in np.broadcast_to(np.asarray(rgb, float), (3,))]
    return {
        "type": "twosided",
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}},
    }


@dataclass(frozen=True)
class Texture:
    """One texture as sampled: ``image`` (H, W, C) float32 linear values (row 0 = ``v`` 0),
    ``wrap`` ``"repeat"``, ``"clamp"`` or ``"mirror"`` (both axes), ``nearest`` filtering,
    ``srgb``: decoded from sRGB (a colour texture)."""

    image: np.ndarray
    wrap: str = "repeat"
    nearest: bool = False
    name: str = ""
    srgb: bool = False


@dataclass(frozen=True)
class PbrMaterial:
    """One glTF material (factors and texture indices into :attr:`PbrMaterials.textures`)."""

    name: str = ""
    base_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    metallic: float = 1.0
    roughness: float = 1.0
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal_scale: float = 1.0
    base_color_texture: int = -1
    metallic_roughness_texture: int = -1
    emissive_texture: int = -1
    normal_texture: int = -1
    double_sided: bool = False

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "base_color_factor": list(self.base_color),
            "metallic_factor": self.metallic,
            "roughness_factor": self.roughness,
            "emissive": list(self.emissive),
            "normal_scale": self.normal_scale,
            "textures": {
                k: v
                for k, v in (
                    ("base_color", self.base_color_texture),
                    ("metallic_roughness", self.metallic_roughness_texture),
                    ("emissive", self.emissive_texture),
                    ("normal", self.normal_texture),
                )
                if v >= 0
            },
            "double_sided": self.double_sided,
        }


_SLOTS = ("base_color_texture", "metallic_roughness_texture", "emissive_texture", "normal_texture")


@dataclass
class PbrMaterials:
    """The materials of a glTF scene and the material of each shape (by shape index)."""

    materials: list[PbrMaterial]
    textures: list[Texture]
    shape_material: np.ndarray
    _dr: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def has_normal_textures(self) -> bool:
        return any(m.normal_texture >= 0 for m in self.materials)

    def to_json(self) -> dict:
        return {
            "materials": [m.to_json() for m in self.materials],
            "textures": [
                {"name": t.name, "size": list(t.image.shape[:2]), "wrap": t.wrap}
                for t in self.textures
            ],
            "shape_material": [int(i) for i in self.shape_material],
        }

    def _tables(self):
        """Dr.Jit copies of the factor tables and textures (built once)."""
        if "tables" in self._dr:
            return self._dr["tables"]
        import drjit as dr
        import mitsuba as mi

        mats = self.materials

        def col(values):
            return mi.Float(np.asarray(values, dtype=np.float32))

        tables = {
            "shape_material": mi.Int32(np.asarray(self.shape_material, dtype=np.int32)),
            "base": [col([m.base_color[i] for m in mats]) for i in range(3)],
            "emissive": [col([m.emissive[i] for m in mats]) for i in range(3)],
            "metallic": col([m.metallic for m in mats]),
            "roughness": col([m.roughness for m in mats]),
            "normal_scale": col([m.normal_scale for m in mats]),
            "slots": {
                s: mi.Int32(np.asarray([getattr(m, s) for m in mats], np.int32)) for s in _SLOTS
            },
        }
        wraps = {
            "repeat": dr.WrapMode.Repeat,
            "clamp": dr.WrapMode.Clamp,
            "mirror": dr.WrapMode.Mirror,
        }
        tables["textures"] = [
            mi.Texture2f(
                mi.TensorXf(np.ascontiguousarray(t.image, dtype=np.float32)),
                use_accel=False,
                filter_mode=dr.FilterMode.Nearest if t.nearest else dr.FilterMode.Linear,
                wrap_mode=wraps[t.wrap],
            )
            for t in self.textures
        ]
        self._dr["tables"] = tables
        return tables

    def evaluate_dr(self, shape_index, uv, active) -> dict:
        """Material parameters at hits of shapes ``shape_index`` (Dr.Jit Int32, -1 sky) with
        texture coordinates ``uv`` (Point2f): ``base_color``, ``emissive`` (Color3f, linear),
        ``metallic``, ``roughness``, ``normal_scale`` (Float), ``normal_texel`` (Vector3f
        tangent-space normal before scaling, ``(0, 0, 1)`` without a normal texture) and
        ``has_normal`` (Bool)."""
        import drjit as dr
        import mitsuba as mi

        t = self._tables()
        shape = dr.select(active, shape_index, 0)
        mat = dr.gather(mi.Int32, t["shape_material"], shape, active)

        def factor(table):
            return dr.gather(mi.Float, table, mat, active)

        base = [factor(c) for c in t["base"]]
        emissive = [factor(c) for c in t["emissive"]]
        metallic = factor(t["metallic"])
        roughness = factor(t["roughness"])
        nrm = [mi.Float(0.0), mi.Float(0.0), mi.Float(1.0)]
        has_normal = mi.Bool(False) & active
        pos = mi.Point2f(uv.x, uv.y)
        slot = {s: dr.gather(mi.Int32, t["slots"][s], mat, active) for s in _SLOTS}
        for k, tex in enumerate(t["textures"]):
            uses = {s: active & (slot[s] == k) for s in _SLOTS}
            any_use = uses[_SLOTS[0]] | uses[_SLOTS[1]] | uses[_SLOTS[2]] | uses[_SLOTS[3]]
            texel = tex.eval(pos, any_use)
            rgb = [texel[min(i, len(texel) - 1)] for i in range(3)]
            m = uses["base_color_texture"]
            base = [dr.select(m, b * c, b) for b, c in zip(base, rgb, strict=True)]
            m = uses["emissive_texture"]
            emissive = [dr.select(m, e * c, e) for e, c in zip(emissive, rgb, strict=True)]
            m = uses["metallic_roughness_texture"]
            metallic = dr.select(m, metallic * rgb[2], metallic)
            roughness = dr.select(m, roughness * rgb[1], roughness)
            m = uses["normal_texture"]
            nrm = [dr.select(m, 2.0 * c - 1.0, n) for n, c in zip(nrm, rgb, strict=True)]
            has_normal |= m
        return {
            "base_color": mi.Color3f(*base),
            "emissive": mi.Color3f(*emissive),
            "metallic": dr.clip(metallic, 0.0, 1.0),
            "roughness": dr.clip(roughness, 0.0, 1.0),
            "normal_scale": factor(t["normal_scale"]),
            "normal_texel": mi.Vector3f(*nrm),
            "has_normal": has_normal,
        }


def perturb_normal_dr(n, dp_du, tangent4, texel, scale, has_normal, flipped):
    """The shading normal bent by a normal texture (Dr.Jit).

    ``n`` is the unit interpolated normal facing the viewer; the tangent ``T`` is the vertex
    tangent ``tangent4.xyz`` where the mesh has one (bitangent sign ``tangent4.w``) and else
    ``dp/du`` of the triangle (the Khronos sample renderer's fallback, bitangent sign +1);
    ``T`` is made orthogonal to ``n`` and ``B = w (n x T)``. The result is
    ``normalize(T x s + B y s + n z)`` for the texel ``(x, y, z)`` and scale ``s`` where
    ``has_normal``, ``n`` elsewhere. Where ``flipped`` (a back face: ``n`` was turned to face
    the viewer) the tangent and bitangent flip too, as the sample renderer flips them.
    """
    import drjit as dr
    import mitsuba as mi

    given = dr.squared_norm(mi.Vector3f(tangent4[0], tangent4[1], tangent4[2])) > 0.0
    t_raw = dr.select(given, mi.Vector3f(tangent4[0], tangent4[1], tangent4[2]), dp_du)
    w = dr.select(given & (tangent4[3] < 0.0), -1.0, 1.0)
    t = t_raw - n * dr.dot(n, t_raw)
    t_len = dr.norm(t)
    ok = has_normal & (t_len > 1e-12)
    t = t / dr.select(t_len > 1e-12, t_len, 1.0)
    t = dr.select(flipped, -t, t)
    b = dr.cross(n, t) * dr.select(flipped, -w, w)
    bent = dr.normalize(t * (texel.x * scale) + b * (texel.y * scale) + n * texel.z)
    return dr.select(ok, bent, n)


def surface_dr(pbr: PbrMaterials, si, shape_index, normal, to_eye, active) -> dict:
    """The glTF material at primary hits ``si`` (a Mitsuba SurfaceInteraction3f of shapes
    ``shape_index``): :meth:`PbrMaterials.evaluate_dr`'s parameters and ``normal``, the
    viewer-facing shading normal ``normal`` bent by the normal texture (``si`` needs
    ``dp_du``, i.e. ``RayFlags.dPdUV``, when the scene has normal textures)."""
    import drjit as dr

    mat = pbr.evaluate_dr(shape_index, si.uv, active)
    if not pbr.has_normal_textures:
        mat["normal"] = normal
        return mat
    on = active & mat["has_normal"]
    t3 = si.shape.eval_attribute_3("vertex_tangent", si, on)
    tw = si.shape.eval_attribute_1("vertex_tangent_w", si, on)
    flipped = dr.dot(si.sh_frame.n, to_eye) < 0.0
    mat["normal"] = perturb_normal_dr(
        normal,
        si.dp_du,
        (t3.x, t3.y, t3.z, tw),
        mat["normal_texel"],
        mat["normal_scale"],
        on,
        flipped,
    )
    return mat
