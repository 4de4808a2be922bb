"""glTF input (issue 29): node hierarchy, camera choice, the file forms, and refusals.

Every unsupported feature is refused with one line naming it (library: SceneError; command
line: exit 2 and one line), never silently dropped.
"""

from __future__ import annotations

import base64
import json
import math
import warnings

import numpy as np
import pygltflib
import pytest
from gltf_scenes import flat_plane, pbr_material
from raster_oracle.oracle.cli import main
from raster_oracle.scenes.formats.gltf_write import (
    GltfCamera,
    GltfLight,
    GltfMesh,
    glb_bytes,
    light_matrix,
)

from raster_oracle import scenes


def _sun():
    return GltfLight("sun", "directional", light_matrix((0.2, -1.0, 0.1)), intensity=2.0)


def _doc(glb: bytes):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=RuntimeWarning)
        return pygltflib.GLTF2.load_from_bytes(glb)


def _save(doc, path):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=RuntimeWarning)
        path.write_bytes(b"".join(doc.save_to_bytes()))
    return path


def _plane(tmp_path, **kw):
    glb = flat_plane(lights=[_sun()], material=pbr_material((0.5,) * 3, 0.0, 0.5), **kw)
    return _doc(glb)


def test_node_hierarchy_composes_trs_and_matrices(tmp_path):
    """A triangle under a parent (matrix: translate) and a child (TRS: rotate 90 degrees about
    +Y, scale 2, translate) lands at parent @ child @ vertex."""
    doc = _plane(tmp_path)
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    glb = glb_bytes(
        camera=GltfCamera(np.eye(4), 0.1, 50.0, yfov=1.0),
        lights=[_sun()],
        meshes=[GltfMesh("tri", v, np.array([[0, 1, 2]]), material=0)],
        materials=[pbr_material((0.5,) * 3, 0.0, 0.5)],
    )
    doc = _doc(glb)
    tri = len(doc.nodes) - 1
    parent = pygltflib.Node(name="parent", children=[tri])
    parent.matrix = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3.0, -1.0, -10.0, 1]  # column-major
    s = math.sqrt(0.5)
    doc.nodes[tri].rotation = [0.0, s, 0.0, s]  # 90 degrees about +Y
    doc.nodes[tri].scale = [2.0, 2.0, 2.0]
    doc.nodes[tri].translation = [0.0, 1.0, 0.0]
    doc.nodes.append(parent)
    doc.scenes[0].nodes = [n for n in doc.scenes[0].nodes if n != tri] + [len(doc.nodes) - 1]
    loaded = scenes.load(_save(doc, tmp_path / "tree.glb"))
    got = loaded.mesh_data["tri"][0]
    rot = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], dtype=float)  # +X -> -Z
    want = (2.0 * v) @ rot.T + [0.0, 1.0, 0.0] + [3.0, -1.0, -10.0]
    np.testing.assert_allclose(got, want, atol=1e-6)


def test_camera_choice_and_orthographic(tmp_path):
    doc = _plane(tmp_path, ortho=4.0)
    first = len(doc.cameras)
    doc.cameras.append(
        pygltflib.Camera(
            type="perspective",
            perspective=pygltflib.Perspective(yfov=0.5, znear=0.2, zfar=30.0),
        )
    )
    node = pygltflib.Node(name="cam2", camera=first, translation=[0.0, 3.0, 9.0])
    doc.nodes.append(node)
    doc.scenes[0].nodes.append(len(doc.nodes) - 1)
    path = _save(doc, tmp_path / "two.glb")
    a = scenes.load(path, width=64, height=32)
    assert a.camera.kind == "orthographic" and a.camera.half_extent()[1] == pytest.approx(4.0)
    b = scenes.load(path, width=64, height=32, camera=1)
    assert b.camera.kind == "perspective"
    np.testing.assert_allclose(b.camera.fov_y, math.degrees(0.5), rtol=1e-6)  # yfov kept
    np.testing.assert_allclose(b.camera.position, [0.0, 3.0, 9.0])
    np.testing.assert_allclose(b.camera.forward, [0.0, 0.0, -1.0])  # glTF looks down -Z
    assert a.content_hash != b.content_hash
    with pytest.raises(scenes.SceneError, match="camera 2 out of range"):
        scenes.load(path, camera=2)
    with pytest.raises(scenes.SceneError, match="glTF scenes only"):
        scenes.load("plate", camera=0)


