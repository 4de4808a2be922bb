"""Write glTF 2.0 binary files (GLB) from plain records: the project's own glTF scenes, the
tests' glTF twins of built-in scenes and ``export`` of a glTF scene.

:func:`glb_bytes` takes a camera, KHR_lights_punctual lights, triangle meshes (world space or
with a node matrix), glTF material dictionaries and PNG images, and returns the GLB bytes
(pygltflib writes the container). Node order is camera, lights, meshes (the order
:mod:`scenes.formats.gltf` reads them back in).
"""

from __future__ import annotations

import io
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "GL_TO_MI",
    "GltfCamera",
    "GltfLight",
    "GltfMesh",
    "glb_bytes",
    "light_matrix",
    "png_bytes",
]

#: glTF camera axes to Mitsuba's (+X right -> +X left, -Z forward -> +Z forward): a camera
#: node's matrix is ``to_world @ GL_TO_MI`` and ``to_world`` is ``node @ GL_TO_MI``.
GL_TO_MI = np.diag([-1.0, 1.0, -1.0, 1.0])


@dataclass
class GltfCamera:
    """A glTF camera node: ``matrix`` (4x4 world matrix, glTF convention: looks down -Z, +Y
    up), ``yfov`` in radians (perspective) or ``ymag`` (orthographic), clip distances."""

    matrix: np.ndarray
    znear: float
    zfar: float | None
    yfov: float | None = None
    ymag: float | None = None
    aspect: float | None = None
    #: film (width, height) in pixels, kept in the camera's ``extras`` (``film_size``): the
    #: loader's default size (an export's size)
    film: tuple[int, int] | None = None


@dataclass
class GltfLight:
    """A KHR_lights_punctual light on a node with world ``matrix`` (travels along -Z)."""

    name: str
    kind: str
    matrix: np.ndarray
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    range: float | None = None
    inner: float = 0.0
    outer: float = math.pi / 4


