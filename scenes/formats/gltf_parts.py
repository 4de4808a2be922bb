"""The parts of a glTF 2.0 scene, read from a checked :class:`.gltf_document.GltfDocument`.

- :func:`walk_nodes`: the node hierarchy (``matrix`` or TRS, composed parent first, every
  transform finite and within :data:`.gltf_document.LIMITS`);
- :func:`primitive_mesh`: a ``TRIANGLES`` primitive as an ``ro_mesh`` entry in world space
  (positions in float64 stored as float32, normals by the inverse transpose, ``TEXCOORD_0``,
  tangents and ``COLOR_0``'s alpha, :func:`vertex_alpha`);
- :class:`Textures` and :func:`read_material`: metallic-roughness materials and their
  textures (:mod:`scenes.shading.materials`), sRGB colour textures decoded to linear;
  ``alphaMode`` OPAQUE or MASK (whose alpha :mod:`.gltf_alpha` reads), BLEND refused;
- :func:`camera_entry`: the camera as a Mitsuba sensor (glTF cameras look down -Z with +Y up;
  Mitsuba's down +Z with +X left);
- :func:`light_entry`: a KHR_lights_punctual light as a Mitsuba emitter and its attenuation
  record.

Each refuses what it does not support with one line naming it (:class:`.gltf_document.GltfError`).
"""

from __future__ import annotations

import io
import math
import warnings

import numpy as np

from ..base.display import srgb_decode
from ..camera import look_at
from ..shading.alpha import AlphaError, gltf_alpha_mode
from ..shading.materials import PbrMaterial, Texture
from .gltf_document import LIMITS, GltfDocument, GltfError, as_index, as_number, as_numbers
from .gltf_write import GL_TO_MI

__all__ = [
    "vertex_alpha",
    "SUPPORTED_EXTENSIONS",
    "Textures",
    "camera_entry",
    "check_extensions",
    "light_entry",
    "primitive_mesh",
    "read_material",
    "walk_nodes",
]

#: Extensions read here; any other one named in ``extensionsUsed`` is refused.
SUPPORTED_EXTENSIONS = ("KHR_lights_punctual", "KHR_materials_emissive_strength")
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 5: "TRIANGLE_STRIP"}
_MODES[6] = "TRIANGLE_FAN"
_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}


