"""What `score` reads and writes (issue 17): candidate kinds inferred only when unambiguous,
layered EXR channels as engines write them, export folders, the memory estimate, reused
--out folders, multi-frame records."""

from __future__ import annotations

import json

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr

W, H = 48, 27
SIZE = ["--width", str(W), "--height", str(H)]


def _engine_exr(path, layers: dict) -> None:
    """Write an EXR with OpenEXR's own API, as an engine does (half channels, layers)."""
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    chans = {k: np.ascontiguousarray(v, dtype=np.float16) for k, v in layers.items()}
    with OpenEXR.File(header, chans) as f:
        f.write(str(path))


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    """A 4-spp reference of the plate: stands for an engine's (noisy) render."""
    root = tmp_path_factory.mktemp("ref")
    args = ["reference", "plate", *SIZE, "--spp", "4", "--seed", "3", "--quiet"]
    assert main([*args, "--out", str(root)]) == 0
    return read_exr(root / "reference.exr")


def _score(tmp_path, candidate, *extra, out="s"):
    code = main(
        ["score", "plate", *SIZE, "--candidate", str(candidate), "--spp", "4", "--quiet"]
        + ["--out", str(tmp_path / out), *extra]
    )
    record = None
    if (tmp_path / out / "metrics.json").is_file():
        record = json.loads((tmp_path / out / "metrics.json").read_text())
    return code, record


def _rgb(ref):
    return np.stack([ref[f"color.{c}"] for c in "RGB"], -1)


# --------------------------------------------------------------------------- kinds


def test_grey_exr_y_scored_as_visibility(tmp_path, ref, capsys):
    path = tmp_path / "shadow.exr"
    _engine_exr(path, {"Y": ref["visibility"]})
    code, rec = _score(tmp_path, path)
    assert code == 0
    assert rec["channel"] == "visibility"
    assert rec["visibility_mae"] is not None and rec["misclassified_fraction"] is not None
    assert rec["delta_e2000_mean"] is None
    assert "candidate shadow.exr: visibility from channel 'Y'" in capsys.readouterr().out


def test_grey_png_scored_as_visibility(tmp_path, ref):
    path = tmp_path / "shadow.png"
    Image.fromarray(np.round(ref["visibility"] * 255).astype(np.uint8), mode="L").save(path)
    code, rec = _score(tmp_path, path)
    assert code == 0 and rec["channel"] == "visibility"
    assert rec["visibility_mae"] is not None
    # 8-bit quantisation of a 4-spp mask: within half a level of the EXR
    assert rec["visibility_mae"] < 0.2


def test_grey_alpha_and_16bit_png_are_visibility(tmp_path):
    from raster_oracle.oracle.scoring.inputs.layout import candidate_layout

    la = tmp_path / "la.png"
    Image.fromarray(np.zeros((H, W, 2), np.uint8), mode="LA").save(la)
    g16 = tmp_path / "g16.png"
    Image.fromarray(np.zeros((H, W), np.uint16)).save(g16)
    rgb = tmp_path / "rgb.png"
    Image.fromarray(np.zeros((H, W, 3), np.uint8), mode="RGB").save(rgb)
    assert candidate_layout(la).kind == "visibility"
    assert candidate_layout(g16).kind == "visibility"
    assert candidate_layout(rgb).kind == "color"
    assert candidate_layout(la, channel="coverage").kind == "coverage"


def test_two_layers_without_channel_is_exit_2_naming_them(tmp_path, ref, capsys):
    path = tmp_path / "frame.exr"
    layers = {f"color.{c}": ref[f"color.{c}"] for c in "RGB"}
    _engine_exr(path, {**layers, "shadow.Y": ref["visibility"]})
    code, rec = _score(tmp_path, path)
    err = capsys.readouterr().err
    assert code == 2 and rec is None
    assert "holds several images (color, shadow.Y)" in err
    assert "--channel color or shadow.Y" in err
    assert "Traceback" not in err


def test_rgb_plus_coverage_is_ambiguous(tmp_path):
    from raster_oracle.oracle.scoring.inputs.candidates import CandidateError
    from raster_oracle.oracle.scoring.inputs.layout import candidate_layout

    path = tmp_path / "c.exr"
    z = np.zeros((H, W))
    _engine_exr(path, {"R": z, "G": z, "B": z, "A": z, "msaa.coverage": z})
    with pytest.raises(CandidateError, match=r"several images \(color, msaa\.coverage\)"):
        candidate_layout(path)


# --------------------------------------------------------------------------- layers