def test_camera_option_on_the_command_line(tmp_path, capsys):
    path = _save(_plane(tmp_path), tmp_path / "plane.glb")
    out = tmp_path / "ref"
    argv = ["reference", str(path), "--camera", "0", "--width", "16", "--height", "8"]
    assert main([*argv, "--spp", "1", "--no-cache", "--quiet", "--out", str(out)]) == 0
    meta = json.loads((out / "reference.json").read_text())
    assert meta["scene"]["shading_model"].startswith("gltf-metallic-roughness")
    capsys.readouterr()
    assert main(["reference", str(path), "--camera", "3", "--no-cache", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "camera 3 out of range" in err[0]


def test_gltf_json_with_an_external_buffer(tmp_path):
    """The ``.gltf`` form: JSON with its buffer in a ``.bin`` file beside it (hashed too)."""
    doc = _plane(tmp_path)
    blob = doc.binary_blob()
    (tmp_path / "plane.bin").write_bytes(blob)
    doc.buffers[0].uri = "plane.bin"
    doc.set_binary_blob(b"")
    data = json.loads(doc.gltf_to_json())
    (tmp_path / "plane.gltf").write_text(json.dumps(data))
    a = scenes.load(tmp_path / "plane.gltf", width=32, height=16)
    glb = scenes.load(_save(_plane(tmp_path), tmp_path / "plane.glb"), width=32, height=16)
    np.testing.assert_array_equal(a.mesh_data["plane"][0], glb.mesh_data["plane"][0])
    (tmp_path / "plane.bin").write_bytes(b"\1" + blob[1:])  # a position's low bits
    b = scenes.load(tmp_path / "plane.gltf", width=32, height=16)
    assert a.content_hash != b.content_hash
    # a data URI works as well
    doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode(
        "ascii"
    )
    (tmp_path / "inline.gltf").write_text(doc.gltf_to_json())
    c = scenes.load(tmp_path / "inline.gltf", width=32, height=16)
    np.testing.assert_array_equal(c.mesh_data["plane"][0], glb.mesh_data["plane"][0])


def _break(doc, what: str):
    prim = doc.meshes[0].primitives[0]
    mat = doc.materials[0]
    if what == "mode":
        prim.mode = 1
    elif what == "blend":
        mat.alphaMode = "BLEND"
    elif what == "extension":
        doc.extensionsUsed = [*doc.extensionsUsed, "KHR_materials_clearcoat"]
    elif what == "texcoord":
        mat.pbrMetallicRoughness.baseColorTexture = pygltflib.TextureInfo(index=0, texCoord=1)
        doc.textures = [pygltflib.Texture(source=0)]
        doc.images = [pygltflib.Image(uri="x.png")]
    elif what == "camera":
        doc.nodes = [n for n in doc.nodes if n.camera is None]
        doc.scenes[0].nodes = list(range(len(doc.nodes)))
    elif what == "colors":
        prim.attributes.COLOR_0 = prim.attributes.POSITION
    elif what == "targets":
        prim.targets = [{"POSITION": prim.attributes.POSITION}]
    elif what == "draco":  # an extension used without being declared
        prim.extensions = {"KHR_draco_mesh_compression": {"bufferView": 0}}
    return doc


@pytest.mark.parametrize(
    "what, message",
    [
        ("mode", "primitive mode LINES"),
        ("blend", "alphaMode BLEND; only OPAQUE and MASK are supported"),
        ("extension", "extension KHR_materials_clearcoat is not supported"),
        ("texcoord", "TEXCOORD_1"),
        ("camera", "no camera node"),
        ("colors", "COLOR_0"),
        ("targets", "morph targets"),
        ("draco", "extension KHR_draco_mesh_compression"),
    ],
)
def test_unsupported_features_are_refused_by_name(tmp_path, capsys, what, message):
    path = _save(_break(_plane(tmp_path), what), tmp_path / f"{what}.glb")
    with pytest.raises(scenes.SceneError, match=message):
        scenes.load(path)
    assert main(["reference", str(path), "--spp", "1", "--no-cache", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_malformed_and_missing_files(tmp_path, capsys):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(scenes.SceneError, match="bad.glb"):
        scenes.load(bad)
    with pytest.raises(scenes.SceneError, match="not found"):
        scenes.load(tmp_path / "missing.gltf")
    assert main(["reference", str(tmp_path / "missing.glb"), "--no-cache", "--quiet"]) == 2
    assert "not found" in capsys.readouterr().err
    doc = _plane(tmp_path)
    doc.nodes[-1].mesh = 99  # a mesh that does not exist
    path = _save(doc, tmp_path / "dangling.glb")
    with pytest.raises(scenes.SceneError, match="dangling.glb: node 2 mesh index is 99"):
        scenes.load(path)


def test_a_sweep_spec_takes_a_gltf_file(tmp_path):
    from raster_oracle.oracle.sweeps.spec import expand_spec

    _save(_plane(tmp_path), tmp_path / "plane.glb")
    spec = {"defaults": {"width": 32, "height": 16, "spp": 4}}
    spec["case"] = [{"scenes": ["plane.glb", "pbr-foliage"], "technique": "noaa"}]
    cases = expand_spec(spec, base_dir=tmp_path).cases
    assert [c.scene for c in cases] == [str((tmp_path / "plane.glb").resolve()), "pbr-foliage"]
