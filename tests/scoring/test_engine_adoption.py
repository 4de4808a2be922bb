"""What an engine team hit scoring a real renderer (issue 37): each fixed item, the PNG
transfer, baselines a team can live with (the metrics compared, tolerances, missing and new
cases, regressions grouped per case) and the folder scoring of the Python API, which gives
the command line's records."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.reports.formatting import fmt_number

import raster_oracle

W, H = 48, 27
SIZE = ["--width", str(W), "--height", str(H)]
SCENES = ("plate", "spot", "stripes")


@pytest.fixture(scope="module")
def engine_files(tmp_path_factory):
    """Per scene an engine-style layered EXR (``shadow.Y``, ``msaa.R/G/B``) of a 4-spp
    render (seed 7), and the 16-spp colour of the plate as 8-bit PNGs (sRGB and gamma 2.2)."""
    root = tmp_path_factory.mktemp("engine")
    (root / "images").mkdir()
    refs = {}
    for scene in SCENES:
        assert main(["export", scene, *SIZE, "--out", str(root / "exports" / scene)]) == 0
        args = ["reference", str(root / "exports" / scene), "--spp", "4", "--seed", "7", "--quiet"]
        assert main([*args, "--out", str(root / "ref" / scene)]) == 0
        ref = read_exr(root / "ref" / scene / "reference.exr")
        refs[scene] = ref
        layers = {"shadow.Y": ref["visibility"]}
        layers.update({f"msaa.{c}": ref[f"color.{c}"] for c in "RGB"})
        write_exr(root / "images" / f"{scene}.exr", layers)
    return root, refs


def _rgb(ref) -> np.ndarray:
    return np.stack([ref[f"color.{c}"] for c in "RGB"], -1).astype(np.float64)


# 1: a camera that sees no receiver ------------------------------------------------------


def test_no_receiver_in_view_is_null_not_a_traceback(tmp_path, capsys):
    """A camera looking at the sky: the shadow metrics and the edge-aware fraction are
    null (no traceback, exit 0 without gates); a gate on them is one line and exit 2."""
    up = [[1, 0, 0, 0], [0, 0, 1, 10], [0, -1, 0, 0], [0, 0, 0, 1]]  # +Z (view) -> world +Y
    cams = tmp_path / "cams.json"
    cams.write_text(json.dumps({"frames": [{"to_world": up, "fov_x_deg": 40.0}] * 2}))
    mask = np.ones((H, W), np.float32)
    for k in range(2):
        write_exr(tmp_path / f"f_{k:03d}.exr", {"Y": mask})
    argv = ["score", "plate", *SIZE, "--camera-file", str(cams), "--frames", "2"]
    argv += ["--candidate", str(tmp_path / "f_{frame:03d}.exr"), "--channel", "visibility"]
    argv += ["--spp", "1", "--no-cache", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 0
    rec = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert rec["edge_aware_error_fraction"] is None
    assert all(f["receiver_count"] == 0 for f in rec["frames"])
    capsys.readouterr()
    gate = ["--fail-above", "edge_aware_error_fraction=0.005"]
    assert main([*argv, *gate, "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err
    # no gate on nothing (issue 43 item 3): the case, the metric and the empty set named
    assert "case plate: edge_aware_error_fraction is computed over the receivers" in err
    assert "(support: 0)" in err and "Traceback" not in err
    assert rec["support"]["misclassified_fraction"] == 0 and rec["misclassified_fraction"] is None


# 2: --gate-frames judges the motion vectors too --------------------------------------------


def test_gate_frames_judges_the_motion_vectors():
    """Frame 0's vectors are zero (wrong), frames 1-2 exact: with --gate-frames 2 the
    judged motion_epe_* is the exact frames' 0, while frame 0 keeps its own error."""
    from raster_oracle.oracle.scoring.options import ScoreOptions
    from raster_oracle.oracle.scoring.request import ScoreRequest
    from raster_oracle.oracle.scoring.score import score
    from raster_oracle.oracle.scoring.temporal import truth_motion

    from raster_oracle import scenes

    base = scenes.load("plate", width=W, height=H, camera_path="rotate", n_frames=3)
    frames = [base.with_frame(k, path="rotate", n_frames=3) for k in range(3)]
    motion, _ = truth_motion(frames, seed=0, cache=None, quiet=True)

    def candidate(frame_scene, k):
        mv = np.zeros_like(motion[k]) if k == 0 else motion[k]
        return np.zeros((H, W, 3), np.float32), {"frame": k, "motion": mv}

    def request(gate_frames=None):
        options = ScoreOptions(spp=1, frames=3, camera_path="rotate", gate_frames=gate_frames)
        return ScoreRequest(base, "color", candidate, options=options)

    rec = score(request(gate_frames=2)).record
    assert rec["frames"][0]["motion_epe_mean"] > 0.2
    assert rec["motion_epe_mean"] == 0.0 and rec["motion_epe_over_half"] == 0.0
    assert score(request()).record["motion_epe_mean"] > 0.1  # all frames: frame 0 counts


