"""An engine's images of a MASK glTF export scored like any other export (issue 44): the
export of ``alpha-foliage``, an engine that honours the cutout (here: the oracle's own
estimate of the cut-out scene, a second seed) and an engine that ignores it (the same
cards drawn opaque, ``alpha=0``), each written as the engine's layered EXR and scored with
``score`` against the cut-out truth. The honest engine passes the shadow and coverage gates;
the one that casts and covers opaque quads fails both, with the error named."""

from __future__ import annotations

import json

import numpy as np
import pytest
from engine_raster import write_engine_exr
from raster_oracle.oracle.cli import main

import raster_oracle as ro

W, H, N = 64, 36, 60
SCENE = f"alpha-foliage:n={N}"
SPP = ["--spp", "64"]
#: Gates an engine team would set: mean shadow and coverage error, a little above the noise
#: of two independent estimates (the engine here is a 64-spp estimate of the cut-out scene).
GATES = {"shadow": "visibility_mae=0.04", "msaa.coverage": "coverage_mae=0.12"}


def _engine_images(scene, *, seed: int) -> dict:
    ref = ro.reference(
        scene, width=W, height=H, spp=64, seed=seed, channels=["visibility", "coverage", "color"]
    )
    return {"shadow": ref.visibility, "coverage": ref.coverage, "color": ref.color}


@pytest.fixture(scope="module")
def engine(tmp_path_factory):
    root = tmp_path_factory.mktemp("alpha-engine")
    export = root / "export"
    argv = ["export", SCENE, "--width", str(W), "--height", str(H), "--out", str(export)]
    assert main(argv) == 0
    write_engine_exr(root / "cutout.exr", _engine_images(export, seed=7))
    write_engine_exr(root / "opaque.exr", _engine_images(f"{SCENE}:alpha=0", seed=7))
    return {"root": root, "scene": str(export / "scene.glb")}


def _score(engine, candidate, channel):
    out = engine["root"] / f"{candidate}-{channel}"
    argv = ["score", engine["scene"], "--candidate", str(engine["root"] / f"{candidate}.exr")]
    gate = ["--fail-above", GATES[channel]]
    code = main([*argv, "--channel", channel, *SPP, *gate, "--out", str(out)])
    return code, json.loads((out / "metrics.json").read_text())


def test_export_keeps_the_cutout():
    glb = ro.load_scene(SCENE, width=W, height=H)
    assert glb.alpha is not None and len(glb.alpha.masks) == 1


@pytest.mark.parametrize("channel", ["shadow", "msaa.coverage"])
def test_engine_honouring_the_cutout_passes_and_opaque_quads_fail(engine, channel):
    code_ok, ok = _score(engine, "cutout", channel)
    code_bad, bad = _score(engine, "opaque", channel)
    key = "visibility_mae" if channel == "shadow" else "coverage_mae"
    assert code_ok == 0, ok[key]
    assert code_bad == 1
    # the opaque quads are an error well beyond the cut-out engine's noise
    assert bad[key] > 5 * max(ok[key], 1e-4)
    assert np.isfinite(bad[key])