def test_channel_finds_engine_layers(tmp_path, ref, capsys):
    path = tmp_path / "engine.exr"
    cov = ref["coverage"] if "coverage" in ref else None
    assert cov is not None
    layers = {f"color.{c}": ref[f"color.{c}"] for c in "RGB"}
    _engine_exr(path, {**layers, "shadow.Y": ref["visibility"], "msaa.coverage": cov})
    code, rec = _score(tmp_path, path, "--channel", "msaa.coverage", out="cov")
    assert code == 0 and rec["channel"] == "coverage"
    assert rec["coverage_mae"] is not None
    code, rec = _score(tmp_path, path, "--channel", "shadow", out="vis")
    assert code == 0 and rec["channel"] == "visibility"
    assert rec["misclassified_fraction"] is not None
    code, rec = _score(tmp_path, path, "--channel", "color", out="col")
    assert code == 0 and rec["channel"] == "color" and rec["delta_e2000_mean"] is not None
    # the kinds keep finding their layers
    code, rec = _score(tmp_path, path, "--channel", "coverage", out="cov2")
    assert code == 0 and rec["channel"] == "coverage"
    out = capsys.readouterr().out
    assert "candidate engine.exr: coverage from channel 'msaa.coverage'" in out
    assert "candidate engine.exr: visibility from channel 'shadow.Y'" in out


def test_layer_with_rgb_is_colour_and_kind_overrides(tmp_path):
    from raster_oracle.oracle.scoring.inputs.layout import candidate_layout

    path = tmp_path / "c.exr"
    z = np.zeros((H, W))
    _engine_exr(path, {"beauty.R": z, "beauty.G": z, "beauty.B": z, "mask.V": z})
    lay = candidate_layout(path, channel="beauty")
    assert (lay.kind, lay.names) == ("color", ("beauty.R", "beauty.G", "beauty.B"))
    lay = candidate_layout(path, channel="mask", kind="coverage")
    assert (lay.kind, lay.names) == ("coverage", ("mask.V",))


def test_channel_miss_lists_channels_and_layers(tmp_path, ref, capsys):
    path = tmp_path / "engine.exr"
    _engine_exr(path, {"shadow.Y": ref["visibility"], "Z": ref["visibility"]})
    code, _ = _score(tmp_path, path, "--channel", "msaa.coverage")
    err = capsys.readouterr().err
    assert code == 2
    assert "no channel or layer 'msaa.coverage'" in err
    assert "channels: Z, shadow.Y; layers: shadow" in err


# --------------------------------------------------------------------------- exports


