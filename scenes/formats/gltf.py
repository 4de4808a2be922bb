"""Read a glTF 2.0 scene (``.gltf`` or ``.glb``) into the project's scene representation.

:func:`gltf_input` turns a glTF document (read with pygltflib) into a :class:`GltfInput`: a
Mitsuba scene dictionary (triangle meshes in world space with their normals, ``TEXCOORD_0``
and tangents, the camera as a Mitsuba sensor, the lights as Mitsuba emitters) that
:mod:`scenes.loader` loads as it loads a built-in scene, the glTF materials
(:class:`scenes.formats.gltf_materials.PbrMaterials`) and the KHR_lights_punctual attenuation
of every light. What is read:

- the scene's node hierarchy (``matrix`` or TRS, composed parent first) and its meshes'
  ``TRIANGLES`` primitives (indexed or not); positions are transformed in float64 and stored
  as float32; normals by the inverse transpose; a primitive without normals gets face normals;
- the camera (the first camera node in depth-first order, or the node of glTF camera ``N``):
  perspective (``yfov``; the horizontal field of view follows the film's aspect ratio, not
  ``aspectRatio``) or orthographic (``ymag``; the half width is ``ymag`` times the film's
  aspect; the camera node's scale is removed); a missing ``zfar`` becomes just beyond the
  farthest vertex. The film is 160
  pixels wide and as high as ``aspectRatio`` gives (else 90), or the ``film_size`` of the
  camera's ``extras`` (written by ``export``). glTF cameras look down
  -Z with +Y up; Mitsuba's look down +Z with +X left: ``to_world = node @ diag(-1, 1, -1, 1)``;
- KHR_lights_punctual lights (a light travels along its node's -Z);
- pbrMetallicRoughness factors and textures, emissive (and KHR_materials_emissive_strength),
  normal textures. Occlusion textures scale ambient light only, which these scenes do not
  have: they are read and have no effect.

Untrusted input (:mod:`scenes.base.untrusted`): the file and every external buffer or image
are read only when regular files of at most :data:`LIMITS` ``file_bytes``; an external ``uri``
must stay inside the glTF's own folder (no absolute path, no ``..``, no link out, no scheme
but ``data:``); a GLB's header and chunk lengths are checked (version 2 only); every index,
count, offset and stride is checked against what it points at; node matrices and TRS,
positions, light intensity, colour and range, camera ``yfov``, ``aspectRatio``, ``xmag``,
``ymag`` and clip planes must be finite and in range; the counts of :data:`LIMITS` (nodes,
hierarchy depth, mesh instances, vertices, triangles, image pixels, accessor bytes) are
enforced, naming the one exceeded.

Refused, with one line naming it: other primitive modes, ``alphaMode`` MASK or BLEND, vertex
colours, skins and morph targets, sparse accessors, texture coordinate sets other than 0,
different wrap modes in s and t, and every extension but KHR_lights_punctual and
KHR_materials_emissive_strength. Materials are shaded two-sided (back faces are not culled;
closed meshes are unaffected).
"""

from __future__ import annotations

import base64
import hashlib
import io
import math
import re
import struct
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..base.untrusted import LIMITS as FILE_LIMITS
from ..base.untrusted import contained, loads_json, read_bounded
from ..catalogue.factories import diffuse, look_at
from .gltf_materials import PbrMaterial, PbrMaterials, Texture, srgb_to_linear

__all__ = ["GLTF_SUFFIXES", "GltfError", "GltfInput", "gltf_input", "gltf_scene", "is_gltf"]

GLTF_SUFFIXES = (".gltf", ".glb")
#: Extensions read here; any other one named in ``extensionsUsed`` is refused.
SUPPORTED_EXTENSIONS = ("KHR_lights_punctual", "KHR_materials_emissive_strength")
#: Default film width of a glTF file (its height follows the camera's ``aspectRatio``).
DEFAULT_WIDTH = 160
DEFAULT_HEIGHT = 90
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 5: "TRIANGLE_STRIP"}
_MODES[6] = "TRIANGLE_FAN"
_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16}
_COMPONENTS.update({5125: np.uint32, 5126: np.float32})
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
#: glTF camera axes to Mitsuba's: +X right -> +X left, -Z forward -> +Z forward.
_GL_TO_MI = np.diag([-1.0, 1.0, -1.0, 1.0])
#: Limits of a glTF scene (beyond one: refused, naming it).
LIMITS = {
    "file_bytes": FILE_LIMITS["gltf_bytes"],  # the file and each external buffer or image
    "nodes": 10_000,  # nodes of the document
    "arrays": 100_000,  # entries of any other top-level array (meshes, accessors, ...)
    "depth": 64,  # node hierarchy depth
    "instances": 2_000,  # mesh primitives placed in the scene (node x primitive)
    "vertices": 4_000_000,  # vertices of all placed primitives
    "triangles": 4_000_000,  # triangles of all placed primitives
    "accessor_bytes": 256 << 20,  # bytes one accessor spans
    "image_pixels": 4096 * 4096,  # pixels of one texture image
    "film_pixels": 16384,  # width or height of the film an aspectRatio asks for
    "coordinate": 1e8,  # |world coordinate| of a vertex, node translation, light position
    "scale": 1e6,  # |matrix entry| and |scale| of a node
}


