"""Hostile glTF input (issue 39): every case is refused with one line (GltfError, the command
line's exit 2), reads no byte outside the glTF's folder, and ends in bounded time.

Each case is a small glTF document (a triangle pair, a camera, a sun) edited one way; the
in-process cases call :func:`scenes.gltf.gltf_input` (no Mitsuba scene is built), a few run
the real command line (``export``) and search its outputs for a secret's bytes.
"""

from __future__ import annotations

import base64
import copy
import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _bounded import bounded
from raster_oracle.scenes.formats.gltf import LIMITS, GltfError, gltf_input

SECRET = b"HOSTILE-SECRET-0123456789-" * 8


def _mesh_bytes() -> bytes:
    v = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], dtype="<f4")
    i = np.array([0, 1, 2, 0, 2, 3], dtype="<u2")
    return v.tobytes() + i.tobytes()


def _doc(uri: str = "mesh.bin") -> dict:
    """A valid glTF: a 2-triangle square, a perspective camera 3 units above, a sun."""
    data = _mesh_bytes()
    cam = [1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 3, 0, 1]  # looking down -Y
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0, "name": "square"},
            {"camera": 0, "matrix": cam},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "matrix": cam},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [-1, 0, -1],
                "max": [1, 0, 1],
            },
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
        ],
        "buffers": [{"uri": uri, "byteLength": len(data)}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {
            "KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.0}]}
        },
    }


def _write(folder: Path, doc: dict, name: str = "scene.gltf") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "mesh.bin").write_bytes(_mesh_bytes())
    path = folder / name
    path.write_text(json.dumps(doc))
    return path


def _glb(doc: dict, blob: bytes, *, version: int = 2, length: int | None = None) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    body += struct.pack("<II", len(blob), 0x004E4942) + blob
    total = 12 + len(body) if length is None else length
    return b"glTF" + struct.pack("<II", version, total) + body


def _refused(path, match: str | None = None) -> str:
    with pytest.raises(GltfError) as info:
        bounded(gltf_input, path)
    text = str(info.value)
    assert "\n" not in text and "Traceback" not in text
    if match is not None:
        assert match in text, text
    return text


def test_the_base_document_is_read(tmp_path):
    """The unedited document loads (so every refusal below is the edit's doing)."""
    gl = gltf_input(_write(tmp_path, _doc()))
    assert len(gl.raw["square"]["faces"]) == 2
    assert gl.raw["camera"]["type"] == "perspective"


# --- external files: nothing outside the glTF's folder is read ------------------------------


def _outside(tmp_path) -> Path:
    secret = tmp_path / "outside" / "secret.bin"
    secret.parent.mkdir(parents=True)
    secret.write_bytes(SECRET)
    return secret


URI_CASES = {
    "dotdot": lambda s: "../outside/secret.bin",
    "dotdot-deep": lambda s: "sub/../../outside/secret.bin",
    "percent-dotdot": lambda s: "%2e%2e/outside/secret.bin",
    "absolute": lambda s: str(s),
    "file-scheme": lambda s: f"file://{s}",
    "http": lambda s: "http://example.com/secret.bin",
    "passwd": lambda s: "/etc/passwd",
    "environ": lambda s: "/proc/self/environ",
    "home": lambda s: "~/secret.bin",
    "nul": lambda s: "mesh.bin\x00.txt",
    "backslash": lambda s: "..\\outside\\secret.bin",
    "empty": lambda s: "",
    "not-a-string": lambda s: 12,
    "missing": lambda s: "nosuch.bin",
}


@pytest.mark.parametrize("case", sorted(URI_CASES))
def test_buffer_uri_outside_the_folder_is_refused(tmp_path, case):
    secret = _outside(tmp_path)
    doc = _doc(URI_CASES[case](secret))
    _refused(_write(tmp_path / "scene", doc))


@pytest.mark.parametrize("case", ["dotdot", "absolute", "environ", "file-scheme"])
def test_image_uri_outside_the_folder_is_refused(tmp_path, case):
    secret = _outside(tmp_path)
    doc = _doc()
    doc["images"] = [{"uri": URI_CASES[case](secret)}]
    doc["textures"] = [{"source": 0}]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    _refused(_write(tmp_path / "scene", doc))