# 3: exports write the camera of frame -1 ---------------------------------------------------


def test_export_records_the_previous_camera_for_frame_0(tmp_path):
    """Frame 0's motion is against frame -1 (the paths are defined there): every exported
    camera record carries the previous frame's camera, so an exact engine scores ~0 EPE on
    frame 0 too."""
    from engine_raster import velocity
    from raster_oracle.oracle.scoring.temporal import truth_motion
    from raster_oracle.scenes.formats.export import export

    from raster_oracle import scenes

    frame = scenes.load("plate", width=W, height=H, camera_path="rotate", n_frames=3)
    folder = tmp_path / "export"
    export(frame, folder)
    camera = json.loads((folder / "camera.json").read_text())
    assert camera["previous"] == frame.previous().camera.to_json()
    per_frame = json.loads((folder / "cameras" / "frame_000.json").read_text())
    assert per_frame["previous"] == camera["previous"]
    mv = velocity(folder, camera["previous"])
    truth, dis = truth_motion([frame], seed=0, cache=None, quiet=True)
    epe = np.linalg.norm(mv - truth[0], axis=-1)[~dis[0]]
    assert np.abs(truth[0]).max() > 0.5 and np.median(epe) < 0.01


# 5, 10, 11 ----------------------------------------------------------------------------