def test_score_export_dir_at_its_size_and_mismatch_names_fix(tmp_path, capsys):
    exp = tmp_path / "exp"
    assert main(["export", "plate", "--width", "40", "--height", "24", "--out", str(exp)]) == 0
    rdir = tmp_path / "r"
    args = ["reference", str(exp), "--spp", "4", "--seed", "5", "--quiet", "--out", str(rdir)]
    assert main(args) == 0
    vis = read_exr(rdir / "reference.exr")["visibility"]
    assert vis.shape == (24, 40)
    cand = exp / "render" / "shadow.exr"
    cand.parent.mkdir()
    _engine_exr(cand, {"Y": vis})
    common = ["--candidate", str(cand), "--spp", "4", "--quiet"]
    assert main(["score", str(exp), *common, "--out", str(tmp_path / "a")]) == 0
    rec = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert rec["channel"] == "visibility" and rec["visibility_mae"] is not None
    report = json.loads((tmp_path / "a" / "report.json").read_text())
    assert report["title"] == "shadow.exr on exp"  # named after the export folder
    xml = str(exp / "scene.xml")
    assert main(["score", xml, *common, "--out", str(tmp_path / "b")]) == 0
    capsys.readouterr()
    code = main(["score", "plate", *common, "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err
    assert code == 2
    assert "candidate is 40x24, the reference is 160x90" in err
    assert "pass --width 40 --height 24" in err
    assert f"score the export folder {exp.resolve()} that wrote it" in err
    assert not (tmp_path / "c").exists()


# --------------------------------------------------------------------------- memory guard


def test_memory_estimate_grows_with_size_spp_and_channels():
    from raster_oracle.oracle.reference.render import estimate_memory

    vis = ("visibility", "edge", "id", "normal", "position")
    col = ("color", "edge", "id")
    small = estimate_memory(160, 90, spp=4, channels=vis)
    assert estimate_memory(160, 90, spp=64, channels=vis) > small
    assert estimate_memory(320, 180, spp=64, channels=vis) > estimate_memory(
        160, 90, spp=64, channels=vis
    )
    assert estimate_memory(320, 180, spp=64, channels=col) > estimate_memory(
        320, 180, spp=64, channels=vis
    )
    # a launch is at most SAMPLES_PER_CHUNK samples: spp beyond it adds nothing
    assert estimate_memory(320, 180, spp=4096, channels=vis) == estimate_memory(
        320, 180, spp=1024, channels=vis
    )
    # the refusal: a 320x180 64-spp score on a machine with 1.4 GiB free
    assert estimate_memory(320, 180, spp=64, channels=col) < 0.5 * 2**30


def test_small_reference_not_refused_with_little_memory(monkeypatch):
    from raster_oracle.oracle.reference import render
    from raster_oracle.oracle.reference import settings as settings_module
    from raster_oracle.oracle.reference.render import ReferenceSettings, ReferenceSettingsError

    from raster_oracle import scenes

    loaded = scenes.load("plate", width=320, height=180)
    settings = ReferenceSettings(spp=64, channels=("visibility", "edge", "id"))
    monkeypatch.setattr(settings_module, "available_memory", lambda: int(1.4 * 2**30))
    channels, _ = render.render_reference(loaded, settings, quiet=True)
    assert channels["visibility"].shape == (180, 320)
    monkeypatch.setattr(settings_module, "available_memory", lambda: 32 << 20)
    with pytest.raises(ReferenceSettingsError, match=r"320x180 reference at 64 spp needs about"):
        render.render_reference(loaded, settings, quiet=True)


# --------------------------------------------------------------------------- reused --out


def test_reused_out_holds_only_this_runs_files(tmp_path, ref):
    vis = tmp_path / "v.exr"
    _engine_exr(vis, {"Y": ref["visibility"]})
    col = tmp_path / "c.exr"
    _engine_exr(col, {c: ref[f"color.{c}"] for c in "RGB"})
    out = tmp_path / "s"
    assert _score(tmp_path, vis)[0] == 0
    assert (out / "visibility_error.png").is_file() and (out / "misclassified.png").is_file()
    (out / "notes.txt").write_text("mine")
    code, rec = _score(tmp_path, col)
    assert code == 0
    files = {p.name for p in out.iterdir()}
    assert files == set(rec["files"]) | {"notes.txt"}
    assert not (out / "visibility_error.png").exists()
    assert (out / "delta_e2000.png").is_file()
    # a folder from before the manifest: its record's maps name its PNGs
    legacy = json.loads((out / "metrics.json").read_text())
    del legacy["files"]
    (out / "metrics.json").write_text(json.dumps(legacy))
    code, rec = _score(tmp_path, vis)
    assert code == 0 and not (out / "delta_e2000.png").exists()
    assert {p.name for p in out.iterdir()} == set(rec["files"]) | {"notes.txt"}


# --------------------------------------------------------------------------- frames


def test_added_flicker_is_non_negative_closed_form():
    from raster_oracle.metrics import flicker
    from raster_oracle.oracle.scoring.score import added_flicker

    ref = np.zeros((2, 4, 4))
    ref[1] = 0.5  # the reference changes by 0.5 everywhere
    cand = np.zeros((2, 4, 4))
    cand[1, :, 2:] = 1.0  # steady on the left, a change of 1 on the right
    assert flicker(ref, cand) == pytest.approx(0.0)  # steadiness cancels the flicker
    assert added_flicker(ref, cand) == pytest.approx(0.25)  # 0.5 excess on half the pixels
    assert added_flicker(ref, ref) == 0.0
    assert added_flicker(ref, np.zeros_like(ref)) == 0.0  # steadier is not negative


def test_two_frame_record_and_report(tmp_path):
    path_args = ["--camera-path", "subpixel-pan", "--frames", "2"]
    for k in range(2):
        out = tmp_path / f"r{k}"
        args = ["reference", "plate", *SIZE, "--spp", "4", "--seed", "9", "--quiet"]
        args += [*path_args, "--frame", str(k), "--channels", "visibility", "--out", str(out)]
        assert main(args) == 0
        vis = read_exr(out / "reference.exr")["visibility"]
        # frame 1 crawls: a checkerboard of flipped pixels the reference does not have
        if k == 1:
            vis = vis.copy()
            vis[::2, ::2] = 1.0 - vis[::2, ::2]
        _engine_exr(tmp_path / f"frame_{k:03d}.exr", {"Y": vis})
    code, rec = _score(tmp_path, tmp_path / "frame_{frame:03d}.exr", *path_args)
    assert code == 0
    assert [f["visibility_mae"] is not None for f in rec["frames"]] == [True, True]
    assert rec["frames"][1]["visibility_mae"] > rec["frames"][0]["visibility_mae"]
    assert rec["flicker"] > 0
    assert rec["noise_floor"]["flicker"] >= 0
    assert rec["flicker"] > rec["noise_floor"]["flicker"]
    assert "temporal_error" in rec["noise_floor"]
    report = json.loads((tmp_path / "s" / "report.json").read_text())
    text = json.dumps(report)
    assert "{frame" not in text and "frame_{" not in text
    assert "subpixel-pan frames 0-1 on plate" in text
    names = [c["name"] for c in report["cases"]]
    assert "subpixel-pan frames 0-1 frame 0" in names
    assert "subpixel-pan frames 0-1 frame 1" in names


# --------------------------------------------------------------------------- progress


def test_no_progress_bar_off_a_terminal(capsys):
    from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
    from raster_oracle.oracle.sweeps.run import _progress

    from raster_oracle import scenes

    loaded = scenes.load("plate", width=16, height=9)
    render_reference(loaded, ReferenceSettings(spp=4, channels=("visibility",)), quiet=False)
    bar = _progress(3, quiet=False, desc="cases")
    bar.update(3)
    bar.close()
    err = capsys.readouterr().err  # captured stderr is not a terminal: no bar redraws
    assert "\r" not in err
    assert err.splitlines() == ["cases: 3/3 cases (100%), 0 s"]  # plain lines for a CI log


# --------------------------------------------------------------------------- score-folder


def test_score_folder_by_scene_and_frame(tmp_path, capsys):
    root = tmp_path / "engine"
    (root / "spot").mkdir(parents=True)
    (root / "notes.txt").write_text("not an image")
    refs = tmp_path / "refs"
    common = ["--spp", "4", "--seed", "2", "--quiet", "--channels", "visibility"]
    assert main(["reference", "plate", *common, "--out", str(refs / "plate")]) == 0
    _engine_exr(root / "plate.exr", {"Y": read_exr(refs / "plate" / "reference.exr")["visibility"]})
    for k in range(2):
        out = refs / f"spot{k}"
        path = ["--camera-path", "dolly", "--frames", "2", "--frame", str(k)]
        assert main(["reference", "spot", *common, *path, "--out", str(out)]) == 0
        vis = read_exr(out / "reference.exr")["visibility"]
        _engine_exr(root / "spot" / f"frame_{k:03d}.exr", {"Y": vis})
    args = ["score-folder", str(root), "--spp", "4", "--quiet", "--out", str(tmp_path / "o")]
    # frames without the path they were rendered along: exit 2 (it used to be dolly, unsaid)
    assert main([*args, "--fail-above", "visibility_mae=0.5"]) == 2
    assert "--camera-path" in capsys.readouterr().err
    args += ["--camera-path", "dolly"]
    assert main([*args, "--fail-above", "visibility_mae=0.5"]) == 0
    combined = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert sorted(combined["scenes"]) == ["plate", "spot"]
    assert combined["failed"] == {}
    assert combined["scenes"]["plate"]["channel"] == "visibility"
    assert combined["scenes"]["plate"]["frames"] is None
    assert len(combined["scenes"]["spot"]["frames"]) == 2
    assert combined["scenes"]["spot"]["flicker"] >= 0
    assert (tmp_path / "o" / "report.html").is_file()
    assert (tmp_path / "o" / "spot" / "metrics.json").is_file()
    # a gate that a scene fails: exit 1, named
    assert main([*args, "--fail-above", "visibility_mae=0"]) == 1
    captured = capsys.readouterr()
    assert "plate: failed: visibility_mae <= 0" in captured.err
    assert "plate: FAIL visibility_mae " in captured.out
    # a file named after no scene: exit 2 before anything is rendered
    (root / "nosuch.exr").write_bytes((root / "plate.exr").read_bytes())
    assert main([*args[:-1], str(tmp_path / "o2")]) == 2
    assert "'nosuch' is not a built-in scene" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()


def test_candidate_name_never_the_raw_pattern():
    from raster_oracle.oracle.scoring.inputs.frames import candidate_name

    pat = "out/frame_{frame:03d}.exr"
    assert candidate_name(pat, frames=8, camera_path="dolly") == "dolly frames 0-7"
    assert candidate_name(pat, frames=None, camera_path="dolly") == "frame_000.exr"
    assert candidate_name("out/x.png", frames=None, camera_path=None) == "x.png"