@pytest.mark.parametrize("target", ["file", "folder"])
def test_a_link_in_the_folder_pointing_out_is_refused(tmp_path, target):
    secret = _outside(tmp_path)
    folder = tmp_path / "scene"
    path = _write(folder, _doc("link.bin" if target == "file" else "inner/secret.bin"))
    if target == "file":
        (folder / "link.bin").symlink_to(secret)
    else:
        (folder / "inner").symlink_to(secret.parent)
    _refused(path, "outside")


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device"])
def test_a_buffer_that_is_no_regular_file_is_refused(tmp_path, kind):
    folder = tmp_path / "scene"
    path = _write(folder, _doc("odd.bin"))
    if kind == "fifo":
        os.mkfifo(folder / "odd.bin")
    elif kind == "folder":
        (folder / "odd.bin").mkdir()
    else:
        (folder / "odd.bin").symlink_to("/dev/zero")  # inside by name, a device by kind
    _refused(path)


@pytest.mark.parametrize("kind", ["fifo", "folder", "zero-device"])
def test_a_scene_file_that_is_no_regular_file_is_refused(tmp_path, kind):
    path = tmp_path / "scene.glb"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    else:
        path.symlink_to("/dev/zero")
    _refused(path)


def test_a_link_inside_the_folder_is_read(tmp_path):
    """A link that stays inside the folder is fine (containment, not a ban on links)."""
    folder = tmp_path / "scene"
    path = _write(folder, _doc("alias.bin"))
    (folder / "alias.bin").symlink_to(folder / "mesh.bin")
    assert len(gltf_input(path).raw["square"]["faces"]) == 2


def test_a_data_uri_buffer_is_read(tmp_path):
    doc = _doc("data:application/octet-stream;base64," + base64.b64encode(_mesh_bytes()).decode())
    path = tmp_path / "inline.gltf"
    path.write_text(json.dumps(doc))
    assert len(gltf_input(path).raw["square"]["faces"]) == 2


# --- GLB containers -------------------------------------------------------------------------


def _glb_doc() -> dict:
    doc = _doc()
    del doc["buffers"][0]["uri"]
    return doc


GLB_CASES = {
    "version-1": lambda d, b: _glb(d, b, version=1),
    "version-3": lambda d, b: _glb(d, b, version=3),
    "length-short": lambda d, b: _glb(d, b)[:-8],
    "length-over": lambda d, b: _glb(d, b, length=10**6),
    "bin-chunk-past-end": lambda d, b: _patch_bin_length(_glb(d, b), 10**6),
    "header-only": lambda d, b: b"glTF" + struct.pack("<II", 2, 12),
    "json-not-utf8": lambda d, b: _bad_json_chunk(b"\xff\xfe{}  "),
    "json-nan": lambda d, b: _bad_json_chunk(b'{"asset": {"version": "2.0"}, "x": NaN}'),
    "json-deep": lambda d, b: _bad_json_chunk(b"[" * 100_000 + b"]" * 100_000),
    "two-bin-chunks": lambda d, b: _two_bins(d, b),
    "bytelength-over-blob": lambda d, b: _glb({**d, "buffers": [{"byteLength": 10**6}]}, b),
}


def _patch_bin_length(glb: bytes, length: int) -> bytes:
    json_len = struct.unpack_from("<I", glb, 12)[0]
    at = 12 + 8 + json_len
    return glb[:at] + struct.pack("<I", length) + glb[at + 4 :]


def _bad_json_chunk(text: bytes) -> bytes:
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _two_bins(doc, blob) -> bytes:
    glb = _glb(doc, blob)
    extra = struct.pack("<II", 4, 0x004E4942) + b"\0" * 4
    return glb[:8] + struct.pack("<I", len(glb) + len(extra)) + glb[12:] + extra


@pytest.mark.parametrize("case", sorted(GLB_CASES))
def test_malformed_glb_is_refused(tmp_path, case):
    path = tmp_path / "scene.glb"
    path.write_bytes(GLB_CASES[case](_glb_doc(), _mesh_bytes()))
    _refused(path)


def test_a_textured_document_is_read(tmp_path):
    """The texture helper's document loads as it is (its edits above are the refusals')."""
    doc = copy.deepcopy(_doc())
    _textured(doc)
    gl = gltf_input(_write(tmp_path, doc))
    assert len(gl.textures) == 1 and gl.textures[0].image.shape[:2] == (2, 2)


