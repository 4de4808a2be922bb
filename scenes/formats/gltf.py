"""Read a glTF 2.0 scene (``.gltf`` or ``.glb``) into the project's scene representation.

:func:`gltf_input` turns a glTF document (read with pygltflib) into a :class:`GltfInput`: a
Mitsuba scene dictionary (triangle meshes in world space with their normals, ``TEXCOORD_0``
and tangents, the camera as a Mitsuba sensor, the lights as Mitsuba emitters) that
:mod:`scenes.loader` loads as it loads a built-in scene, the glTF materials
(:class:`scenes.shading.materials.PbrMaterials`) and the KHR_lights_punctual attenuation
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
  normal textures; ``alphaMode`` MASK (the alpha test of :mod:`scenes.shading.alpha`, read
  by :mod:`.gltf_alpha`: alpha-tested shapes are cut out for every ray). Occlusion
  textures scale ambient light only, which these scenes do not
  have: they are read and have no effect.

The document is read and checked by :mod:`.gltf_document`, its nodes, meshes, materials,
camera and lights by :mod:`.gltf_parts`; this module assembles the scene.

Untrusted input (:mod:`scenes.base.untrusted`): the file and every external buffer or image
are read only when regular files of at most :data:`LIMITS` ``file_bytes``; an external ``uri``
must stay inside the glTF's own folder (no absolute path, no ``..``, no link out, no scheme
but ``data:``); a GLB's header and chunk lengths are checked (version 2 only); every index,
count, offset and stride is checked against what it points at; node matrices and TRS,
positions, light intensity, colour and range, camera ``yfov``, ``aspectRatio``, ``xmag``,
``ymag`` and clip planes must be finite and in range; the counts of :data:`LIMITS` (nodes,
hierarchy depth, mesh instances, vertices, triangles, image pixels, accessor bytes) are
enforced, naming the one exceeded.

Refused, with one line naming it: other primitive modes, ``alphaMode`` BLEND, vertex
colours, skins and morph targets, sparse accessors, texture coordinate sets other than 0,
different wrap modes in s and t, and every extension but KHR_lights_punctual and
KHR_materials_emissive_strength. Materials are shaded two-sided (back faces are not culled;
closed meshes are unaffected).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..shading.materials import PbrMaterial, PbrMaterials, diffuse
from .gltf_alpha import alpha_table, read_alpha
from .gltf_document import (
    LIMITS,
    GltfDocument,
    GltfError,
    as_index,
    as_int,
    as_number,
    read_document,
)
from .gltf_parts import (
    Textures,
    camera_entry,
    check_extensions,
    light_entry,
    primitive_mesh,
    read_material,
    walk_nodes,
)

__all__ = [
    "GLTF_SUFFIXES",
    "LIMITS",
    "GltfError",
    "GltfInput",
    "gltf_input",
    "gltf_scene",
    "is_gltf",
]

GLTF_SUFFIXES = (".gltf", ".glb")
#: Default film width of a glTF file (its height follows the camera's ``aspectRatio``).
DEFAULT_WIDTH = 160
DEFAULT_HEIGHT = 90


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
    #: per material slot: its alpha mask (glTF MASK, :mod:`.gltf_alpha`) or None (OPAQUE)
    alpha_masks: list = field(default_factory=list)

    def lights(self, lights: list) -> list:
        """The loaded lights with their KHR_lights_punctual attenuation."""
        return [replace(lt, **self.light_records.get(lt.name, {})) for lt in lights]

    def pbr(self, shape_names: list[str]) -> PbrMaterials:
        """The material table for shapes in loaded order."""
        table = np.array([self.shape_materials[n] for n in shape_names], dtype=np.int32)
        return PbrMaterials(list(self.materials), list(self.textures), table)

    def alpha(self, shape_names: list[str]):
        """The alpha-tested shapes' table (:class:`scenes.shading.alpha.AlphaTable`) for
        shapes in loaded order, or None when no material is ``MASK``."""
        return alpha_table(self.alpha_masks, self.shape_materials, shape_names)


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", text) or "x"


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
    d, data = read_document(scene, label)
    try:
        return _scene_input(d, data, scene, width=width, height=height, camera=camera, name=name)
    except (IndexError, KeyError, TypeError, AttributeError, ValueError, OverflowError) as exc:
        if isinstance(exc, GltfError):
            raise
        # an index or field the document names does not exist or has the wrong type
        raise GltfError(f"{label}: malformed glTF ({type(exc).__name__}: {exc})") from None


def _mask_reads_colour(d, alpha_masks: list, slot: int, label: str) -> None:
    """Material ``slot``'s mask reads ``COLOR_0``'s alpha (a primitive of ``label`` has one);
    a material that is not ``MASK`` is refused (vertex colours serve the alpha test only)."""
    mask = alpha_masks[slot]
    if mask is None:
        d.fail(
            f"{label} has COLOR_0 on a material that is not alphaMode MASK; "
            "vertex colours are read for the alpha test only"
        )
    alpha_masks[slot] = replace(mask, vertex_alpha=True)


def _colourless_alpha_one(raw: dict, shape_materials: dict, alpha_masks: list) -> None:
    """A mesh without ``COLOR_0`` whose mask reads it gets a vertex alpha of 1."""
    for key, slot in shape_materials.items():
        mask = alpha_masks[slot]
        if mask is not None and mask.vertex_alpha and "vertex_alpha" not in raw[key]:
            raw[key]["vertex_alpha"] = np.ones(len(raw[key]["vertices"]), np.float32)


def _scene_input(d: GltfDocument, data: bytes, scene, *, width, height, camera, name) -> GltfInput:
    label = d.label
    check_extensions(d)
    doc = d.doc
    nodes = walk_nodes(d)
    textures = Textures(d)
    materials: list[PbrMaterial] = []
    alpha_masks: list = []
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
            entry, record = light_entry(d, int(light.get("light", -1)), world)
            key = key_for(node.name or f"light_{n}")
            raw[key], light_records[key] = entry, record
        if node.mesh is None:
            continue
        mesh = doc.meshes[as_index(d, node.mesh, doc.meshes, f"node {n} mesh")]
        prims = mesh.primitives or []
        for p, prim in enumerate(prims):
            base = node.name or mesh.name or f"node_{n}"
            label_p = f"mesh {node.mesh} ({mesh.name or 'unnamed'}) primitive {p}"
            entry = primitive_mesh(d, prim, world, label_p)
            if prim.material not in mat_index:
                mat_index[prim.material] = len(materials)
                materials.append(read_material(d, prim.material, textures))
                alpha_masks.append(read_alpha(d, prim.material))
            if "vertex_alpha" in entry:
                _mask_reads_colour(d, alpha_masks, mat_index[prim.material], label_p)
            mat = materials[mat_index[prim.material]]
            entry["bsdf"] = diffuse(mat.base_color)  # Mitsuba's view (the G-buffer's is ours)
            key = key_for(base if len(prims) == 1 else f"{base}_{p}")
            raw[key], shape_materials[key] = entry, mat_index[prim.material]
    if not shape_materials:
        d.fail("the scene has no triangle mesh")
    _colourless_alpha_one(raw, shape_materials, alpha_masks)
    if camera is not None:
        if not 0 <= camera < len(doc.cameras or []):
            d.fail(f"camera {camera} out of range: the file has {len(doc.cameras or [])} camera(s)")
        cams = [(n, w) for n, w in cams if doc.nodes[n].camera == camera]
        if not cams:
            d.fail(f"camera {camera} is not placed in the scene by any node")
    if not cams:
        d.fail("the scene has no camera node; add one (perspective or orthographic)")
    cam_node, cam_world = cams[0]
    cam_index = as_index(d, doc.nodes[cam_node].camera, doc.cameras, f"node {cam_node} camera")
    gl_cam = doc.cameras[cam_index]
    aspect = getattr(gl_cam.perspective, "aspectRatio", None)
    if aspect is not None:
        aspect = as_number(d, aspect, f"camera {cam_index} aspectRatio", 0.0, 1e9, open_lo=True)
    film = (gl_cam.extras or {}).get("film_size") if isinstance(gl_cam.extras, dict) else None
    top = LIMITS["film_pixels"]
    if film and not (width or height):  # an export's size (scenes.formats.gltf_write's extras)
        if not isinstance(film, list) or len(film) != 2:
            d.fail(f"camera {cam_index} extras film_size must be [width, height]")
        width, height = (as_int(d, v, f"camera {cam_index} film_size", 1, top) for v in film)
    w = int(width or DEFAULT_WIDTH)
    h = int(height or (round(w / aspect) if aspect and not width else DEFAULT_HEIGHT))
    if not 1 <= h <= top:
        d.fail(f"camera {cam_index} aspectRatio {aspect!r} gives a film {w}x{h} (1 to {top} px)")
    verts = np.concatenate([e["vertices"] for k, e in raw.items() if k in shape_materials])
    cam_entry = camera_entry(d, cam_index, cam_world, w, h, verts.astype(np.float64))
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
        alpha_masks=alpha_masks,
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