def _node_matrix(node, d: GltfDocument | None = None, where: str = "node") -> np.ndarray:
    if d is not None:
        _check_trs(d, node, where)
    if node.matrix is not None and len(node.matrix) == 16:
        return np.array(node.matrix, dtype=np.float64).reshape(4, 4).T  # column-major
    m = np.eye(4)
    if node.rotation is not None:
        x, y, z, w = (float(c) for c in node.rotation)
        m[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    if node.scale is not None:
        m[:3, :3] = m[:3, :3] * np.asarray(node.scale, dtype=np.float64)[None, :]
    if node.translation is not None:
        m[:3, 3] = np.asarray(node.translation, dtype=np.float64)
    return m


def _check_trs(d: GltfDocument, node, where: str) -> None:
    """A node's matrix or TRS: finite numbers within :data:`LIMITS` (scale, coordinate)."""
    big, far = LIMITS["scale"], LIMITS["coordinate"]
    if node.matrix is not None:
        m = as_numbers(d, node.matrix, 16, f"{where} matrix", max(big, far))
        if max(abs(c) for c in m[:12]) > big:
            d.fail(f"{where} matrix has an entry over {big:g} in magnitude (the scale limit)")
    if node.rotation is not None:
        as_numbers(d, node.rotation, 4, f"{where} rotation", 1.0 + 1e-3)
    if node.scale is not None:
        as_numbers(d, node.scale, 3, f"{where} scale", big)
    if node.translation is not None:
        as_numbers(d, node.translation, 3, f"{where} translation", far)


def walk_nodes(d: GltfDocument) -> list[tuple[int, np.ndarray]]:
    """(node index, world matrix) of every node of the scene, depth first, parents first."""
    doc = d.doc
    nodes = doc.nodes or []
    if len(nodes) > LIMITS["nodes"]:
        d.fail(f"{len(nodes):,} nodes, over the limit of {LIMITS['nodes']:,}")
    scenes = doc.scenes or []
    if not scenes:
        roots = list(range(len(nodes)))
    else:
        index = doc.scene if doc.scene is not None else 0
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(scenes):
            d.fail(f"scene index {index!r} out of range ({len(scenes)} scenes)")
        roots = scenes[index].nodes or []
        if not isinstance(roots, list):
            d.fail(f"scene {index} nodes must be a list")
    out, seen = [], set()
    stack = [(r, np.eye(4), 1) for r in reversed(roots)]
    while stack:
        i, parent, depth = stack.pop()
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < len(nodes) or i in seen:
            d.fail(f"node hierarchy is not a tree (node {i!r})")
        if depth > LIMITS["depth"]:
            d.fail(f"node hierarchy deeper than {LIMITS['depth']} levels (the limit)")
        seen.add(i)
        world = parent @ _node_matrix(nodes[i], d, f"node {i}")
        if not np.isfinite(world).all() or np.abs(world[:3, 3]).max() > LIMITS["coordinate"]:
            d.fail(f"node {i}'s world transform is out of range (over {LIMITS['coordinate']:g})")
        out.append((i, world))
        children = nodes[i].children or []
        if not isinstance(children, list):
            d.fail(f"node {i} children must be a list")
        stack.extend((c, world, depth + 1) for c in reversed(children))
    return out


def check_extensions(d: GltfDocument) -> None:
    used = set(d.doc.extensionsUsed or []) | set(d.doc.extensionsRequired or [])
    bad = sorted(used - set(SUPPORTED_EXTENSIONS))
    if bad:
        d.fail(
            f"glTF extension {', '.join(bad)} is not supported (only "
            f"{', '.join(SUPPORTED_EXTENSIONS)}; extensions that change shading or geometry "
            "are refused, never dropped)"
        )


def _image(d: GltfDocument, index: int, *, mode: str = "RGB") -> np.ndarray:
    """Image ``index`` as (H, W, 3) float64 values in [0, 1] (``mode="RGBA"``: (H, W, 4),
    alpha kept; an image without alpha has alpha 1)."""
    from PIL import Image

    img = d.doc.images[as_index(d, index, d.doc.images, "image")]
    if img.uri is not None:
        data = d.uri_bytes(img.uri, f"image {index}")
    elif img.bufferView is not None:
        data = d.view_bytes(as_index(d, img.bufferView, d.doc.bufferViews, "buffer view"))[0]
    else:
        d.fail(f"image {index} has neither uri nor bufferView")
    limit = LIMITS["image_pixels"]
    try:
        with warnings.catch_warnings():
            # Pillow's own bomb warning (over 89 Mpx) is a refusal here, not a stray line
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as im:
                w, h = im.size
                if w * h > limit:
                    d.fail(f"image {index} is {w}x{h}, over the limit of {limit:,} pixels")
                rgb = np.asarray(im.convert(mode), dtype=np.float64) / 255.0
    except GltfError:
        raise
    except (Image.DecompressionBombWarning, Image.DecompressionBombError):
        d.fail(f"image {index} is over the limit of {limit:,} pixels")
    except Exception as exc:  # Pillow raises many types for undecodable data
        d.fail(f"image {index} cannot be decoded: {exc}")
    return rgb


class Textures:
    """Textures by (glTF texture, colour space), built on first use."""

    def __init__(self, d: GltfDocument):
        self.d, self.items, self.index = d, [], {}

    def get(self, info, *, srgb: bool, what: str) -> int:
        if info is None:
            return -1
        d = self.d
        if (getattr(info, "texCoord", 0) or 0) != 0:
            d.fail(f"{what} uses TEXCOORD_{info.texCoord}; only TEXCOORD_0 is supported")
        if getattr(info, "extensions", None):  # e.g. KHR_texture_transform, undeclared
            d.fail(f"{what} uses extension {', '.join(sorted(info.extensions))} (not supported)")
        key = (info.index, srgb)
        if key not in self.index:
            tex = d.doc.textures[as_index(d, info.index, d.doc.textures, f"{what} texture")]
            if tex.source is None:
                d.fail(f"texture {info.index} has no image source")
            wrap, nearest = "repeat", False
            if tex.sampler is not None:
                smp = d.doc.samplers[as_index(d, tex.sampler, d.doc.samplers, "sampler")]
                ws, wt = smp.wrapS or 10497, smp.wrapT or 10497
                if ws != wt or ws not in _WRAP:
                    d.fail(
                        f"sampler {tex.sampler} has wrapS {ws} and wrapT {wt}; "
                        "one wrap mode for both is supported"
                    )
                wrap, nearest = _WRAP[ws], smp.magFilter == 9728
            rgb = _image(d, tex.source)
            img = srgb_decode(rgb) if srgb else rgb
            name = f"texture {info.index} ({'sRGB' if srgb else 'linear'})"
            self.index[key] = len(self.items)
            self.items.append(Texture(img.astype(np.float32), wrap, nearest, name, srgb))
        return self.index[key]


def read_material(d: GltfDocument, index: int | None, textures: Textures) -> PbrMaterial:
    if index is None:
        return PbrMaterial(name="default")
    mat = d.doc.materials[as_index(d, index, d.doc.materials, "material")]
    label = f"material {index} ({mat.name or 'unnamed'})"
    try:  # OPAQUE and MASK (scenes.formats.gltf_alpha); BLEND refused with one line
        gltf_alpha_mode({"alphaMode": mat.alphaMode, "alphaCutoff": mat.alphaCutoff}, label=label)
    except AlphaError as exc:
        d.fail(str(exc))
    ext = dict(mat.extensions or {})
    es = ext.pop("KHR_materials_emissive_strength", {})
    strength = as_number(d, es.get("emissiveStrength", 1.0), f"{label} emissiveStrength", 0, 1e6)
    if ext:
        d.fail(f"{label} uses extension {', '.join(sorted(ext))}, which is not supported")
    pbr = mat.pbrMetallicRoughness
    base = pbr.baseColorFactor if pbr and pbr.baseColorFactor is not None else [1.0] * 4
    base = as_numbers(d, base, 4, f"{label} baseColorFactor", 1.0, lo=0.0)
    emissive = as_numbers(
        d, mat.emissiveFactor or [0.0] * 3, 3, f"{label} emissiveFactor", 1.0, 0.0
    )
    metallic = pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0
    rough = pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0
    normal = mat.normalTexture
    scale = normal.scale if normal is not None and normal.scale is not None else 1.0
    return PbrMaterial(
        name=mat.name or f"material_{index}",
        base_color=tuple(base[:3]),
        metallic=as_number(d, metallic, f"{label} metallicFactor", 0.0, 1.0),
        roughness=as_number(d, rough, f"{label} roughnessFactor", 0.0, 1.0),
        emissive=tuple(strength * c for c in emissive),
        normal_scale=as_number(d, scale, f"{label} normalTexture scale", -1e3, 1e3),
        base_color_texture=textures.get(
            pbr.baseColorTexture if pbr else None, srgb=True, what=f"{label} base colour"
        ),
        metallic_roughness_texture=textures.get(
            pbr.metallicRoughnessTexture if pbr else None, srgb=False, what=f"{label} mr"
        ),
        emissive_texture=textures.get(mat.emissiveTexture, srgb=True, what=f"{label} emissive"),
        normal_texture=textures.get(normal, srgb=False, what=f"{label} normal"),
        double_sided=bool(mat.doubleSided),
    )


def _attribute(d: GltfDocument, index, n: int, width: int, what: str) -> np.ndarray:
    """A vertex attribute: ``n`` rows of ``width`` finite values (float64); an empty NORMAL
    or TEXCOORD_0 (the project's own exports write one for a mesh without) stays empty."""
    a = d.accessor(index).astype(np.float64)
    if a.shape == (0, width) and width != 4:
        return a
    if a.shape != (n, width) or not np.isfinite(a).all():
        d.fail(f"{what} must be {n} finite rows of {width} (got {a.shape[0]}x{a.shape[1]})")
    return a


def primitive_mesh(d: GltfDocument, prim, world: np.ndarray, label: str) -> dict:
    mode = 4 if prim.mode is None else prim.mode
    if mode != 4:
        d.fail(f"{label} has primitive mode {_MODES.get(mode, mode)}; only TRIANGLES is supported")
    attrs = {k: v for k, v in vars(prim.attributes).items() if v is not None}
    if "JOINTS_0" in attrs:
        d.fail(f"{label} has JOINTS_0 (skinning), which is not supported")
    if prim.targets:
        d.fail(f"{label} has morph targets, which are not supported")
    if prim.extensions:  # e.g. KHR_draco_mesh_compression, even when not declared
        d.fail(f"{label} uses extension {', '.join(sorted(prim.extensions))} (not supported)")
    if "POSITION" not in attrs:
        d.fail(f"{label} has no POSITION attribute")
    d.count("instances", 1)
    pos = d.accessor(attrs["POSITION"]).astype(np.float64)
    d.count("vertices", len(pos))
    if pos.shape[1] != 3:
        d.fail(f"{label} POSITION is not VEC3")
    with np.errstate(all="ignore"):  # inf/NaN positions: refused just below
        v = pos @ world[:3, :3].T + world[:3, 3]
    if not np.isfinite(v).all() or (len(v) and np.abs(v).max() > LIMITS["coordinate"]):
        d.fail(f"{label} has vertices that are not finite or beyond {LIMITS['coordinate']:g}")
    if prim.indices is not None:
        idx = d.accessor(prim.indices)
        if idx.dtype.kind not in "iu" or idx.shape[1] != 1:
            d.fail(f"{label} indices must be unsigned integer SCALARs")
        idx = idx.astype(np.int64).ravel()
    else:
        idx = np.arange(len(v))
    d.count("triangles", len(idx) // 3)
    if len(idx) % 3 or (len(idx) and (idx.min() < 0 or idx.max() >= len(v))):
        d.fail(f"{label} has {len(idx)} indices, not whole triangles within its vertices")
    entry = {"type": "ro_mesh", "vertices": v.astype(np.float32)}
    entry["faces"] = idx.reshape(-1, 3).astype(np.uint32)
    lin = world[:3, :3]
    if "NORMAL" in attrs:
        nrm = _attribute(d, attrs["NORMAL"], len(v), 3, f"{label} NORMAL") @ np.linalg.inv(lin)
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        entry["normals"] = (nrm / np.where(length > 0, length, 1.0)).astype(np.float32)
    if "TEXCOORD_0" in attrs:
        uv = _attribute(d, attrs["TEXCOORD_0"], len(v), 2, f"{label} TEXCOORD_0")
        entry["texcoords"] = uv.astype(np.float32)
    tangents = np.zeros((len(v), 4), np.float32)
    if "TANGENT" in attrs:
        t = _attribute(d, attrs["TANGENT"], len(v), 4, f"{label} TANGENT")
        xyz = t[:, :3] @ lin.T
        length = np.linalg.norm(xyz, axis=1, keepdims=True)
        tangents[:, :3] = xyz / np.where(length > 0, length, 1.0)
        tangents[:, 3] = np.sign(t[:, 3] + (t[:, 3] == 0)) * np.sign(np.linalg.det(lin) or 1.0)
    entry["tangents"] = tangents
    if "COLOR_0" in attrs:
        entry["vertex_alpha"] = vertex_alpha(d, attrs["COLOR_0"], len(v), f"{label} COLOR_0")
    return entry


#: ``COLOR_0`` component types (glTF 2.0 3.7.2.1): float, normalized unsigned byte and short.
_COLOR_COMPONENTS = {5126: "float", 5121: "unsigned byte", 5123: "unsigned short"}
#: RGB of ``COLOR_0`` within this of 1 is no tint (an 8-bit step).
_NO_TINT = 1.0 / 255.0


def vertex_alpha(d: GltfDocument, index, n: int, what: str) -> np.ndarray:
    """The alpha of a ``COLOR_0`` accessor: ``n`` values in [0, 1] (float32; 1 for ``VEC3``).

    As the specification allows: ``VEC3`` or ``VEC4`` of floats, or of unsigned bytes or
    shorts with ``normalized`` set (read as ``value / max``); float values must lie in
    [0, 1]. Only the alpha is used (the alpha test of ``MASK`` materials), so an RGB that
    tints the base colour, which the shading does not model, is refused with one line."""
    acc = d.doc.accessors[as_index(d, index, d.doc.accessors, f"{what} accessor")]
    kind = acc.componentType
    if isinstance(kind, bool) or kind not in _COLOR_COMPONENTS or acc.type not in ("VEC3", "VEC4"):
        d.fail(
            f"{what} is {acc.type}/{kind}; expected VEC3 or VEC4 of float (5126), or of "
            "normalized unsigned byte (5121) or short (5123)"
        )
    if kind != 5126 and not acc.normalized:
        d.fail(f"{what} is {_COLOR_COMPONENTS[kind]} without normalized: true")
    width = 4 if acc.type == "VEC4" else 3
    c = d.accessor(index).astype(np.float64)
    if c.shape != (n, width) or not np.isfinite(c).all():
        d.fail(f"{what} must be {n} finite rows of {width} (got {c.shape[0]}x{c.shape[1]})")
    if len(c) and (c.min() < 0.0 or c.max() > 1.0):
        d.fail(f"{what} has values outside [0, 1] ({c.min():g} to {c.max():g})")
    if len(c) and np.abs(c[:, :3] - 1.0).max() > _NO_TINT:
        d.fail(
            f"{what} tints the base colour (RGB not 1), which the shading does not model; "
            "only its alpha is read (alphaMode MASK)"
        )
    alpha = c[:, 3] if width == 4 else np.ones(n)
    return alpha.astype(np.float32)


def camera_entry(d, cam_index, world, width, height, verts) -> dict:
    cam = d.doc.cameras[cam_index]
    world = world.copy()
    norms = np.linalg.norm(world[:3, :3], axis=0)
    if not (norms > 1e-12).all():
        d.fail(f"camera {cam_index}'s node has a degenerate transform (zero scale)")
    world[:3, :3] /= norms  # a camera node's scale is not a zoom: the frame alone counts
    to_world = world @ GL_TO_MI
    film = {"type": "hdrfilm", "width": int(width), "height": int(height)}
    film.update({"rfilter": {"type": "box"}, "component_format": "float32"})
    eye = world[:3, 3]
    reach = float(np.max(np.linalg.norm(verts - eye, axis=1))) if len(verts) else 1.0
    where, far_limit = f"camera {cam_index}", LIMITS["coordinate"] * 4
    if cam.type == "orthographic" and cam.orthographic is not None:
        o = cam.orthographic
        ymag = as_number(d, o.ymag, f"{where} ymag", 0.0, far_limit, open_lo=True)
        s = ymag * width / height
        to_world = to_world @ np.diag([s, s, 1.0, 1.0])
        near = as_number(d, o.znear, f"{where} znear", 0.0, far_limit)
        far = as_number(d, o.zfar, f"{where} zfar", 0.0, far_limit, open_lo=True)
        entry = {"type": "orthographic"}
    elif cam.type == "perspective" and cam.perspective is not None:
        p = cam.perspective
        yfov = as_number(d, p.yfov, f"{where} yfov", 0.0, math.pi, open_lo=True)
        fov_x = math.degrees(2.0 * math.atan(width / height * math.tan(yfov / 2.0)))
        if not 0.0 < fov_x < 180.0 or yfov >= math.pi:
            d.fail(f"{where} yfov {yfov!r} gives no usable field of view")
        near = as_number(d, p.znear, f"{where} znear", 0.0, far_limit, open_lo=True)
        if p.zfar is not None:
            far = as_number(d, p.zfar, f"{where} zfar", 0.0, far_limit, open_lo=True)
        else:
            far = 1.01 * reach + near
        entry = {"type": "perspective", "fov": fov_x, "fov_axis": "x"}
    else:
        d.fail(f"camera {cam_index} has type {cam.type!r}; perspective or orthographic")
    if not (0 < near < far and np.isfinite(to_world).all()):
        d.fail(f"camera {cam_index} has near {near} and far {far}; need 0 < near < far")
    entry.update({"near_clip": near, "far_clip": far, "to_world": to_world, "film": film})
    return entry


def light_entry(d: GltfDocument, index: int, world: np.ndarray) -> tuple[dict, dict]:
    lights = (d.doc.extensions or {}).get("KHR_lights_punctual", {}).get("lights", [])
    if not 0 <= index < len(lights):
        d.fail(f"KHR_lights_punctual light {index} does not exist")
    lt = lights[index]
    if not isinstance(lt, dict):
        d.fail(f"KHR_lights_punctual light {index} must be an object")
    kind = lt.get("type")
    where = f"KHR_lights_punctual light {index}"
    intensity = as_number(d, lt.get("intensity", 1.0), f"{where} intensity", 0.0, 1e12)
    color = as_numbers(d, lt.get("color", [1.0, 1.0, 1.0]), 3, f"{where} color", 1e3, lo=0.0)
    rgb = [c * intensity for c in color]
    d_axis = -world[:3, 2]
    if not np.linalg.norm(d_axis) > 0:
        d.fail(f"{where}: its node's transform has no direction (zero scale)")
    pos = world[:3, 3]
    rng = lt.get("range")
    rng = 0.0 if rng is None else as_number(d, rng, f"{where} range", 0.0, 1e12, open_lo=True)
    if kind == "directional":
        entry = {"type": "directional", "direction": [float(c) for c in d_axis]}
        return entry | {"irradiance": {"type": "rgb", "value": rgb}}, {"model": "gltf"}
    if kind == "point":
        entry = {"type": "point", "position": [float(c) for c in pos]}
        return entry | {"intensity": {"type": "rgb", "value": rgb}}, {"model": "gltf", "range": rng}
    if kind == "spot":
        spot = lt.get("spot", {})
        if not isinstance(spot, dict):
            d.fail(f"{where} spot must be an object")
        inner = as_number(d, spot.get("innerConeAngle", 0.0), f"{where} innerConeAngle", 0, 2)
        outer = as_number(d, spot.get("outerConeAngle", math.pi / 4), f"{where} outer", 0, 2)
        if not 0 <= inner < outer <= math.pi / 2:
            d.fail(f"spot light {index} has cone angles {inner}, {outer}; need 0 <= in < out")
        up = (0.0, 1.0, 0.0) if abs(d_axis[1]) < 0.99 * np.linalg.norm(d_axis) else (1.0, 0, 0)
        entry = {
            "type": "spot",
            "to_world": look_at(pos, pos + d_axis, up),
            "intensity": {"type": "rgb", "value": rgb},
            "cutoff_angle": math.degrees(outer),
            "beam_width": math.degrees(inner),
        }
        return entry, {"model": "gltf", "range": rng}
    d.fail(f"KHR_lights_punctual light {index} has unknown type {kind!r}")