def test_a_valid_glb_is_read(tmp_path):
    path = tmp_path / "scene.glb"
    path.write_bytes(_glb(_glb_doc(), _mesh_bytes()))
    assert len(gltf_input(path).raw["square"]["faces"]) == 2


# --- accessors, views, strides --------------------------------------------------------------


def _set(path: str, value):
    """An edit setting the field at ``path`` (dotted, integers index lists)."""

    def edit(doc):
        *head, last = path.split(".")
        node = doc
        for k in head:
            node = node[int(k)] if k.isdigit() else node[k]
        node[int(last) if last.isdigit() else last] = value

    return edit


def _drop(path: str):
    def edit(doc):
        *head, last = path.split(".")
        node = doc
        for k in head:
            node = node[int(k)] if k.isdigit() else node[k]
        del node[last]

    return edit


FIELD_CASES = {
    # buffer views and accessors against their buffer
    "stride-negative-huge": _set("bufferViews.0.byteStride", -(10**12)),
    "stride-huge": _set("bufferViews.0.byteStride", 10**12),
    "stride-below-item": _set("bufferViews.0.byteStride", 4),
    "stride-string": _set("bufferViews.0.byteStride", "12"),
    "view-offset-negative": _set("bufferViews.0.byteOffset", -48),
    "view-length-past-end": _set("bufferViews.0.byteLength", 10**9),
    "view-buffer-missing": _set("bufferViews.0.buffer", 7),
    "view-buffer-negative": _set("bufferViews.0.buffer", -1),
    "accessor-count-huge": _set("accessors.0.count", 10**9),
    "accessor-count-negative": _set("accessors.0.count", -4),
    "accessor-count-float": _set("accessors.0.count", 4.5),
    "accessor-offset-negative": _set("accessors.0.byteOffset", -12),
    "accessor-offset-past-end": _set("accessors.0.byteOffset", 40),
    "accessor-no-view-huge": lambda d: (
        d["accessors"][0].pop("bufferView") or d["accessors"][0].update(count=10**9)
    ),
    "accessor-type-unknown": _set("accessors.0.type", "VEC9"),
    "accessor-component-unknown": _set("accessors.0.componentType", 5130),
    "accessor-component-bool": _set("accessors.0.componentType", True),
    "position-is-vec2": _set("accessors.0.type", "VEC2"),
    "indices-are-float": _set("accessors.1.componentType", 5126),
    "indices-past-vertices": _set("accessors.1.count", 7),
    "position-index-negative": _set("meshes.0.primitives.0.attributes.POSITION", -1),
    "position-index-missing": _set("meshes.0.primitives.0.attributes.POSITION", 9),
    "buffer-bytelength-over": _set("buffers.0.byteLength", 10**6),
    "buffer-bytelength-string": _set("buffers.0.byteLength", "60"),
    # the hierarchy
    "node-mesh-missing": _set("nodes.0.mesh", 5),
    "node-mesh-negative": _set("nodes.0.mesh", -1),
    "node-child-self": _set("nodes.0.children", [0]),
    "node-child-missing": _set("nodes.0.children", [99]),
    "node-children-string": _set("nodes.0.children", "1"),
    "node-children-number": _set("nodes.0.children", 5),
    "node-children-object": _set("nodes.0.children", {"a": 1}),
    "node-not-object": _set("nodes.0", 7),
    "nodes-not-list": _set("nodes", {"0": {}}),
    "scenes-not-list": _set("scenes", 3),
    "asset-version-number": _set("asset.version", 2.0),
    "document-list": lambda d: (d.clear(), d.update({"asset": [1]})),
    "scene-index-out": _set("scene", 4),
    "scene-nodes-string": _set("scenes.0.nodes", "012"),
    # geometry
    "matrix-nan": _set(
        "nodes.0.matrix", [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, float("nan"), 0, 0, 1]
    ),
    "matrix-short": _set("nodes.0.matrix", [1, 0, 0]),
    "matrix-strings": _set("nodes.0.matrix", ["1"] * 16),
    "matrix-huge-scale": _set(
        "nodes.0.matrix", [1e200, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    ),
    "scale-1e200": _set("nodes.0.scale", [1e200, 1e200, 1e200]),
    "scale-inf": _set("nodes.0.scale", [float("inf"), 1, 1]),
    "translation-1e30": _set("nodes.0.translation", [1e30, 0, 0]),
    "translation-nan": _set("nodes.0.translation", [float("nan"), 0, 0]),
    "rotation-huge": _set("nodes.0.rotation", [1e9, 0, 0, 1]),
    "rotation-short": _set("nodes.0.rotation", [0, 0, 1]),
    # lights
    "light-intensity-negative": _set("extensions.KHR_lights_punctual.lights.0.intensity", -5),
    "light-intensity-nan": _set("extensions.KHR_lights_punctual.lights.0.intensity", float("nan")),
    "light-intensity-inf": _set("extensions.KHR_lights_punctual.lights.0.intensity", float("inf")),
    "light-intensity-string": _set("extensions.KHR_lights_punctual.lights.0.intensity", "2"),
    "light-color-negative": _set("extensions.KHR_lights_punctual.lights.0.color", [-1, 1, 1]),
    "light-color-nan": _set("extensions.KHR_lights_punctual.lights.0.color", [float("nan")] * 3),
    "light-color-short": _set("extensions.KHR_lights_punctual.lights.0.color", [1, 1]),
    "light-range-nan": lambda d: d["extensions"]["KHR_lights_punctual"]["lights"][0].update(
        type="point", range=float("nan")
    ),
    "light-range-zero": lambda d: d["extensions"]["KHR_lights_punctual"]["lights"][0].update(
        type="point", range=0
    ),
    "light-spot-nan": lambda d: d["extensions"]["KHR_lights_punctual"]["lights"][0].update(
        type="spot", spot={"outerConeAngle": float("nan")}
    ),
    "light-spot-string": lambda d: d["extensions"]["KHR_lights_punctual"]["lights"][0].update(
        type="spot", spot="wide"
    ),
    "light-missing": _set("nodes.2.extensions.KHR_lights_punctual.light", 3),
    "light-type-unknown": _set("extensions.KHR_lights_punctual.lights.0.type", "area"),
    "light-not-object": _set("extensions.KHR_lights_punctual.lights.0", 7),
    # cameras
    "yfov-nan": _set("cameras.0.perspective.yfov", float("nan")),
    "yfov-zero": _set("cameras.0.perspective.yfov", 0),
    "yfov-pi": _set("cameras.0.perspective.yfov", 3.1416),
    "yfov-string": _set("cameras.0.perspective.yfov", "0.8"),
    "znear-zero": _set("cameras.0.perspective.znear", 0),
    "znear-negative": _set("cameras.0.perspective.znear", -1),
    "zfar-below-znear": _set("cameras.0.perspective.zfar", 0.05),
    "zfar-inf": _set("cameras.0.perspective.zfar", float("inf")),
    "aspect-1e9": _set("cameras.0.perspective.aspectRatio", 1e9),
    "aspect-1e-9": _set("cameras.0.perspective.aspectRatio", 1e-9),
    "aspect-negative": _set("cameras.0.perspective.aspectRatio", -1.5),
    "ortho-ymag-zero": _set(
        "cameras.0",
        {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 0, "znear": 0.1, "zfar": 9}},
    ),
    "ortho-ymag-nan": _set(
        "cameras.0",
        {
            "type": "orthographic",
            "orthographic": {"xmag": 1, "ymag": float("nan"), "znear": 0.1, "zfar": 9},
        },
    ),
    "camera-type-unknown": _set("cameras.0.type", "fisheye"),
    "camera-node-zero-scale": _set("nodes.1.matrix", [0] * 15 + [1]),
    "film-size-huge": _set("cameras.0.extras", {"film_size": [160, 10**9]}),
    "film-size-strings": _set("cameras.0.extras", {"film_size": ["a", "b"]}),
    # materials
    "base-color-nan": lambda d: _material(
        d, {"pbrMetallicRoughness": {"baseColorFactor": [float("nan")] * 4}}
    ),
    "base-color-negative": lambda d: _material(
        d, {"pbrMetallicRoughness": {"baseColorFactor": [-1, 0, 0, 1]}}
    ),
    "metallic-above-one": lambda d: _material(d, {"pbrMetallicRoughness": {"metallicFactor": 1.5}}),
    "roughness-inf": lambda d: _material(
        d, {"pbrMetallicRoughness": {"roughnessFactor": float("inf")}}
    ),
    "emissive-nan": lambda d: _material(d, {"emissiveFactor": [float("nan"), 0, 0]}),
    "emissive-strength-negative": lambda d: _material(
        d, {"extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": -3}}}
    ),
    "material-missing": _set("meshes.0.primitives.0.material", 4),
    "material-negative": lambda d: (
        _material(d, {}) or _set("meshes.0.primitives.0.material", -1)(d)
    ),
    "texture-negative": lambda d: _textured(d, texture=-1),
    "texture-missing": lambda d: _textured(d, texture=5),
    "image-source-negative": lambda d: _textured(d, source=-1),
    "sampler-negative": lambda d: _textured(d, sampler=-1),
    "sampler-wrap-mixed": lambda d: _textured(d, sampler=0, wrap=(33071, 10497)),
    "texcoord-1": lambda d: _textured(d, texcoord=1),
    # the asset
    "version-1": _set("asset.version", "1.0"),
    "no-asset": _drop("asset"),
}