class GltfError(ValueError):
    """A glTF file that cannot be read or uses a feature not supported (one line)."""


def is_gltf(scene) -> bool:
    """Whether ``scene`` (a path or name) names a glTF file by its suffix."""
    return isinstance(scene, str | Path) and Path(str(scene)).suffix.lower() in GLTF_SUFFIXES


@dataclass
class GltfInput:
    """A glTF scene ready for :mod:`scenes.loader`: ``raw`` (Mitsuba dictionary with
    ``ro_mesh`` entries), ``digest`` (SHA-256 of the content), the light records by emitter
    id and the material of each mesh entry."""

    name: str
    source: str
    description: str
    raw: dict
    digest: object
    light_records: dict
    shape_materials: dict
    materials: list
    textures: list

    def lights(self, lights: list) -> list:
        """The loaded lights with their KHR_lights_punctual attenuation."""
        return [replace(lt, **self.light_records.get(lt.name, {})) for lt in lights]

    def pbr(self, shape_names: list[str]) -> PbrMaterials:
        """The material table for shapes in loaded order."""
        table = np.array([self.shape_materials[n] for n in shape_names], dtype=np.int32)
        return PbrMaterials(list(self.materials), list(self.textures), table)


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", text) or "x"


class _Doc:
    """A pygltflib document with its buffers resolved."""

    def __init__(self, doc, base: Path | None, blob: bytes | None, label: str):
        self.doc, self.base, self.blob, self.label = doc, base, blob, label
        self._buffers: dict[int, bytes] = {}
        self.files: list[tuple[str, bytes]] = []
        self.counts = {"vertices": 0, "triangles": 0, "instances": 0}

    def fail(self, what: str):
        raise GltfError(f"{self.label}: {what}")

    def count(self, what: str, n: int) -> None:
        """Add ``n`` to the running count ``what``; beyond :data:`LIMITS`: refused."""
        self.counts[what] += n
        if self.counts[what] > LIMITS[what]:
            self.fail(f"more than {LIMITS[what]:,} {what} (the limit)")

    def uri_bytes(self, uri, what: str) -> bytes:
        if not isinstance(uri, str):
            self.fail(f"{what}: uri must be a string")
        if uri.startswith("data:"):
            if len(uri) > LIMITS["file_bytes"] * 4 // 3 + 64:
                self.fail(f"{what}: data URI over the limit of {LIMITS['file_bytes']} bytes")
            try:
                return base64.b64decode(uri.split(",", 1)[1], validate=False)
            except (ValueError, IndexError):
                self.fail(f"{what}: malformed data URI {uri[:40]!r}")
        if self.base is None:
            self.fail(f"{what}: external file {uri[:60]!r} cannot be resolved (no folder)")
        try:
            path = contained(self.base, unquote(uri), what=f"{what} uri", error=GltfError)
            data = read_bounded(
                path, limit=LIMITS["file_bytes"], what=f"{what} file", error=GltfError
            )
        except GltfError as exc:
            self.fail(str(exc))
        self.files.append((path.name, data))
        return data

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            buf = self.doc.buffers[i]
            if buf.uri is None:
                if self.blob is None:
                    self.fail(f"buffer {i} has no uri and the file has no binary chunk")
                self._buffers[i] = self.blob
            else:
                self._buffers[i] = self.uri_bytes(buf.uri, f"buffer {i}")
            length = _int(self, buf.byteLength, f"buffer {i} byteLength", 0)
            have = len(self._buffers[i])
            if length > have:
                self.fail(f"buffer {i} byteLength {length} is past its {have} bytes")
        return self._buffers[i]

    def view_bytes(self, i: int) -> tuple[bytes, int | None]:
        """Buffer view ``i``'s bytes and its stride (None: tightly packed)."""
        if not 0 <= i < len(self.doc.bufferViews or []):
            self.fail(f"buffer view {i} does not exist")
        view = self.doc.bufferViews[i]
        where = f"buffer view {i}"
        b = _index(self, view.buffer, self.doc.buffers, f"{where} buffer")
        data = self.buffer(b)
        start = _int(self, view.byteOffset or 0, f"{where} byteOffset", 0)
        length = _int(self, view.byteLength, f"{where} byteLength", 0)
        stride = view.byteStride
        if stride is not None:
            stride = _int(self, stride, f"{where} byteStride", 4, 252)
        if start + length > len(data):
            self.fail(f"{where} reads past the end of buffer {b}")
        return data[start : start + length], stride

    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as a float64 or integer array ``(count, width)``."""
        acc = self.doc.accessors[_index(self, i, self.doc.accessors, "accessor")]
        if acc.sparse is not None:
            self.fail(f"accessor {i} is sparse (not supported)")
        width = _WIDTH.get(acc.type) if isinstance(acc.type, str) else None
        kind = acc.componentType
        if isinstance(kind, bool) or kind not in _COMPONENTS or width is None:
            self.fail(f"accessor {i} has an unsupported type {acc.type}/{acc.componentType}")
        dtype = np.dtype(_COMPONENTS[kind]).newbyteorder("<")
        item = dtype.itemsize * width
        count = _int(self, acc.count, f"accessor {i} count", 0)
        if count * item > LIMITS["accessor_bytes"]:
            self.fail(
                f"accessor {i} spans {count * item:,} bytes, over the limit of "
                f"{LIMITS['accessor_bytes']:,}"
            )
        if acc.bufferView is None:
            return np.zeros((count, width), dtype=dtype)
        data, stride = self.view_bytes(_index(self, acc.bufferView, self.doc.bufferViews, "view"))
        if stride is not None and stride < item:
            self.fail(f"accessor {i}: its view's byteStride {stride} is below its {item} bytes")
        stride = stride or item
        offset = _int(self, acc.byteOffset or 0, f"accessor {i} byteOffset", 0)
        need = offset + stride * (count - 1) + item if count else 0
        if need > len(data):
            self.fail(f"accessor {i} reads past the end of its buffer view")
        if count == 0:
            return np.zeros((0, width), dtype=dtype)
        raw = np.frombuffer(data, dtype=np.uint8, count=need - offset, offset=offset)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(count, item), strides=(stride, 1))
        out = np.ascontiguousarray(rows).view(dtype).reshape(count, width)
        if acc.normalized and dtype.kind in "iu":
            scale = float(np.iinfo(dtype).max)
            return np.maximum(out.astype(np.float64) / scale, -1.0)
        return out


def _int(d: _Doc, value, what: str, lo: int = 0, hi: int | None = None) -> int:
    """``value`` as an integer in ``[lo, hi]``, else one line naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, int):
        d.fail(f"{what} must be an integer, got {type(value).__name__}")
    if value < lo or (hi is not None and value > hi):
        d.fail(f"{what} is {value}, out of range [{lo}, {'...' if hi is None else hi}]")
    return value


