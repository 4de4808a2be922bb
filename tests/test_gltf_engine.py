"""An engine's own glTF content scored on colour (issue 29).

A glTF twin of ``plate`` with PBR materials (a rough metal ground, a dielectric plate) is
written by the tests, exported with ``export`` (``scene.glb``, camera and light matrices,
glTF ``materials.json``), rendered by the tests' independent NumPy engine
(``tests/engine_raster.py``: its own rasterizer, shadow map and glTF BRDF, none of the
oracle's code) on an 8 x 8 sample grid, and scored with the command line: every colour metric
is within its noise floor. The same engine with the roughness remapped wrongly
(``alpha = roughness`` instead of ``roughness^2``) fails a colour gate.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from engine_raster import render, write_engine_exr
from gltf_scenes import pbr_material, plate_twin
from raster_oracle.oracle.cli import main

from raster_oracle import scenes

SPP = "16"
#: The engine's colour metrics against the reference and the reference's own noise floor
#: (an exact candidate's score) agree within this factor: the engine's 64 regular samples a
#: pixel and its 2048^2 shadow map leave errors of the order of the 16-spp reference's noise
#: (measured: FLIP 0.0034 against a floor of 0.0035, mean CIEDE2000 0.053 against 0.049).
FLOOR_FACTOR = 1.5
#: Colour gates of the CI command (about 3x the floors above; the wrong remapping scores
#: FLIP 0.33 and CIEDE2000 9.6).
GATES = ["--fail-above", "flip_mean=0.01", "--fail-above", "delta_e2000_mean=0.15"]


@pytest.fixture(scope="module")
def engine(tmp_path_factory):
    root = tmp_path_factory.mktemp("gltf_engine")
    plate = scenes.load("plate", width=96, height=54)
    materials = [
        pbr_material((0.9, 0.85, 0.8), 1.0, 0.5),  # ground: rough metal
        pbr_material((0.7, 0.3, 0.2), 0.0, 0.4),  # plate: dielectric
    ]
    glb = root / "plate_pbr.glb"
    glb.write_bytes(plate_twin(plate, materials))
    export = root / "export"
    assert main(["export", str(glb), "--width", "96", "--height", "54", "--out", str(export)]) == 0
    good = render(export, samples=8, shadow_map_size=2048, bias=0.02)
    wrong = render(export, samples=8, shadow_map_size=2048, bias=0.02, alpha_of=lambda r: r)
    write_engine_exr(root / "good.exr", good)
    write_engine_exr(root / "wrong.exr", wrong)
    return {"root": root, "export": export}


def _score(engine, candidate, out):
    folder = engine["root"] / out
    argv = ["score", str(engine["export"]), "--candidate", str(engine["root"] / candidate)]
    argv += ["--channel", "msaa", "--spp", SPP, "--out", str(folder), "--quiet", *GATES]
    code = main(argv)
    return code, json.loads((folder / "metrics.json").read_text())


def test_export_writes_the_gltf_scene_and_its_materials(engine):
    folder = engine["export"]
    assert (folder / "scene.glb").is_file() and not (folder / "scene.xml").exists()
    mats = json.loads((folder / "materials.json").read_text())
    assert mats["model"].startswith("gltf-metallic-roughness")
    ground = mats["shapes"]["ground"]["pbr"]
    assert ground["metallic_factor"] == 1.0 and ground["roughness_factor"] == 0.5
    cam = json.loads((folder / "camera.json").read_text())
    assert (cam["width"], cam["height"]) == (96, 54)
    light = json.loads((folder / "lights.json").read_text())["lights"][0]
    assert light["model"] == "KHR_lights_punctual" and light["units"] == "illuminance lux"
    m = np.asarray(light["to_world_gltf"])
    d = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    np.testing.assert_allclose(d, light["direction"], atol=1e-12)  # travels along -Z
    loaded = scenes.load(folder / "scene.glb")  # the export's own size, from the file
    assert (loaded.width, loaded.height) == (96, 54)


def test_engine_colour_is_within_the_noise_floor(engine, capsys):
    code, rec = _score(engine, "good.exr", "good")
    assert code == 0, capsys.readouterr().err
    floor = rec["noise_floor"]
    assert rec["reference"]["scene"]["shading_model"].startswith("gltf-metallic-roughness")
    for key in ("flip_mean", "delta_e2000_mean", "edge_mae", "interior_mae"):
        assert rec[key] <= FLOOR_FACTOR * floor[key], (key, rec[key], floor[key])
    assert rec["ssim"] >= 1.0 - FLOOR_FACTOR * (1.0 - floor["ssim"])
    assert rec["significant_fraction"] <= floor["significant_fraction"] + 0.005


def test_wrong_roughness_remapping_fails_the_colour_gate(engine, capsys):
    code, rec = _score(engine, "wrong.exr", "wrong")
    assert code == 1
    assert rec["flip_mean"] > 10 * rec["noise_floor"]["flip_mean"]
    assert "flip_mean" in capsys.readouterr().out


def test_a_gltf_export_is_a_scene_of_score_folder(engine, capsys):
    """``score-folder`` finds the glTF export by name (``--exports``) and scores its frame."""
    import shutil

    root = engine["root"] / "folder"
    root.mkdir()
    shutil.copy(engine["root"] / "good.exr", root / "export.exr")
    out = engine["root"] / "folder-out"
    argv = ["score-folder", str(root), "--exports", str(engine["root"]), "--channel", "msaa"]
    code = main([*argv, "--spp", SPP, "--out", str(out), "--quiet", *GATES])
    assert code == 0, capsys.readouterr().err
    rec = json.loads((out / "export" / "metrics.json").read_text())
    assert rec["reference"]["scene"]["shading_model"].startswith("gltf-metallic-roughness")
    assert rec["flip_mean"] <= FLOOR_FACTOR * rec["noise_floor"]["flip_mean"]