def _textured(doc: dict, *, texture=0, source=0, sampler=None, wrap=None, texcoord=0) -> None:
    """A base colour texture (a 2x2 PNG inline) with the given indices."""
    import io

    from PIL import Image

    png = io.BytesIO()
    Image.new("RGB", (2, 2), (200, 100, 50)).save(png, format="PNG")
    doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}]
    doc["textures"] = [{"source": source} | ({"sampler": sampler} if sampler is not None else {})]
    if wrap is not None:
        doc["samplers"] = [{"wrapS": wrap[0], "wrapT": wrap[1]}]
    info = {"index": texture} | ({"texCoord": texcoord} if texcoord else {})
    _material(doc, {"pbrMetallicRoughness": {"baseColorTexture": info}})


def _material(doc: dict, material: dict) -> None:
    doc["materials"] = [material]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    if "extensions" in material:
        doc["extensionsUsed"].append("KHR_materials_emissive_strength")


@pytest.mark.parametrize("case", sorted(FIELD_CASES))
def test_a_field_out_of_range_is_refused(tmp_path, case):
    doc = copy.deepcopy(_doc())
    FIELD_CASES[case](doc)
    _refused(_write(tmp_path, doc))


def test_nan_positions_are_refused(tmp_path):
    folder = tmp_path / "scene"
    path = _write(folder, _doc())
    data = bytearray(_mesh_bytes())
    data[0:4] = struct.pack("<f", float("nan"))
    (folder / "mesh.bin").write_bytes(bytes(data))
    _refused(path, "not finite")


