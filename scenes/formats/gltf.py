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
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

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
        self.files: list[Path] = []

    def fail(self, what: str):
        raise GltfError(f"{self.label}: {what}")

    def uri_bytes(self, uri: str) -> bytes:
        if uri.startswith("data:"):
            try:
                return base64.b64decode(uri.split(",", 1)[1])
            except (ValueError, IndexError):
                self.fail(f"malformed data URI {uri[:40]!r}")
        if self.base is None:
            self.fail(f"external file {uri!r} cannot be resolved (no folder)")
        path = (self.base / uri).resolve()
        if not path.is_file():
            self.fail(f"referenced file not found: {path}")
        self.files.append(path)
        return path.read_bytes()

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            buf = self.doc.buffers[i]
            if buf.uri is None:
                if self.blob is None:
                    self.fail(f"buffer {i} has no uri and the file has no binary chunk")
                self._buffers[i] = self.blob
            else:
                self._buffers[i] = self.uri_bytes(buf.uri)
        return self._buffers[i]

    def view_bytes(self, i: int) -> tuple[bytes, int | None]:
        """Buffer view ``i``'s bytes and its stride (None: tightly packed)."""
        if not 0 <= i < len(self.doc.bufferViews or []):
            self.fail(f"buffer view {i} does not exist")
        view = self.doc.bufferViews[i]
        data = self.buffer(view.buffer)
        start = view.byteOffset or 0
        if start + view.byteLength > len(data):
            self.fail(f"buffer view {i} reads past the end of buffer {view.buffer}")
        return data[start : start + view.byteLength], view.byteStride

    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as a float64 or integer array ``(count, width)``."""
        acc = self.doc.accessors[i]
        if acc.sparse is not None:
            self.fail(f"accessor {i} is sparse (not supported)")
        dtype = np.dtype(_COMPONENTS.get(acc.componentType, np.float32)).newbyteorder("<")
        width = _WIDTH.get(acc.type)
        if acc.componentType not in _COMPONENTS or width is None:
            self.fail(f"accessor {i} has an unsupported type {acc.type}/{acc.componentType}")
        if acc.bufferView is None:
            return np.zeros((acc.count, width), dtype=dtype)
        data, stride = self.view_bytes(acc.bufferView)
        item = dtype.itemsize * width
        stride = stride or item
        offset = acc.byteOffset or 0
        need = offset + stride * (acc.count - 1) + item if acc.count else 0
        if need > len(data):
            self.fail(f"accessor {i} reads past the end of its buffer view")
        raw = np.frombuffer(data, dtype=np.uint8, count=need - offset, offset=offset)
        rows = np.lib.stride_tricks.as_strided(raw, shape=(acc.count, item), strides=(stride, 1))
        out = np.ascontiguousarray(rows).view(dtype).reshape(acc.count, width)
        if acc.normalized and dtype.kind in "iu":
            scale = float(np.iinfo(dtype).max)
            return np.maximum(out.astype(np.float64) / scale, -1.0)
        return out


def _node_matrix(node) -> np.ndarray:
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


def _walk(d: _Doc) -> list[tuple[int, np.ndarray]]:
    """(node index, world matrix) of every node of the scene, depth first, parents first."""
    doc = d.doc
    scenes = doc.scenes or []
    if not scenes:
        roots = list(range(len(doc.nodes or [])))
    else:
        index = doc.scene if doc.scene is not None else 0
        if not 0 <= index < len(scenes):
            d.fail(f"scene index {index} out of range ({len(scenes)} scenes)")
        roots = list(scenes[index].nodes or [])
    out, stack, seen = [], [(r, np.eye(4)) for r in reversed(roots)], set()
    while stack:
        i, parent = stack.pop()
        if not 0 <= i < len(doc.nodes) or i in seen:
            d.fail(f"node hierarchy is not a tree (node {i})")
        seen.add(i)
        world = parent @ _node_matrix(doc.nodes[i])
        out.append((i, world))
        stack.extend((c, world) for c in reversed(doc.nodes[i].children or []))
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

    img = d.doc.images[index]
    if img.uri is not None:
        data = d.uri_bytes(img.uri)
    elif img.bufferView is not None:
        data = d.view_bytes(img.bufferView)[0]
    else:
        d.fail(f"image {index} has neither uri nor bufferView")
    try:
        with Image.open(io.BytesIO(data)) as im:
            rgb = np.asarray(im.convert("RGB"), dtype=np.float64) / 255.0
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
            tex = d.doc.textures[info.index]
            if tex.source is None:
                d.fail(f"texture {info.index} has no image source")
            wrap, nearest = "repeat", False
            if tex.sampler is not None:
                smp = d.doc.samplers[tex.sampler]
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
    mat = d.doc.materials[index]
    label = f"material {index} ({mat.name or 'unnamed'})"
    if (mat.alphaMode or "OPAQUE") != "OPAQUE":
        d.fail(f"{label} has alphaMode {mat.alphaMode}; only OPAQUE is supported")
    ext = dict(mat.extensions or {})
    strength = float(ext.pop("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0))
    if ext:
        d.fail(f"{label} uses extension {', '.join(sorted(ext))}, which is not supported")
    pbr = mat.pbrMetallicRoughness
    base = list(pbr.baseColorFactor) if pbr and pbr.baseColorFactor else [1.0] * 4
    normal = mat.normalTexture
    return PbrMaterial(
        name=mat.name or f"material_{index}",
        base_color=tuple(float(c) for c in base[:3]),
        metallic=float(pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0),
        roughness=float(pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0),
        emissive=tuple(strength * float(c) for c in (mat.emissiveFactor or [0.0, 0.0, 0.0])),
        normal_scale=float(normal.scale if normal is not None and normal.scale is not None else 1),
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
    pos = d.accessor(attrs["POSITION"]).astype(np.float64)
    v = pos @ world[:3, :3].T + world[:3, 3]
    if prim.indices is not None:
        idx = d.accessor(prim.indices).astype(np.int64).ravel()
    else:
        idx = np.arange(len(v))
    if len(idx) % 3 or (len(idx) and (idx.min() < 0 or idx.max() >= len(v))):
        d.fail(f"{label} has {len(idx)} indices, not whole triangles within its vertices")
    entry = {"type": "ro_mesh", "vertices": v.astype(np.float32)}
    entry["faces"] = idx.reshape(-1, 3).astype(np.uint32)
    lin = world[:3, :3]
    if "NORMAL" in attrs:
        nrm = d.accessor(attrs["NORMAL"]).astype(np.float64) @ np.linalg.inv(lin)
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        entry["normals"] = (nrm / np.where(length > 0, length, 1.0)).astype(np.float32)
    if "TEXCOORD_0" in attrs:
        entry["texcoords"] = d.accessor(attrs["TEXCOORD_0"]).astype(np.float32)
    tangents = np.zeros((len(v), 4), np.float32)
    if "TANGENT" in attrs:
        t = d.accessor(attrs["TANGENT"]).astype(np.float64)
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
    if cam.type == "orthographic" and cam.orthographic is not None:
        o = cam.orthographic
        s = float(o.ymag) * width / height
        to_world = to_world @ np.diag([s, s, 1.0, 1.0])
        near, far = float(o.znear), float(o.zfar)
        entry = {"type": "orthographic"}
    elif cam.type == "perspective" and cam.perspective is not None:
        p = cam.perspective
        fov_x = math.degrees(2.0 * math.atan(width / height * math.tan(float(p.yfov) / 2.0)))
        near = float(p.znear)
        far = float(p.zfar) if p.zfar is not None else 1.01 * reach + near
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
    kind = lt.get("type")
    rgb = [float(c) * float(lt.get("intensity", 1.0)) for c in lt.get("color", [1.0, 1.0, 1.0])]
    d_axis = -world[:3, 2]
    pos = world[:3, 3]
    rng = float(lt.get("range") or 0.0)
    if kind == "directional":
        entry = {"type": "directional", "direction": [float(c) for c in d_axis]}
        return entry | {"irradiance": {"type": "rgb", "value": rgb}}, {"model": "gltf"}
    if kind == "point":
        entry = {"type": "point", "position": [float(c) for c in pos]}
        return entry | {"intensity": {"type": "rgb", "value": rgb}}, {"model": "gltf", "range": rng}
    if kind == "spot":
        spot = lt.get("spot", {})
        inner = float(spot.get("innerConeAngle", 0.0))
        outer = float(spot.get("outerConeAngle", math.pi / 4))
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


def _read(scene, label: str) -> tuple[_Doc, bytes]:
    """The document of a path or of GLB/glTF bytes, and the bytes hashed for it."""
    import pygltflib

    if isinstance(scene, bytes):
        data, base = scene, None
    else:
        path = Path(scene)
        if not path.is_file():
            raise GltfError(f"scene file not found: {path}")
        data, base = path.read_bytes(), path.resolve().parent
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
    except (IndexError, KeyError, TypeError, AttributeError, ValueError) as exc:
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

    def key_for(base: str) -> str:
        key, k = _safe(base), 1
        while key in keys or key in ("type", "camera"):
            key, k = f"{_safe(base)}_{k}", k + 1
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
        mesh = doc.meshes[node.mesh]
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
    cam_index = doc.nodes[cam_node].camera
    gl_cam = doc.cameras[cam_index]
    aspect = getattr(gl_cam.perspective, "aspectRatio", None)
    film = (gl_cam.extras or {}).get("film_size") if isinstance(gl_cam.extras, dict) else None
    if film and not (width or height):  # an export's size (scenes.formats.gltf_write's extras)
        width, height = int(film[0]), int(film[1])
    w = int(width or DEFAULT_WIDTH)
    h = int(height or (round(w / aspect) if aspect and not width else DEFAULT_HEIGHT))
    verts = np.concatenate([e["vertices"] for k, e in raw.items() if k in shape_materials])
    cam_entry = _camera_entry(d, cam_index, cam_world, w, h, verts.astype(np.float64))
    raw = {"type": "scene", "camera": cam_entry, **{k: v for k, v in raw.items() if k != "type"}}
    digest = hashlib.sha256(b"gltf:" + data)
    for f in d.files:
        digest.update(f.name.encode() + f.read_bytes())
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
