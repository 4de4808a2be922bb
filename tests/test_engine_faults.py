"""The faults of a real renderer (pyrender on Mesa, issue 37), made by the test suite's own
rasterizer (tests/engine_raster.py) on an export of the plate, each named by the oracle:

- a 3x3 PCF that reads its shadow map one texel over fails ``--expect`` conformance with its
  displacement named, while the corrected renderer conforms (and its truth metrics show the
  PCF's inherent softness, which the README's edge-aware profile fails);
- a Fresnel-weighted diffuse is a gain (a few per cent), colour x pi is named as x pi, a
  gamma-2.2 PNG read as sRGB is named with the option that reads it right.

Sizes are small (96x54, 4 spp) so the file runs in well under a minute."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from engine_raster import render, write_engine_exr, write_rgb_png
from raster_oracle.metrics.shift import apply_shift, subpixel_shift
from raster_oracle.metrics.tonemap import srgb_decode
from raster_oracle.oracle.cli import main

W, H = 96, 54
RES = 256
#: What the engine claims: the model's 3x3 PCF at its resolution and depth bias.
EXPECT = f"shadow-map:resolution={RES},filter=pcf,pcf_size=3,bias=0.02"
GATE = ["--fail-above", "conformance_misclassified_fraction=0.005"]


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    root = tmp_path_factory.mktemp("plate")
    assert (
        main(["export", "plate", "--width", str(W), "--height", str(H), "--out", str(root / "e")])
        == 0
    )
    images = {}
    kw = dict(shadow_map_size=RES, pcf=3, samples=1, depth_bias=0.02)
    images["pcf"] = render(root / "e", **kw)
    images["pcf_offset"] = render(root / "e", pcf_offset=(-1, 1), **kw)
    images["fresnel"] = render(root / "e", diffuse="fresnel", **kw)
    images["pi"] = render(root / "e", color_scale=math.pi, **kw)
    # an engine that wrote 2.2-encoded colour into the linear EXR (read as if sRGB-decoded)
    encoded = srgb_decode(np.power(np.clip(images["pcf"]["color"], 0, 1), 1 / 2.2))
    images["gamma_in_exr"] = {**images["pcf"], "color": encoded}
    for name, im in images.items():
        write_engine_exr(root / f"{name}.exr", im)
    write_rgb_png(root / "gamma22.png", images["pcf"]["color"], gamma=2.2)
    return root


def _score(plate, tmp_path, name, *extra):
    out = tmp_path / name.replace(".", "_")
    argv = ["score", str(plate / "e"), "--candidate", str(plate / name), "--spp", "4"]
    rc = main([*argv, "--quiet", "--out", str(out), *extra])
    return rc, json.loads((out / "metrics.json").read_text())


def test_subpixel_shift_recovers_a_known_translation():
    y, x = np.mgrid[0:54, 0:96]
    disc = (np.hypot(x - 48, y - 27) < 15).astype(float)
    moved = (np.hypot(x - 48 + 1.37, y - 27 + 1.30) < 15).astype(float)
    s = subpixel_shift(disc, moved)
    assert abs(s["dx"] + 1.37) < 0.1 and abs(s["dy"] + 1.30) < 0.1
    smooth = apply_shift(np.clip(x / 10.0 - 4, 0, 1) * np.clip(y / 8.0 - 2, 0, 1), 0.4, -0.3)
    s = subpixel_shift(np.clip(x / 10.0 - 4, 0, 1) * np.clip(y / 8.0 - 2, 0, 1), smooth)
    assert abs(s["dx"] - 0.4) < 0.02 and abs(s["dy"] + 0.3) < 0.02


def test_pcf_offset_fails_conformance_and_the_corrected_renderer_passes(plate, tmp_path, capsys):
    rc, good = _score(plate, tmp_path, "pcf.exr", "--channel", "shadow", "--expect", EXPECT, *GATE)
    assert rc == 0
    assert good["conformance_misclassified_fraction"] == 0.0
    assert good["conformance_edge_displacement_px"] < 0.05
    # the truth metrics show the 3x3 PCF's own soft edge: not a conformance failure (item 8:
    # an intended filter is gated on conformance, not on its distance from a hard shadow)
    assert good["edge_band_mae"] > 0.05
    capsys.readouterr()
    rc, bad = _score(
        plate, tmp_path, "pcf_offset.exr", "--channel", "shadow", "--expect", EXPECT, *GATE
    )
    out = capsys.readouterr().out
    assert rc == 1 and bad["conformance_misclassified_fraction"] > 0.01
    assert bad["conformance_edge_displacement_px"] > 1.0
    assert "conformance: the candidate's edges are displaced by (" in out
    assert "FAIL conformance_misclassified_fraction" in out
    assert bad["conformance"]["technique"] == "shadow-map"
    assert bad["conformance"]["params"]["resolution"] == RES


def test_expect_is_checked_before_rendering(plate, tmp_path, capsys):
    bad = ["--channel", "shadow", "--expect", "shadow-map:resolution=-3"]
    argv = ["score", str(plate / "e"), "--candidate", str(plate / "pcf.exr"), *bad]
    assert main([*argv, "--out", str(tmp_path / "x"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--expect shadow-map:resolution=-3" in err and not (tmp_path / "x").exists()
    argv = ["score", str(plate / "e"), "--candidate", str(plate / "pcf.exr"), "--channel", "shadow"]
    assert main([*argv, *GATE, "--out", str(tmp_path / "y"), "--quiet"]) == 2
    assert "--expect" in capsys.readouterr().err


def _causes(rec):
    return [c["cause"] for c in rec["colour_causes"]["causes"]]


def test_colour_faults_are_named(plate, tmp_path):
    _, good = _score(plate, tmp_path, "pcf.exr", "--channel", "msaa")
    _, pi = _score(plate, tmp_path, "pi.exr", "--channel", "msaa")
    _, fresnel = _score(plate, tmp_path, "fresnel.exr", "--channel", "msaa")
    _, gamma = _score(plate, tmp_path, "gamma22.png")
    assert _causes(good) == []
    # colour x pi: one global gain, named as pi
    assert _causes(pi)[0] == "global gain"
    assert "colour x pi" in pi["colour_causes"]["causes"][0]["message"]
    assert "colour x pi" in pi["diagnoses"][0]["message"]
    assert not any("sRGB-encoded" in d["message"] for d in pi["diagnoses"] + fresnel["diagnoses"])
    # a Fresnel-weighted diffuse: a gain of a few per cent down, per material at least
    assert {"global gain", "per-material gain"} & set(_causes(fresnel))
    assert 0.9 < fresnel["colour_causes"]["gain"] < 0.99
    # gamma 2.2 read as sRGB: named with the option that reads it right
    assert _causes(gamma)[0] == "gamma 2.2 read as sRGB"
    assert "--transfer gamma2.2" in gamma["colour_causes"]["causes"][0]["message"]
    # the same content in an EXR (which takes no --transfer): write linear radiance (item 8)
    _, exr = _score(plate, tmp_path, "gamma_in_exr.exr", "--channel", "msaa")
    message = exr["colour_causes"]["causes"][0]["message"]
    assert "write linear radiance" in message and "--transfer" not in message.split("(")[0]
    # the per-shape table: every shape seen, worst first, the gain undone beside the raw
    rows = fresnel["materials"]
    assert len(rows) >= 2 and all(r["name"] for r in rows)
    assert [r["flip_mean"] for r in rows] == sorted((r["flip_mean"] for r in rows), reverse=True)
    assert all(0.85 < r["mean_ratio"] < 1.0 for r in rows if r["pixels"] > 50)
    assert fresnel["gain_corrected"]["flip_mean"] < fresnel["flip_mean"]
    assert pi["gain_corrected"]["flip_mean"] < 0.5 * pi["flip_mean"]
    # the report's first screen: the cause, the worst shapes, the gain-corrected metrics
    (case, *_) = json.loads((tmp_path / "pi_exr" / "report.json").read_text())["cases"]
    shown = case["diagnoses"]
    assert shown[0].startswith("colour: a global gain of x3.1")
    assert any(s.startswith("shape ") for s in shown)
    assert any(s.startswith("after the best per-material gain: FLIP") for s in shown)


def test_manifest_expect_gates_conformance_per_layer(plate, tmp_path, capsys):
    """``expect`` in a manifest: the shadow layer of the offset renderer fails conformance,
    the corrected one passes; the report shows the conformance metrics."""
    images = tmp_path / "images"
    images.mkdir()
    for name in ("pcf", "pcf_offset"):
        (images / f"{name}.exr").write_bytes((plate / f"{name}.exr").read_bytes())
    manifest = tmp_path / "ci.toml"
    text = f'[defaults]\nspp = 4\nexpect = "{EXPECT}"\n'
    text += "fail_above = { conformance_misclassified_fraction = 0.005 }\n"
    for name in ("pcf", "pcf_offset"):
        text += f'[scenes.{name}]\nscene = "{plate / "e"}"\nfile = "{name}.exr"\n'
        text += "channels = { shadow = {} }\n"
    manifest.write_text(text)
    out = tmp_path / "o"
    argv = ["score-folder", str(images), "--manifest", str(manifest), "--quiet"]
    assert main([*argv, "--out", str(out)]) == 1
    rec = json.loads((out / "metrics.json").read_text())
    assert list(rec["failed"]) == ["pcf_offset/shadow"]
    assert rec["scenes"]["pcf/shadow"]["conformance_misclassified_fraction"] == 0.0
    (case, *_) = json.loads((out / "pcf" / "shadow" / "report.json").read_text())["cases"]
    assert "conformance_edge_displacement_px" in case["metrics"]


def test_a_texel_fault_after_baseline_accept_is_named_in_cli_junit_and_markdown(
    plate, tmp_path, capsys
):
    """Issue 43 "must show": the correct PCF accepted as the baseline, then the same engine
    reading its map one texel over: exit 1 with the conformance regression named in the
    CLI, the JUnit XML and the Markdown summary (before: not compared, exit 0)."""
    import xml.etree.ElementTree as ET

    keys = "conformance_misclassified_fraction,conformance_edge_displacement_px"
    common = ["--channel", "shadow", "--expect", EXPECT, "--baseline-metrics", keys]
    rc, _ = _score(plate, tmp_path, "pcf.exr", *common)
    assert rc == 0
    base = tmp_path / "baselines"
    argv = ["baseline", "accept", str(tmp_path / "pcf_exr"), "--into", str(base)]
    assert main([*argv, "--note", "the correct PCF"]) == 0
    capsys.readouterr()
    junit, md = tmp_path / "ci.xml", tmp_path / "ci.md"
    extra = ["--baseline", str(base), "--junit", str(junit), "--summary-md", str(md)]
    out = tmp_path / "faulty"
    argv = ["score", str(plate / "e"), "--candidate", str(plate / "pcf_offset.exr")]
    rc = main([*argv, "--spp", "4", *common, *extra, "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 1
    assert "REGRESSION conformance_edge_displacement_px" in text
    failures = [
        c.get("name") for c in ET.parse(junit).iter("testcase") if c.find("failure") is not None
    ]
    assert "baseline conformance_edge_displacement_px" in failures
    assert "conformance\\_edge\\_displacement\\_px" in md.read_text()