@pytest.mark.parametrize("value", [float("inf"), 3e38])
def test_infinite_or_huge_positions_are_refused(tmp_path, value):
    folder = tmp_path / "scene"
    path = _write(folder, _doc())
    data = bytearray(_mesh_bytes())
    data[12:16] = struct.pack("<f", value)
    (folder / "mesh.bin").write_bytes(bytes(data))
    _refused(path)


# --- resource limits ------------------------------------------------------------------------


def test_twenty_thousand_instancing_nodes_are_refused_quickly(tmp_path):
    doc = _doc()
    n = 20_000
    doc["nodes"] += [{"mesh": 0} for _ in range(n)]
    doc["scenes"][0]["nodes"] += list(range(3, 3 + n))
    _refused(_write(tmp_path, doc), "nodes")


def test_many_instances_under_the_node_limit_are_refused_quickly(tmp_path):
    doc = _doc()
    n = LIMITS["instances"] + 5
    doc["nodes"] += [{"mesh": 0, "name": "same"} for _ in range(n)]
    doc["scenes"][0]["nodes"] += list(range(3, 3 + n))
    _refused(_write(tmp_path, doc), "instances")


def test_a_chain_twenty_thousand_deep_is_refused_quickly(tmp_path):
    doc = _doc()
    n = 20_000
    doc["nodes"] += [{"children": [4 + k]} for k in range(n - 1)] + [{"mesh": 0}]
    doc["scenes"][0]["nodes"].append(3)
    _refused(_write(tmp_path, doc))