@dataclass
class GltfMesh:
    """One mesh node of one primitive: ``vertices`` (V, 3), ``faces`` (F, 3) and optional
    ``normals`` (V, 3), ``texcoords`` (V, 2), ``tangents`` (V, 4), ``colors`` (``COLOR_0``,
    (V, 3) or (V, 4): float, or uint8/uint16 written normalized); ``material`` index."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    material: int | None = None
    normals: np.ndarray | None = None
    texcoords: np.ndarray | None = None
    tangents: np.ndarray | None = None
    matrix: np.ndarray | None = None
    colors: np.ndarray | None = None


@dataclass
class _Blob:
    data: bytearray = field(default_factory=bytearray)
    views: list = field(default_factory=list)
    accessors: list = field(default_factory=list)

    def view(self, raw: bytes, target: int | None = None) -> int:
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target is not None:
            view["target"] = target
        self.data.extend(raw)
        self.views.append(view)
        return len(self.views) - 1

    def accessor(self, arr: np.ndarray, kind: str, *, index: bool = False) -> int:
        normalized = False
        if index:
            arr = np.ascontiguousarray(arr, dtype="<u4").ravel()
            ctype, target = 5125, 34963
        elif np.asarray(arr).dtype in (np.uint8, np.uint16):  # normalized colours
            arr = np.ascontiguousarray(arr, dtype=np.asarray(arr).dtype.newbyteorder("<"))
            ctype, target, normalized = (5121 if arr.dtype.itemsize == 1 else 5123), 34962, True
        else:
            arr = np.ascontiguousarray(arr, dtype="<f4")
            ctype, target = 5126, 34962
        acc = {
            "bufferView": self.view(arr.tobytes(), target),
            "componentType": ctype,
            "count": int(len(arr)),
            "type": kind,
        }
        if normalized:
            acc["normalized"] = True
        if kind == "VEC3" and not index and not normalized:
            acc["min"] = [float(c) for c in arr.min(axis=0)] if len(arr) else [0.0] * 3
            acc["max"] = [float(c) for c in arr.max(axis=0)] if len(arr) else [0.0] * 3
        self.accessors.append(acc)
        return len(self.accessors) - 1


def light_matrix(direction=None, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A node matrix whose -Z axis is ``direction`` (kept unnormalized: the loader hands it to
    Mitsuba as given) and whose translation is ``position``."""
    m = np.eye(4)
    m[:3, 3] = np.asarray(position, dtype=np.float64)
    if direction is None:
        return m
    d = np.asarray(direction, dtype=np.float64)
    u = d / np.linalg.norm(d)
    helper = np.array([0.0, 1.0, 0.0]) if abs(u[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, -u)
    x /= np.linalg.norm(x)
    y = np.cross(-u, x)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, -d
    return m


def png_bytes(values: np.ndarray) -> bytes:
    """An 8-bit RGB PNG of ``values`` (H, W, 3) in [0, 1], or RGBA of (H, W, 4) (stored as
    given: encode sRGB yourself for a colour texture; alpha is linear)."""
    from PIL import Image

    arr = np.clip(np.rint(np.asarray(values, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(arr, "RGBA" if arr.shape[-1] == 4 else "RGB").save(buf, format="PNG")
    return buf.getvalue()


def _matrix_list(m: np.ndarray) -> list[float]:
    return [float(c) for c in np.asarray(m, dtype=np.float64).T.ravel()]  # column-major


def glb_bytes(
    *,
    camera: GltfCamera,
    lights: list[GltfLight],
    meshes: list[GltfMesh],
    materials: list[dict],
    images: list[bytes] = (),
    textures: list[dict] = (),
    samplers: list[dict] = (),
) -> bytes:
    """The GLB file of the records (one buffer, images embedded as PNG buffer views)."""
    import pygltflib

    blob = _Blob()
    nodes, cam = [], {}
    if camera.yfov is not None:
        persp = {"yfov": float(camera.yfov), "znear": float(camera.znear)}
        if camera.zfar is not None:
            persp["zfar"] = float(camera.zfar)
        if camera.aspect is not None:
            persp["aspectRatio"] = float(camera.aspect)
        cam = {"type": "perspective", "perspective": persp}
    else:
        mag = float(camera.ymag)
        ortho = {"xmag": mag * (camera.aspect or 1.0), "ymag": mag}
        cam = {"type": "orthographic", "orthographic": ortho}
        cam["orthographic"].update({"znear": float(camera.znear), "zfar": float(camera.zfar)})
    if camera.film is not None:
        cam["extras"] = {"film_size": [int(camera.film[0]), int(camera.film[1])]}
    nodes.append({"name": "camera", "camera": 0, "matrix": _matrix_list(camera.matrix)})
    khr = []
    for lt in lights:
        rec = {"name": lt.name, "type": lt.kind, "color": [float(c) for c in lt.color]}
        rec["intensity"] = float(lt.intensity)
        if lt.range is not None and lt.kind != "directional":
            rec["range"] = float(lt.range)
        if lt.kind == "spot":
            rec["spot"] = {"innerConeAngle": float(lt.inner), "outerConeAngle": float(lt.outer)}
        node = {"name": lt.name, "matrix": _matrix_list(lt.matrix)}
        node["extensions"] = {"KHR_lights_punctual": {"light": len(khr)}}
        khr.append(rec)
        nodes.append(node)
    gl_meshes = []
    for mesh in meshes:
        attrs = {"POSITION": blob.accessor(mesh.vertices, "VEC3")}
        for key, arr, kind in (
            ("NORMAL", mesh.normals, "VEC3"),
            ("TEXCOORD_0", mesh.texcoords, "VEC2"),
            ("TANGENT", mesh.tangents, "VEC4"),
            (
                "COLOR_0",
                mesh.colors,
                f"VEC{np.shape(mesh.colors)[-1]}" if mesh.colors is not None else "",
            ),
        ):
            if arr is not None:
                attrs[key] = blob.accessor(arr, kind)
        prim = {"attributes": attrs, "indices": blob.accessor(mesh.faces, "SCALAR", index=True)}
        if mesh.material is not None:
            prim["material"] = int(mesh.material)
        node = {"name": mesh.name, "mesh": len(gl_meshes)}
        if mesh.matrix is not None:
            node["matrix"] = _matrix_list(mesh.matrix)
        gl_meshes.append({"name": mesh.name, "primitives": [prim]})
        nodes.append(node)
    doc = {
        "asset": {"version": "2.0", "generator": "raster-oracle"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "cameras": [cam],
        "meshes": gl_meshes,
        "materials": list(materials),
    }
    if khr:
        doc["extensionsUsed"] = ["KHR_lights_punctual"]
        doc["extensions"] = {"KHR_lights_punctual": {"lights": khr}}
    if images:
        doc["images"] = [
            {"bufferView": blob.view(bytes(png)), "mimeType": "image/png"} for png in images
        ]
        doc["textures"] = list(textures)
        if samplers:
            doc["samplers"] = list(samplers)
    doc["buffers"] = [{"byteLength": len(blob.data)}]
    doc["bufferViews"] = blob.views
    doc["accessors"] = blob.accessors
    with warnings.catch_warnings():
        # dataclasses_json warns on optional fields glTF leaves out (an image's uri)
        warnings.filterwarnings("ignore", message=".*non-optional type", category=RuntimeWarning)
        gltf = pygltflib.GLTF2.from_dict(doc)
        gltf.set_binary_blob(bytes(blob.data))
        return b"".join(gltf.save_to_bytes())