def test_manifest_default_profile_skips_kinds_it_does_not_fit(engine_files, tmp_path, capsys):
    """``profiles = ["edge-aware"]`` in ``[defaults]``: judged on the shadow layer, left out
    with a note naming the manifest key on the colour layer (it used to abort the run)."""
    root, _ = engine_files
    manifest = tmp_path / "ci.toml"
    manifest.write_text(
        f'[defaults]\nspp = 4\nexports = "{root / "exports"}"\nprofiles = ["edge-aware"]\n'
        "[scenes.plate]\nchannels = { shadow = {}, msaa = {} }\n"
    )
    argv = ["score-folder", str(root / "images"), "--manifest", str(manifest)]
    rc = main([*argv, "--quiet", "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert rc in (0, 1) and "Traceback" not in out
    assert "plate/shadow: PASS edge_aware_error_fraction" in out or (
        "plate/shadow: FAIL edge_aware_error_fraction" in out
    )
    assert "plate/msaa: [defaults].profiles edge-aware: edge_aware_error_fraction" in out
    assert "not judged" in out


def test_bad_manifest_gate_names_its_key(engine_files, tmp_path, capsys):
    root, _ = engine_files
    manifest = tmp_path / "ci.toml"
    manifest.write_text(
        f'[defaults]\nspp = 4\nexports = "{root / "exports"}"\n[scenes.plate.channels.msaa]\n'
        "fail_above = { misclassified_fraction = 0.01 }\n"
    )
    argv = ["score-folder", str(root / "images"), "--manifest", str(manifest)]
    assert main([*argv, "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "case plate/msaa: [scenes.plate].channels.msaa.fail_above misclassified_fraction" in err


def test_report_counts_cases_not_frames_and_shows_ssim_floor_digits():
    from raster_oracle.reports import build_report, make_case

    img = np.zeros((4, 4), np.float32)
    cases = [
        make_case(
            name="a",
            scene="s",
            reference=img,
            candidate=img,
            kind="visibility",
            metrics={"ssim": 1.0},
        )
    ]
    for k in range(3):
        case = make_case(
            name=f"a frame {k}",
            scene="s",
            reference=img,
            candidate=img,
            kind="visibility",
            metrics={"ssim": 1.0},
        )
        case["frame"] = k
        cases.append(case)
    summary = build_report(cases, title="t", provenance={})["summary"]
    assert summary["n_cases"] == 1 and summary["n_frames"] == 3
    assert fmt_number(0.99996) == "0.99996" and fmt_number(1.0) == "1"


@pytest.mark.parametrize("transfer", ["gamma2.2", "linear"])
def test_transfer_decodes_8bit_colour_as_stated(engine_files, tmp_path, capsys, transfer):
    """An 8-bit PNG written with a 2.2 power (or linear values) scores as the reference only
    when read with its transfer; the transfer is stated in metrics.json."""
    from PIL import Image

    _, refs = engine_files
    rgb = np.clip(_rgb(refs["plate"]), 0, 1)
    encoded = rgb ** (1 / 2.2) if transfer == "gamma2.2" else rgb
    png = tmp_path / "c.png"
    Image.fromarray(np.round(encoded * 255).astype(np.uint8), mode="RGB").save(png)
    argv = ["score", "plate", *SIZE, "--candidate", str(png), "--spp", "4", "--quiet"]
    assert main([*argv, "--transfer", transfer, "--out", str(tmp_path / "t")]) == 0
    assert main([*argv, "--out", str(tmp_path / "s")]) == 0
    right = json.loads((tmp_path / "t" / "metrics.json").read_text())
    wrong = json.loads((tmp_path / "s" / "metrics.json").read_text())
    assert right["candidate_layout"]["transfer"] == transfer
    assert wrong["candidate_layout"]["transfer"] == "srgb"
    assert right["delta_e2000_mean"] < 0.5 * wrong["delta_e2000_mean"]
    capsys.readouterr()
    exr = engine_files[0] / "images" / "plate.exr"
    bad = ["score", "plate", *SIZE, "--candidate", str(exr), "--channel", "msaa"]
    assert main([*bad, "--transfer", "gamma2.2", "--out", str(tmp_path / "x")]) == 2
    assert "--transfer applies to the colour of a PNG" in capsys.readouterr().err


# baselines: 3 scenes x 2 layers ------------------------------------------------------------


def _manifest(path, scenes_, exports):
    text = f'[defaults]\nspp = 4\nexports = "{exports}"\nfail_below = {{ ssim = 0.1 }}\n'
    for s in scenes_:
        text += f"[scenes.{s}]\nchannels = {{ shadow = {{}}, msaa = {{}} }}\n"
    path.write_text(text)
    return path


def test_manifest_baseline_missing_case_intended_change_grouped(engine_files, tmp_path, capsys):
    """A baseline of 3 scenes x 2 layers; this run lacks one scene and the plate changed on
    purpose (colour 1.5x, the shadow 2 px over: 20 metrics move): by default only the gated
    metric is compared; with every metric, one grouped REGRESSION row per case with its
    count; the missing scene is named, and fails with --baseline-strict."""
    root, refs = engine_files
    images = root / "images"
    first = tmp_path / "first"
    argv = ["score-folder", str(images), "--quiet"]
    m_all = _manifest(tmp_path / "all.toml", SCENES, root / "exports")
    assert main([*argv, "--manifest", str(m_all), "--out", str(first)]) == 0
    capsys.readouterr()
    changed = tmp_path / "changed"
    changed.mkdir()
    ref = refs["plate"]
    layers = {"shadow.Y": np.roll(ref["visibility"], 2, axis=1)}
    layers.update({f"msaa.{c}": 1.5 * ref[f"color.{c}"] for c in "RGB"})
    write_exr(changed / "plate.exr", layers)
    write_exr(changed / "spot.exr", read_exr(images / "spot.exr"))
    m_two = _manifest(tmp_path / "two.toml", ("plate", "spot"), root / "exports")
    run = ["score-folder", str(changed), "--quiet", "--manifest", str(m_two)]
    run += ["--baseline", str(first)]
    # the unchanged images without the third scene: it is named, and fails only when strict
    same = ["score-folder", str(images), "--quiet", "--manifest", str(m_two)]
    same += ["--baseline", str(first)]
    assert main([*same, "--out", str(tmp_path / "same")]) == 0
    assert "missing from this run: stripes/shadow, stripes/msaa" in capsys.readouterr().out
    assert main([*same, "--baseline-strict", "--out", str(tmp_path / "same-strict")]) == 1
    capsys.readouterr()
    # the intended change, on the gated metric (ssim) alone: one check per case, exit 1
    rc = main([*run, "--out", str(tmp_path / "gated")])
    out = capsys.readouterr().out
    rec = json.loads((tmp_path / "gated" / "metrics.json").read_text())
    assert rec["baseline"]["missing"] == ["stripes/shadow", "stripes/msaa"]
    assert "missing from this run: stripes/shadow, stripes/msaa" in out
    n_gated = sum(c["kind"] == "baseline" for c in rec["scenes"]["plate/msaa"]["gates"])
    assert rc == 1 and n_gated == 1
    # every metric: one grouped row for the changed case, its count
    rc = main([*run, "--baseline-metrics", "all", "--out", str(tmp_path / "every")])
    out = capsys.readouterr().out
    rec = json.loads((tmp_path / "every" / "metrics.json").read_text())
    moved = {c: rec["scenes"][f"plate/{c}"]["regressions"] for c in ("msaa", "shadow")}
    assert rc == 1 and sum(map(len, moved.values())) >= 20
    rows = [line for line in out.splitlines() if "REGRESSION" in line]
    assert [r.split(":")[0] for r in rows] == ["plate/shadow", "plate/msaa"]
    for row in rows:
        assert f"({len(moved[row.split(':')[0].split('/')[1]])} of " in row
    # the report's first screen too: one row per case holding its regressions and count
    summary = json.loads((tmp_path / "every" / "report.json").read_text())["summary"]
    grouped = [r for r in summary["failed_rows"] if r["kind"] == "baseline"]
    assert [(r["case"], r["count"]) for r in grouped] == [
        ("plate/shadow", len(moved["shadow"])),
        ("plate/msaa", len(moved["msaa"])),
    ]
    # tolerances (relative, absolute) take those metrics off; strict: the missing cases fail
    tol = ["--baseline-metrics", "all", "--baseline-tolerance", "flip_mean=5000%"]
    tol += ["--baseline-tolerance", "delta_e2000_mean=10"]
    rc = main([*run, *tol, "--baseline-strict", "--out", str(tmp_path / "strict")])
    out = capsys.readouterr().out
    rec = json.loads((tmp_path / "strict" / "metrics.json").read_text())
    left = rec["scenes"]["plate/msaa"]["regressions"]
    assert rc == 1 and "flip_mean" not in left and "delta_e2000_mean" not in left
    assert "ssim" in left
    assert set(rec["failed"]) >= {"stripes/shadow", "stripes/msaa"}
    # the Python API scores the same cases into the same records
    api = raster_oracle.score_folder(
        changed, manifest=m_two, out=tmp_path / "api", baseline=first, cache=True
    )
    cli = json.loads((tmp_path / "gated" / "metrics.json").read_text())
    assert set(api["scenes"]) == set(cli["scenes"]) and api["baseline"] == cli["baseline"]
    for name, case in cli["scenes"].items():
        for key in ("wall_seconds", "provenance", "candidate_info"):
            case.pop(key, None)
            api["scenes"][name].pop(key, None)
        assert api["scenes"][name] == case, name


def test_help_and_docs_say_what_the_commands_do(capsys):
    """9: --frames names no default path (score refuses without one), the cache variable
    that works is documented, score's SCENE list names glTF files and exports."""
    from pathlib import Path

    assert main(["score", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "default dolly" not in text and "--transfer" in text and "--baseline-strict" in text
    cli = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    assert "RASTER_ORACLE_CACHE_DIR" in cli and "for\na glTF scene, `scene.glb`" in cli


# 7: a sub-pixel shift of a mask's edges is named ------------------------------------------


def test_subpixel_shift_of_a_shadow_mask_is_named(engine_files, tmp_path, capsys):
    """A shadow mask moved by 0.6 px (no whole-pixel shift explains it) is named with its
    shift estimated; the unmoved mask gets no such note."""
    from raster_oracle.metrics.shift import apply_shift

    root, refs = engine_files
    vis = refs["plate"]["visibility"].astype(np.float64)
    write_exr(tmp_path / "moved.exr", {"Y": apply_shift(vis, 0.6, 0.0).astype(np.float32)})
    argv = ["score", str(root / "exports" / "plate"), "--candidate", str(tmp_path / "moved.exr")]
    assert main([*argv, "--spp", "16", "--quiet", "--out", str(tmp_path / "o")]) == 0
    rec = json.loads((tmp_path / "o" / "metrics.json").read_text())
    (note,) = [d["message"] for d in rec["diagnoses"] if "edges shifted by" in d["message"]]
    dx = float(note.split("edges shifted by (")[1].split(",")[0])
    assert abs(dx - 0.6) < 0.15 and "sub-pixel" in note
    assert "edges shifted by" in capsys.readouterr().out


def test_manifest_reads_transfer_expect_and_baseline_keys(tmp_path):
    from raster_oracle.oracle.scoring.inputs.manifest import ManifestError, read_manifest

    path = tmp_path / "ci.toml"
    path.write_text(
        '[defaults]\ntransfer = "gamma2.2"\nbaseline_metrics = ["flip_mean", "ssim"]\n'
        'baseline_tolerance = { flip_mean = "5%", ssim = 0.001 }\n'
        '[scenes.plate.channels.shadow]\nexpect = "shadow-map:resolution=256"\n'
        'baseline_metrics = "all"\n'
    )
    (case,) = read_manifest(path).cases
    assert case.transfer == "gamma2.2" and case.expect == "shadow-map:resolution=256"
    assert case.baseline == {
        "metrics": "all",
        "tolerances": {"flip_mean": (0.05, True), "ssim": (0.001, False)},
    }
    for bad, key in (
        ('transfer = "gamma2.4"', "[scenes.plate].channels.shadow.transfer"),
        ('baseline_tolerance = { flip_mean = "x%" }', "[defaults].baseline_tolerance"),
        ('baseline_metrics = ["nope"]', "[defaults].baseline_metrics"),
    ):
        where = "[scenes.plate.channels.shadow]\n" if "transfer" in bad else ""
        text = (
            f"[defaults]\n{bad}\n[scenes.plate.channels.shadow]\n"
            if not where
            else (f"[scenes.plate.channels.shadow]\n{bad}\n")
        )
        path.write_text(text)
        with pytest.raises(ManifestError, match=key.replace("[", r"\[").replace("]", r"\]")):
            read_manifest(path)


def test_api_score_image_takes_transfer_and_expect(engine_files, tmp_path):
    from PIL import Image

    root, refs = engine_files
    rgb = np.clip(_rgb(refs["plate"]), 0, 1) ** (1 / 2.2)
    png = tmp_path / "c.png"
    Image.fromarray(np.round(rgb * 255).astype(np.uint8), mode="RGB").save(png)
    scene = root / "exports" / "plate"
    rec = raster_oracle.score_image(scene, png, spp=4, transfer="gamma2.2")
    assert rec["candidate_layout"]["transfer"] == "gamma2.2"
    mask = refs["plate"]["visibility"]
    rec = raster_oracle.score_image(scene, mask, spp=4, expect="shadow-map:resolution=256")
    assert rec["conformance"]["technique"] == "shadow-map"
    assert rec["conformance_misclassified_fraction"] is not None
    with pytest.raises(raster_oracle.InputError, match="--expect"):
        raster_oracle.score_image(scene, mask, spp=4, expect="no-such-technique")