def test_a_chain_beyond_the_depth_limit_is_refused(tmp_path):
    doc = _doc()
    n = LIMITS["depth"] + 2
    doc["nodes"] += [{"children": [4 + k]} for k in range(n - 1)] + [{"mesh": 0}]
    doc["scenes"][0]["nodes"].append(3)
    _refused(_write(tmp_path, doc), "deeper")


def test_an_image_over_the_pixel_limit_is_refused(tmp_path):
    from PIL import Image

    folder = tmp_path / "scene"
    doc = _doc()
    doc["images"] = [{"uri": "big.png"}]
    doc["textures"] = [{"source": 0}]
    _material(doc, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})
    path = _write(folder, doc)
    Image.new("L", (12000, 12000)).save(folder / "big.png", optimize=False)
    _refused(path, "limit")


def test_an_accessor_over_the_byte_limit_is_refused(tmp_path):
    doc = _doc()
    doc["accessors"][0].pop("bufferView")
    doc["accessors"][0]["count"] = LIMITS["accessor_bytes"] // 12 + 1
    _refused(_write(tmp_path, doc), "limit")


# --- the command line: exit 2, one line, nothing of the secret in any output ----------------


def _cli(*args, cwd=None, timeout=120):
    env = {**os.environ, "RASTER_ORACLE_TRUST_BACKEND": "1"}
    cmd = [sys.executable, "-m", "raster_oracle.oracle.cli", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


@pytest.mark.parametrize("case", ["dotdot", "absolute", "link"])
def test_export_never_copies_bytes_from_outside_the_folder(tmp_path, case):
    secret = _outside(tmp_path)
    folder = tmp_path / "scene"
    uri = {"dotdot": "../outside/secret.bin", "absolute": str(secret), "link": "l.bin"}[case]
    path = _write(folder, _doc(uri))
    if case == "link":
        (folder / "l.bin").symlink_to(secret)
    out = tmp_path / "out"
    r = _cli("export", path, "--out", out)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    written = [p for p in tmp_path.rglob("*") if p.is_file() and not p.is_symlink()]
    written = [p for p in written if "outside" not in p.parts]
    assert not any(SECRET[:16] in p.read_bytes() for p in written)
    assert not out.exists() or not any(out.iterdir())


# --- any field of any type: a refusal or a scene, never another exception --------------------


def _paths(node, prefix=()):
    """Every path (keys and indices) into the JSON document."""
    out = [prefix] if prefix else []
    items = (
        node.items()
        if isinstance(node, dict)
        else enumerate(node)
        if isinstance(node, list)
        else ()
    )
    for k, v in items:
        out += _paths(v, (*prefix, k))
    return out


HOSTILE_VALUES = [None, -1, 0, 2**63, 1e300, -1e300, "x", "", [], [1], {}, {"a": 1}, True, 0.5]


def test_every_field_of_every_type_is_refused_or_read(tmp_path):
    """Each path of the base document set to each hostile value (about 1,200 documents):
    :func:`gltf_input` reads it or refuses it with a GltfError; no other exception escapes."""
    base = _doc()
    paths = [p for p in _paths(base) if p[0] != "asset"]
    folder = tmp_path / "scene"
    (folder).mkdir()
    (folder / "mesh.bin").write_bytes(_mesh_bytes())
    escaped = []
    for path in paths:
        for value in HOSTILE_VALUES:
            doc = copy.deepcopy(base)
            node = doc
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = value
            target = folder / "scene.gltf"
            target.write_text(json.dumps(doc))
            try:
                bounded(gltf_input, target)
            except GltfError as exc:
                assert "\n" not in str(exc)
            except Exception as exc:  # the failure this test looks for
                escaped.append(f"{path}={value!r}: {type(exc).__name__}: {exc}")
    assert not escaped, "\n".join(escaped[:20])


def test_a_huge_texture_is_one_line_at_the_command_line(tmp_path):
    """12000 x 12000 pixels: Pillow's own bomb warning is not a second line."""
    from PIL import Image

    folder = tmp_path / "scene"
    doc = _doc()
    doc["images"] = [{"uri": "big.png"}]
    doc["textures"] = [{"source": 0}]
    _material(doc, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})
    path = _write(folder, doc)
    Image.new("L", (12000, 12000)).save(folder / "big.png")
    r = _cli("export", path, "--out", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "limit" in r.stderr
    assert not (tmp_path / "out").exists()