def _index(d: _Doc, value, seq, what: str) -> int:
    """``value`` as an index into ``seq`` (negative indices refused)."""
    return _int(d, value, f"{what} index", 0, len(seq or []) - 1)


def _numbers(d: _Doc, value, n: int, what: str, bound: float, lo: float | None = None):
    """``value`` as ``n`` finite numbers of magnitude at most ``bound`` (at least ``lo``)."""
    if not isinstance(value, list | tuple) or len(value) != n:
        d.fail(f"{what} must be a list of {n} numbers")
    out = []
    for c in value:
        if isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c):
            d.fail(f"{what} must hold finite numbers, got {c!r}")
        if abs(c) > bound or (lo is not None and c < lo):
            d.fail(f"{what} holds {c!r}, out of range [{-bound if lo is None else lo}, {bound}]")
        out.append(float(c))
    return out


def _number(d: _Doc, value, what: str, lo: float, hi: float, *, open_lo=False) -> float:
    """``value`` as a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    bad = isinstance(value, bool) or not isinstance(value, int | float)
    if bad or not math.isfinite(value) or not lo <= value <= hi or (open_lo and value == lo):
        low = "(" if open_lo else "["
        d.fail(f"{what} is {value!r}; expected a finite number in {low}{lo:g}, {hi:g}]")
    return float(value)


def _node_matrix(node, d: _Doc | None = None, where: str = "node") -> np.ndarray:
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


def _check_trs(d: _Doc, node, where: str) -> None:
    """A node's matrix or TRS: finite numbers within :data:`LIMITS` (scale, coordinate)."""
    big, far = LIMITS["scale"], LIMITS["coordinate"]
    if node.matrix is not None:
        m = _numbers(d, node.matrix, 16, f"{where} matrix", max(big, far))
        if max(abs(c) for c in m[:12]) > big:
            d.fail(f"{where} matrix has an entry over {big:g} in magnitude (the scale limit)")
    if node.rotation is not None:
        _numbers(d, node.rotation, 4, f"{where} rotation", 1.0 + 1e-3)
    if node.scale is not None:
        _numbers(d, node.scale, 3, f"{where} scale", big)
    if node.translation is not None:
        _numbers(d, node.translation, 3, f"{where} translation", far)


