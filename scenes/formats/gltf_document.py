"""A glTF 2.0 document as untrusted input: its container checked, its bytes resolved.

:func:`read_document` checks a ``.gltf``/``.glb`` file's container before pygltflib sees it
(a GLB's header and chunk lengths, version 2 only; strict JSON of bounded nesting; the fields
that address bytes are JSON integers; array lengths and hierarchy depth within
:data:`LIMITS`) and returns a :class:`GltfDocument`: the pygltflib document with its buffers
resolved (an external ``uri`` stays inside the glTF's own folder, read only as a regular
file of at most :data:`LIMITS` ``file_bytes``), its accessors read with every index, count,
offset and stride checked, and the running counts of what the scene places. The field
checks :func:`as_int`, :func:`as_index`, :func:`as_number` and :func:`as_numbers` fail with
one line naming the field (:class:`GltfError`). :mod:`scenes.formats.gltf` reads the scene
from it.
"""

from __future__ import annotations

import base64
import math
import struct
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..base.untrusted import LIMITS as FILE_LIMITS
from ..base.untrusted import contained, loads_json, read_bounded

__all__ = [
    "LIMITS",
    "GltfDocument",
    "GltfError",
    "as_index",
    "as_int",
    "as_number",
    "as_numbers",
    "read_document",
]

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16}
_COMPONENTS.update({5125: np.uint32, 5126: np.float32})
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}

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


class GltfDocument:
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
            length = as_int(self, buf.byteLength, f"buffer {i} byteLength", 0)
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
        b = as_index(self, view.buffer, self.doc.buffers, f"{where} buffer")
        data = self.buffer(b)
        start = as_int(self, view.byteOffset or 0, f"{where} byteOffset", 0)
        length = as_int(self, view.byteLength, f"{where} byteLength", 0)
        stride = view.byteStride
        if stride is not None:
            stride = as_int(self, stride, f"{where} byteStride", 4, 252)
        if start + length > len(data):
            self.fail(f"{where} reads past the end of buffer {b}")
        return data[start : start + length], stride

    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as a float64 or integer array ``(count, width)``."""
        acc = self.doc.accessors[as_index(self, i, self.doc.accessors, "accessor")]
        if acc.sparse is not None:
            self.fail(f"accessor {i} is sparse (not supported)")
        width = _WIDTH.get(acc.type) if isinstance(acc.type, str) else None
        kind = acc.componentType
        if isinstance(kind, bool) or kind not in _COMPONENTS or width is None:
            self.fail(f"accessor {i} has an unsupported type {acc.type}/{acc.componentType}")
        dtype = np.dtype(_COMPONENTS[kind]).newbyteorder("<")
        item = dtype.itemsize * width
        count = as_int(self, acc.count, f"accessor {i} count", 0)
        if count * item > LIMITS["accessor_bytes"]:
            self.fail(
                f"accessor {i} spans {count * item:,} bytes, over the limit of "
                f"{LIMITS['accessor_bytes']:,}"
            )
        if acc.bufferView is None:
            return np.zeros((count, width), dtype=dtype)
        data, stride = self.view_bytes(as_index(self, acc.bufferView, self.doc.bufferViews, "view"))
        if stride is not None and stride < item:
            self.fail(f"accessor {i}: its view's byteStride {stride} is below its {item} bytes")
        stride = stride or item
        offset = as_int(self, acc.byteOffset or 0, f"accessor {i} byteOffset", 0)
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


def as_int(d: GltfDocument, value, what: str, lo: int = 0, hi: int | None = None) -> int:
    """``value`` as an integer in ``[lo, hi]``, else one line naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, int):
        d.fail(f"{what} must be an integer, got {type(value).__name__}")
    if value < lo or (hi is not None and value > hi):
        d.fail(f"{what} is {value}, out of range [{lo}, {'...' if hi is None else hi}]")
    return value


def as_index(d: GltfDocument, value, seq, what: str) -> int:
    """``value`` as an index into ``seq`` (negative indices refused)."""
    return as_int(d, value, f"{what} index", 0, len(seq or []) - 1)


def as_numbers(d: GltfDocument, value, n: int, what: str, bound: float, lo: float | None = None):
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


def as_number(d: GltfDocument, value, what: str, lo: float, hi: float, *, open_lo=False) -> float:
    """``value`` as a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    bad = isinstance(value, bool) or not isinstance(value, int | float)
    if bad or not math.isfinite(value) or not lo <= value <= hi or (open_lo and value == lo):
        low = "(" if open_lo else "["
        d.fail(f"{what} is {value!r}; expected a finite number in {low}{lo:g}, {hi:g}]")
    return float(value)


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


def read_document(scene, label: str) -> tuple[GltfDocument, bytes]:
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
    return GltfDocument(doc, base, blob, label), data