def _walk(d: _Doc) -> list[tuple[int, np.ndarray]]:
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


def _check_extensions(d: _Doc) -> None:
    used = set(d.doc.extensionsUsed or []) | set(d.doc.extensionsRequired or [])
    bad = sorted(used - set(SUPPORTED_EXTENSIONS))
    if bad:
        d.fail(
            f"glTF extension {', '.join(bad)} is not supported (only "
            f"{', '.join(SUPPORTED_EXTENSIONS)}; extensions that change shading or geometry "
            "are refused, never dropped)"
        )


def _image(d: _Doc, index: int) -> np.ndarray:
    """Image ``index`` as (H, W, 3) float64 values in [0, 1] (alpha dropped)."""
    from PIL import Image

    img = d.doc.images[_index(d, index, d.doc.images, "image")]
    if img.uri is not None:
        data = d.uri_bytes(img.uri, f"image {index}")
    elif img.bufferView is not None:
        data = d.view_bytes(_index(d, img.bufferView, d.doc.bufferViews, "buffer view"))[0]
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
                rgb = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
    except GltfError:
        raise
    except (Image.DecompressionBombWarning, Image.DecompressionBombError):
        d.fail(f"image {index} is over the limit of {limit:,} pixels")
    except Exception as exc:  # Pillow raises many types for undecodable data
        d.fail(f"image {index} cannot be decoded: {exc}")
    return rgb


class _Textures:
    """Textures by (glTF texture, colour space), built on first use."""

    def __init__(self, d: _Doc):
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
            tex = d.doc.textures[_index(d, info.index, d.doc.textures, f"{what} texture")]
            if tex.source is None:
                d.fail(f"texture {info.index} has no image source")
            wrap, nearest = "repeat", False
            if tex.sampler is not None:
                smp = d.doc.samplers[_index(d, tex.sampler, d.doc.samplers, "sampler")]
                ws, wt = smp.wrapS or 10497, smp.wrapT or 10497
                if ws != wt or ws not in _WRAP:
                    d.fail(
                        f"sampler {tex.sampler} has wrapS {ws} and wrapT {wt}; "
                        "one wrap mode for both is supported"
                    )
                wrap, nearest = _WRAP[ws], smp.magFilter == 9728
            rgb = _image(d, tex.source)
            img = srgb_to_linear(rgb) if srgb else rgb
            name = f"texture {info.index} ({'sRGB' if srgb else 'linear'})"
            self.index[key] = len(self.items)
            self.items.append(Texture(img.astype(np.float32), wrap, nearest, name, srgb))
        return self.index[key]


def _material(d: _Doc, index: int | None, textures: _Textures) -> PbrMaterial:
    if index is None:
        return PbrMaterial(name="default")
    mat = d.doc.materials[_index(d, index, d.doc.materials, "material")]
    label = f"material {index} ({mat.name or 'unnamed'})"
    if (mat.alphaMode or "OPAQUE") != "OPAQUE":
        d.fail(f"{label} has alphaMode {mat.alphaMode}; only OPAQUE is supported")
    ext = dict(mat.extensions or {})
    es = ext.pop("KHR_materials_emissive_strength", {})
    strength = _number(d, es.get("emissiveStrength", 1.0), f"{label} emissiveStrength", 0, 1e6)
    if ext:
        d.fail(f"{label} uses extension {', '.join(sorted(ext))}, which is not supported")
    pbr = mat.pbrMetallicRoughness
    base = pbr.baseColorFactor if pbr and pbr.baseColorFactor is not None else [1.0] * 4
    base = _numbers(d, base, 4, f"{label} baseColorFactor", 1.0, lo=0.0)
    emissive = _numbers(d, mat.emissiveFactor or [0.0] * 3, 3, f"{label} emissiveFactor", 1.0, 0.0)
    metallic = pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0
    rough = pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0
    normal = mat.normalTexture
    scale = normal.scale if normal is not None and normal.scale is not None else 1.0
    return PbrMaterial(
        name=mat.name or f"material_{index}",
        base_color=tuple(base[:3]),
        metallic=_number(d, metallic, f"{label} metallicFactor", 0.0, 1.0),
        roughness=_number(d, rough, f"{label} roughnessFactor", 0.0, 1.0),
        emissive=tuple(strength * c for c in emissive),
        normal_scale=_number(d, scale, f"{label} normalTexture scale", -1e3, 1e3),
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


def _attribute(d: _Doc, index, n: int, width: int, what: str) -> np.ndarray:
    """A vertex attribute: ``n`` rows of ``width`` finite values (float64); an empty NORMAL
    or TEXCOORD_0 (the project's own exports write one for a mesh without) stays empty."""
    a = d.accessor(index).astype(np.float64)
    if a.shape == (0, width) and width != 4:
        return a
    if a.shape != (n, width) or not np.isfinite(a).all():
        d.fail(f"{what} must be {n} finite rows of {width} (got {a.shape[0]}x{a.shape[1]})")
    return a


def _primitive_mesh(d: _Doc, prim, world: np.ndarray, label: str) -> dict:
    mode = 4 if prim.mode is None else prim.mode
    if mode != 4:
        d.fail(f"{label} has primitive mode {_MODES.get(mode, mode)}; only TRIANGLES is supported")
    attrs = {k: v for k, v in vars(prim.attributes).items() if v is not None}
    for bad, why in (("COLOR_0", "vertex colours"), ("JOINTS_0", "skinning")):
        if bad in attrs:
            d.fail(f"{label} has {bad} ({why}), which is not supported")
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
    return entry


def _camera_entry(d, cam_index, world, width, height, verts) -> dict:
    cam = d.doc.cameras[cam_index]
    world = world.copy()
    norms = np.linalg.norm(world[:3, :3], axis=0)
    if not (norms > 1e-12).all():
        d.fail(f"camera {cam_index}'s node has a degenerate transform (zero scale)")
    world[:3, :3] /= norms  # a camera node's scale is not a zoom: the frame alone counts
    to_world = world @ _GL_TO_MI
    film = {"type": "hdrfilm", "width": int(width), "height": int(height)}
    film.update({"rfilter": {"type": "box"}, "component_format": "float32"})
    eye = world[:3, 3]
    reach = float(np.max(np.linalg.norm(verts - eye, axis=1))) if len(verts) else 1.0
    where, far_limit = f"camera {cam_index}", LIMITS["coordinate"] * 4
    if cam.type == "orthographic" and cam.orthographic is not None:
        o = cam.orthographic
        ymag = _number(d, o.ymag, f"{where} ymag", 0.0, far_limit, open_lo=True)
        s = ymag * width / height
        to_world = to_world @ np.diag([s, s, 1.0, 1.0])
        near = _number(d, o.znear, f"{where} znear", 0.0, far_limit)
        far = _number(d, o.zfar, f"{where} zfar", 0.0, far_limit, open_lo=True)
        entry = {"type": "orthographic"}
    elif cam.type == "perspective" and cam.perspective is not None:
        p = cam.perspective
        yfov = _number(d, p.yfov, f"{where} yfov", 0.0, math.pi, open_lo=True)
        fov_x = math.degrees(2.0 * math.atan(width / height * math.tan(yfov / 2.0)))
        if not 0.0 < fov_x < 180.0 or yfov >= math.pi:
            d.fail(f"{where} yfov {yfov!r} gives no usable field of view")
        near = _number(d, p.znear, f"{where} znear", 0.0, far_limit, open_lo=True)
        if p.zfar is not None:
            far = _number(d, p.zfar, f"{where} zfar", 0.0, far_limit, open_lo=True)
        else:
            far = 1.01 * reach + near
        entry = {"type": "perspective", "fov": fov_x, "fov_axis": "x"}
    else:
        d.fail(f"camera {cam_index} has type {cam.type!r}; perspective or orthographic")
    if not (0 < near < far and np.isfinite(to_world).all()):
        d.fail(f"camera {cam_index} has near {near} and far {far}; need 0 < near < far")
    entry.update({"near_clip": near, "far_clip": far, "to_world": to_world, "film": film})
    return entry


def _light_entry(d: _Doc, index: int, world: np.ndarray) -> tuple[dict, dict]:
    lights = (d.doc.extensions or {}).get("KHR_lights_punctual", {}).get("lights", [])
    if not 0 <= index < len(lights):
        d.fail(f"KHR_lights_punctual light {index} does not exist")
    lt = lights[index]
    if not isinstance(lt, dict):
        d.fail(f"KHR_lights_punctual light {index} must be an object")
    kind = lt.get("type")
    where = f"KHR_lights_punctual light {index}"
    intensity = _number(d, lt.get("intensity", 1.0), f"{where} intensity", 0.0, 1e12)
    color = _numbers(d, lt.get("color", [1.0, 1.0, 1.0]), 3, f"{where} color", 1e3, lo=0.0)
    rgb = [c * intensity for c in color]
    d_axis = -world[:3, 2]
    if not np.linalg.norm(d_axis) > 0:
        d.fail(f"{where}: its node's transform has no direction (zero scale)")
    pos = world[:3, 3]
    rng = lt.get("range")
    rng = 0.0 if rng is None else _number(d, rng, f"{where} range", 0.0, 1e12, open_lo=True)
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
        inner = _number(d, spot.get("innerConeAngle", 0.0), f"{where} innerConeAngle", 0, 2)
        outer = _number(d, spot.get("outerConeAngle", math.pi / 4), f"{where} outer", 0, 2)
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


#: Integer fields of the arrays that address bytes, checked in the JSON (pygltflib would
#: coerce 4.5 or "12"); node transforms are checked to be lists of JSON numbers alike.
_INTEGER_FIELDS = {
    "accessors": ("bufferView", "byteOffset", "componentType", "count"),
    "bufferViews": ("buffer", "byteOffset", "byteLength", "byteStride"),
    "buffers": ("byteLength",),
    "images": ("bufferView",),
    "nodes": ("mesh", "camera", "skin"),
}


def _check_integers(doc, label: str) -> None:
    """The fields of :data:`_INTEGER_FIELDS` are JSON integers where given, node transforms
    lists of JSON numbers."""
    if not isinstance(doc, dict):
        raise GltfError(f"{label}: the glTF JSON must be an object")
    for array, fields in _INTEGER_FIELDS.items():
        items = doc.get(array, [])
        if not isinstance(items, list):
            raise GltfError(f"{label}: {array} must be a list")
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise GltfError(f"{label}: {array}[{i}] must be an object")
            for f in fields:
                v = item.get(f)
                if v is not None and (isinstance(v, bool) or not isinstance(v, int)):
                    raise GltfError(f"{label}: {array}[{i}].{f} must be an integer, got {v!r}")
    asset = doc.get("asset")
    if not isinstance(asset, dict) or not isinstance(asset.get("version"), str):
        raise GltfError(f"{label}: no asset.version (a glTF 2.0 file has one)")
    _check_sizes(doc, label)
    for i, node in enumerate(doc.get("nodes", [])):
        for f in ("matrix", "rotation", "scale", "translation"):
            if not _all(node.get(f), (int, float)):
                raise GltfError(f"{label}: nodes[{i}].{f} must be a list of numbers")
        if not _all(node.get("children"), (int,)):
            raise GltfError(f"{label}: nodes[{i}].children must be a list of node indices")
    for i, scene in enumerate(_list(doc.get("scenes"))):
        if not isinstance(scene, dict) or not _all(scene.get("nodes"), (int,)):
            raise GltfError(f"{label}: scenes[{i}].nodes must be a list of node indices")
    for i, cam in enumerate(_list(doc.get("cameras"))):
        for kind in ("perspective", "orthographic"):
            fields = cam.get(kind) if isinstance(cam, dict) else None
            if fields is not None and not (
                isinstance(fields, dict) and _all(list(fields.values()), (int, float, dict))
            ):
                raise GltfError(f"{label}: cameras[{i}].{kind} fields must be numbers")


def _check_sizes(doc: dict, label: str) -> None:
    """Array lengths and the node hierarchy's depth, on the raw JSON (before pygltflib spends
    seconds on 20,000 nodes): at most :data:`LIMITS` ``nodes`` nodes and ``arrays`` entries
    in any other top-level array, children ``depth`` deep (cycles are found later)."""
    for key, items in doc.items():
        top = LIMITS["nodes"] if key == "nodes" else LIMITS["arrays"]
        if isinstance(items, list) and len(items) > top:
            raise GltfError(f"{label}: {len(items):,} {key}, over the limit of {top:,}")
    nodes = _list(doc.get("nodes"))
    depth = [0] * len(nodes)
    children = [_list(n.get("children")) if isinstance(n, dict) else [] for n in nodes]
    has_parent = {c for kids in children for c in kids if isinstance(c, int)}
    stack = [(i, 1) for i in range(len(nodes)) if i not in has_parent]
    while stack:
        i, level = stack.pop()
        if not (isinstance(i, int) and 0 <= i < len(nodes)) or depth[i] >= level:
            continue  # bad indices and cycles: named when the hierarchy is walked
        if level > LIMITS["depth"]:
            raise GltfError(f"{label}: node hierarchy deeper than {LIMITS['depth']} (the limit)")
        depth[i] = level
        stack.extend((c, level + 1) for c in children[i])


def _list(value) -> list:
    return value if isinstance(value, list) else []


def _all(value, types: tuple) -> bool:
    """None, or a list of JSON values of ``types`` (booleans are no numbers)."""
    if value is None:
        return True
    return isinstance(value, list) and all(
        isinstance(c, types) and not isinstance(c, bool) for c in value
    )


def _check_container(data: bytes, label: str) -> None:
    """A GLB's header and chunk lengths (version 2, lengths within the file), or a glTF
    JSON's syntax (strict JSON, bounded nesting), before pygltflib sees the bytes."""
    if data[:4] != b"glTF":
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            raise GltfError(f"{label}: neither a GLB nor UTF-8 glTF JSON") from None
        _check_integers(loads_json(text, what=label, error=GltfError), label)
        return
    if len(data) < 20:
        raise GltfError(f"{label}: GLB shorter than its 12-byte header and a chunk")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise GltfError(f"{label}: GLB version {version} (only version 2 is read)")
    if length != len(data):
        raise GltfError(f"{label}: GLB header says {length} bytes, the file has {len(data)}")
    at, kinds = 12, []
    while at < len(data):
        if at + 8 > len(data):
            raise GltfError(f"{label}: GLB chunk header at byte {at} runs past the end")
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > len(data):
            raise GltfError(f"{label}: GLB chunk at byte {at} ({size} bytes) runs past the end")
        kinds.append(kind)
        if kind == 0x4E4F534A:  # JSON
            chunk = data[at + 8 : at + 8 + size]
            try:
                text = chunk.decode("utf-8")
                _check_integers(loads_json(text, what=f"{label} JSON", error=GltfError), label)
            except UnicodeDecodeError:
                raise GltfError(f"{label}: GLB JSON chunk is not UTF-8") from None
        at += 8 + size
    if not kinds or kinds[0] != 0x4E4F534A or kinds.count(0x004E4942) > 1:
        raise GltfError(f"{label}: GLB must start with a JSON chunk and hold at most one BIN")


def _read(scene, label: str) -> tuple[_Doc, bytes]:
    """The document of a path or of GLB/glTF bytes, and the bytes hashed for it."""
    import pygltflib

    if isinstance(scene, bytes):
        data, base = scene, None
    else:
        path = Path(scene)
        if not path.exists():
            raise GltfError(f"scene file not found: {path}")
        data = read_bounded(path, limit=LIMITS["file_bytes"], what="glTF", error=GltfError)
        base = path.resolve().parent
    _check_container(data, label)
    try:
        with warnings.catch_warnings():
            # dataclasses_json warns on optional fields glTF leaves out (an image's uri)
            warnings.filterwarnings(
                "ignore", message=".*non-optional type", category=RuntimeWarning
            )
            if data[:4] == b"glTF":
                doc = pygltflib.GLTF2.load_from_bytes(data)
                blob = doc.binary_blob()
            else:
                doc = pygltflib.GLTF2.gltf_from_json(data.decode("utf-8"))
                blob = None
    except Exception as exc:  # pygltflib raises many types on malformed input
        raise GltfError(f"{label}: not a readable glTF 2.0 file ({exc})") from None
    if not str(getattr(doc.asset, "version", "2.0")).startswith("2."):
        raise GltfError(f"{label}: glTF version {doc.asset.version} (only 2.x is read)")
    return _Doc(doc, base, blob, label), data


def gltf_input(
    scene, *, width=None, height=None, camera: int | None = None, name=None
) -> GltfInput:
    """Read a glTF scene (a path, or GLB/glTF bytes written by the project's own code).

    Parameters
    ----------
    scene : path of a ``.gltf``/``.glb`` file, or its bytes.
    width, height : film size; default 160 wide and high as the camera's ``aspectRatio``.
    camera : index into the document's ``cameras`` (default: the first camera node).
    name : the scene's name (default: the file's stem).

    Raises
    ------
    GltfError
        Malformed file or an unsupported feature (named).
    """
    label = name or (Path(scene).name if not isinstance(scene, bytes) else "glTF")
    d, data = _read(scene, label)
    try:
        return _scene_input(d, data, scene, width=width, height=height, camera=camera, name=name)
    except (IndexError, KeyError, TypeError, AttributeError, ValueError, OverflowError) as exc:
        if isinstance(exc, GltfError):
            raise
        # an index or field the document names does not exist or has the wrong type
        raise GltfError(f"{label}: malformed glTF ({type(exc).__name__}: {exc})") from None


def _scene_input(d: _Doc, data: bytes, scene, *, width, height, camera, name) -> GltfInput:
    label = d.label
    _check_extensions(d)
    doc = d.doc
    nodes = _walk(d)
    textures = _Textures(d)
    materials: list[PbrMaterial] = []
    mat_index: dict = {}
    raw: dict = {"type": "scene"}
    shape_materials, light_records, keys = {}, {}, set()
    cams = [(n, w) for n, w in nodes if doc.nodes[n].camera is not None]

    next_k: dict = {}

    def key_for(base: str) -> str:
        key, k = _safe(base), next_k.get(_safe(base), 1)
        while key in keys or key in ("type", "camera"):
            key, k = f"{_safe(base)}_{k}", k + 1
        next_k[_safe(base)] = k
        keys.add(key)
        return key

    for n, world in nodes:
        node = doc.nodes[n]
        if node.skin is not None:
            d.fail(f"node {n} ({node.name or 'unnamed'}) is skinned, which is not supported")
        light = (node.extensions or {}).get("KHR_lights_punctual")
        if light is not None:
            entry, record = _light_entry(d, int(light.get("light", -1)), world)
            key = key_for(node.name or f"light_{n}")
            raw[key], light_records[key] = entry, record
        if node.mesh is None:
            continue
        mesh = doc.meshes[_index(d, node.mesh, doc.meshes, f"node {n} mesh")]
        prims = mesh.primitives or []
        for p, prim in enumerate(prims):
            base = node.name or mesh.name or f"node_{n}"
            label_p = f"mesh {node.mesh} ({mesh.name or 'unnamed'}) primitive {p}"
            entry = _primitive_mesh(d, prim, world, label_p)
            if prim.material not in mat_index:
                mat_index[prim.material] = len(materials)
                materials.append(_material(d, prim.material, textures))
            mat = materials[mat_index[prim.material]]
            entry["bsdf"] = diffuse(mat.base_color)  # Mitsuba's view (the G-buffer's is ours)
            key = key_for(base if len(prims) == 1 else f"{base}_{p}")
            raw[key], shape_materials[key] = entry, mat_index[prim.material]
    if not shape_materials:
        d.fail("the scene has no triangle mesh")
    if camera is not None:
        if not 0 <= camera < len(doc.cameras or []):
            d.fail(f"camera {camera} out of range: the file has {len(doc.cameras or [])} camera(s)")
        cams = [(n, w) for n, w in cams if doc.nodes[n].camera == camera]
        if not cams:
            d.fail(f"camera {camera} is not placed in the scene by any node")
    if not cams:
        d.fail("the scene has no camera node; add one (perspective or orthographic)")
    cam_node, cam_world = cams[0]
    cam_index = _index(d, doc.nodes[cam_node].camera, doc.cameras, f"node {cam_node} camera")
    gl_cam = doc.cameras[cam_index]
    aspect = getattr(gl_cam.perspective, "aspectRatio", None)
    if aspect is not None:
        aspect = _number(d, aspect, f"camera {cam_index} aspectRatio", 0.0, 1e9, open_lo=True)
    film = (gl_cam.extras or {}).get("film_size") if isinstance(gl_cam.extras, dict) else None
    top = LIMITS["film_pixels"]
    if film and not (width or height):  # an export's size (scenes.formats.gltf_write's extras)
        if not isinstance(film, list) or len(film) != 2:
            d.fail(f"camera {cam_index} extras film_size must be [width, height]")
        width, height = (_int(d, v, f"camera {cam_index} film_size", 1, top) for v in film)
    w = int(width or DEFAULT_WIDTH)
    h = int(height or (round(w / aspect) if aspect and not width else DEFAULT_HEIGHT))
    if not 1 <= h <= top:
        d.fail(f"camera {cam_index} aspectRatio {aspect!r} gives a film {w}x{h} (1 to {top} px)")
    verts = np.concatenate([e["vertices"] for k, e in raw.items() if k in shape_materials])
    cam_entry = _camera_entry(d, cam_index, cam_world, w, h, verts.astype(np.float64))
    raw = {"type": "scene", "camera": cam_entry, **{k: v for k, v in raw.items() if k != "type"}}
    digest = hashlib.sha256(b"gltf:" + data)
    for fname, fbytes in d.files:
        digest.update(fname.encode() + fbytes)
    digest.update(f"camera:{cam_index}".encode())
    stem = name or (Path(scene).stem if not isinstance(scene, bytes) else "gltf")
    source = str(Path(scene).resolve()) if not isinstance(scene, bytes) else "builtin"
    return GltfInput(
        name=stem,
        source=source,
        description=f"glTF scene {label}",
        raw=raw,
        digest=digest,
        light_records=light_records,
        shape_materials=shape_materials,
        materials=materials,
        textures=textures.items,
    )


def gltf_scene(scene, builtin: dict, *, width=None, height=None, camera=None):
    """The :class:`GltfInput` of ``scene`` when it is a glTF file or a built-in glTF scene
    (``builtin``: the catalogue, whose glTF entries have ``kind == "gltf"`` and a factory
    returning GLB bytes), else None (another kind of scene: ``camera`` must then be None).

    Raises
    ------
    GltfError
        A glTF scene that cannot be read, or ``camera`` given for another kind of scene.
    """
    name = getattr(scene, "name", None) if not isinstance(scene, str | Path) else None
    spec = scene if name is not None else builtin.get(str(scene))
    if spec is not None and getattr(spec, "kind", "mitsuba") == "gltf":
        w, h = int(width or spec.width), int(height or spec.height)
        gl = gltf_input(spec.factory(w, h), width=w, height=h, camera=camera, name=spec.name)
        gl.description = spec.description
        return gl
    if is_gltf(scene):
        return gltf_input(scene, width=width, height=height, camera=camera)
    if camera is not None:
        label = spec.name if spec is not None else scene
        raise GltfError(
            f"camera {camera}: choosing a camera applies to glTF scenes only, not {label}"
        )
    return None
