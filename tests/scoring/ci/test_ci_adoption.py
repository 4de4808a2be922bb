"""An engine team gates its builds on the oracle (issue 25): one test per friction.

1. one verdict: exit code, ``metrics.json``'s ``failed``, JUnit and the report name the same
   failed gates and regressions;
2. output paths checked before any work;
3. values just outside their range clamped with one warning, beyond it refused with the
   values;
4. baselines that survive a re-render, ``--platform`` and ``baseline accept``.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.scenes import SceneError
from raster_oracle.scenes.inputs import read_export_record

SIZE = ["--width", "48", "--height", "27"]
SPP = ["--spp", "16"]


@pytest.fixture(scope="module")
def cands(tmp_path_factory):
    """The plate at 48x27: its 16-spp seed-0 reference as an exact visibility candidate, a
    4-spp render (noisy: it regresses against the exact one) and the exact colour."""
    root = tmp_path_factory.mktemp("ci")
    for name, spp, seed in (("exact", 16, 0), ("noisy", 4, 7)):
        args = ["reference", "plate", *SIZE, "--spp", str(spp), "--seed", str(seed)]
        assert main([*args, "--out", str(root / name), "--quiet"]) == 0
    files = {"root": root}
    for name in ("exact", "noisy"):
        ref = read_exr(root / name / "reference.exr")
        files[f"{name}_vis"] = root / f"{name}_vis.exr"
        write_exr(files[f"{name}_vis"], {"visibility": ref["visibility"]})
        files[f"{name}_rgb"] = root / f"{name}_rgb.exr"
        write_exr(files[f"{name}_rgb"], {c: ref[f"color.{c}"] for c in "RGB"})
    files["exact_ref"] = read_exr(root / "exact" / "reference.exr")
    files["exports"] = root / "exports"
    export = ["export", "plate", *SIZE, "--out", str(root / "exports" / "plate")]
    assert main(export) == 0
    return files


def _score(tmp_path, capsys, candidate, *extra, out="s"):
    out_dir = tmp_path / out
    argv = ["score", "plate", *SIZE, *SPP, "--candidate", str(candidate), "--quiet"]
    rc = main([*argv, "--out", str(out_dir), *extra])
    said = capsys.readouterr()
    return rc, out_dir, said.out, said.err


def _failed_junit(path) -> list[str]:
    cases = ET.parse(path).getroot().iter("testcase")
    return [c.get("name") for c in cases if c.find("failure") is not None]


# 1 ------------------------------------------------------------------------------------------


def test_one_verdict_for_gates_and_regressions(tmp_path, capsys, cands):
    """A run that exits 1 on regressions alone used to show PASS and 0 fail in the report and
    ``failed: []`` in ``metrics.json``: every output now names the same failed checks."""
    vis = ["--channel", "visibility"]
    rc, first, _, _ = _score(tmp_path, capsys, cands["exact_vis"], *vis, out="first")
    assert rc == 0
    junit = tmp_path / "j.xml"
    extra = ["--baseline", str(first), "--junit", str(junit), "--fail-below", "ssim=0.1"]
    extra += ["--baseline-metrics", "all"]
    rc, out, text, err = _score(tmp_path, capsys, cands["noisy_vis"], *vis, *extra, out="worse")
    m = json.loads((out / "metrics.json").read_text())
    assert rc == 1 and m["exit_code"] == 1
    names = m["failed"]
    assert names and all(n.startswith("baseline ") for n in names)  # regressions only
    assert "baseline visibility_mae" in names
    assert _failed_junit(junit) == names
    assert f"failed: {', '.join(names)}" in err
    # every failed check carries the metric, both values and both floors
    for g in m["gates"]:
        if not g["passed"]:
            assert g["value"] is not None and g["previous"] is not None
            assert g["noise_floor"] is not None and g["previous_noise_floor"] is not None
            assert g["line"] in text
    report = json.loads((out / "report.json").read_text())
    assert report["summary"]["n_fail"] == 1 and report["summary"]["n_pass"] == 0
    assert [c["name"] for c in report["summary"]["failed_checks"]] == names
    assert report["cases"][0]["status"] == "fail"
    page = (out / "report.html").read_text()
    verdict = page[page.index('id="verdict"') : page.index('id="summary"')]
    assert "FAIL" in verdict and all(n in verdict for n in names)
    assert "regression" in verdict
    # provenance is at the bottom, after every case
    assert page.index('id="provenance"') > page.rindex('class="card case')
    # where: the failing case's worst tiles are in the verdict card
    assert verdict.count('class="crop"') >= 3
    # the gated and regressed metrics are the summary table's first columns
    gated = {"ssim"} | {g["metric"] for g in m["gates"] if not g["passed"]}
    assert set(report["metric_names"][: len(gated)]) == gated
    # JUnit passing cases carry their numbers as properties
    ok = [c for c in ET.parse(junit).getroot().iter("testcase") if c.get("name") == "ssim >= 0.1"]
    props = {p.get("name"): p.get("value") for p in ok[0].iter("property")}
    assert float(props["value"]) == m["ssim"] and float(props["limit"]) == 0.1
    assert float(props["noise_floor"]) == m["noise_floor"]["ssim"]


# 2 ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["score", "score-folder"])
def test_output_paths_checked_before_any_work(tmp_path, capsys, cands, command):
    """``--junit`` (and ``--summary-md``) that cannot be written used to end in a traceback
    with exit 1 after all the scoring: now exit 2, one line, nothing written."""
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    folder = tmp_path / "shots"
    folder.mkdir()
    write_exr(folder / "plate.exr", {"visibility": cands["exact_ref"]["visibility"]})
    out = tmp_path / "out"
    if command == "score":
        head = ["score", "plate", *SIZE, "--candidate", str(cands["exact_vis"])]
    else:
        head = ["score-folder", str(folder), "--exports", str(cands["exports"])]
    bad = [
        ["--junit", str(blocker / "j.xml")],  # its folder is a file
        ["--junit", str(folder)],  # a folder
        ["--summary-md", str(blocker / "s.md")],
        ["--junit", str(tmp_path / "x.xml"), "--summary-md", str(tmp_path / "x.xml")],
        ["--junit", str(out / "metrics.json")],  # one of --out's own files
    ]
    for extra in bad:
        capsys.readouterr()
        rc = main([*head, *SPP, "--quiet", "--out", str(out), *extra])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2, extra
        assert len(err) == 1 and "Traceback" not in err[0], err
        assert not out.exists()
    # a missing folder of the JUnit and summary files is created when they are written
    junit, summary = tmp_path / "ci" / "deep" / "j.xml", tmp_path / "ci" / "s.md"
    extra = ["--junit", str(junit), "--summary-md", str(summary)]
    rc = main([*head, *SPP, "--quiet", "--out", str(out), *extra])
    assert rc == 0 and junit.is_file() and summary.read_text().startswith("## raster-oracle: PASS")


# 3 ------------------------------------------------------------------------------------------


def _warnings(err: str) -> list[str]:
    return [t for t in err.splitlines() if t.startswith("raster-oracle: warning:")]


@pytest.mark.parametrize(("value", "shown"), [(1.0000002, "max 1.0000002"), (-1e-7, "min -1e-07")])
def test_mask_just_outside_its_range_is_clamped_with_one_warning(
    tmp_path, capsys, cands, value, shown
):
    """Half-float conversion and resolves give 1.0000002 or -1e-7: clamped, one warning
    with the count and the value to float32's own digits; the score equals the clean one."""
    vis = cands["exact_ref"]["visibility"].copy()
    lit = np.flatnonzero(vis.ravel() == (1.0 if value > 1 else 0.0))[:3]
    vis.ravel()[lit] = value
    path = tmp_path / "mask.exr"
    write_exr(path, {"visibility": vis})
    rc, out, _, err = _score(tmp_path, capsys, path, "--channel", "visibility")
    assert rc == 0, err
    (line,) = _warnings(err)
    assert "clamped 3 visibility values" in line and shown in line
    m = json.loads((out / "metrics.json").read_text())
    assert m["visibility_mae"] == 0.0  # the clamped mask is the reference itself


def test_beyond_the_tolerance_is_refused_with_the_values(tmp_path, capsys, cands):
    vis = cands["exact_ref"]["visibility"].copy()
    vis[0, 0], vis[0, 1] = 1.0002, -0.00011
    path = tmp_path / "mask.exr"
    write_exr(path, {"visibility": vis})
    rc, out, _, err = _score(tmp_path, capsys, path, "--channel", "visibility")
    (line,) = err.strip().splitlines()
    assert rc == 2 and not out.exists()
    assert "2 values outside" in line and "min -0.00011" in line and "max 1.0002" in line


def test_slightly_negative_radiance_is_clamped_relative_to_the_maximum(tmp_path, capsys, cands):
    ref = cands["exact_ref"]
    rgb = {c: ref[f"color.{c}"].copy() for c in "RGB"}
    peak = max(float(v.max()) for v in rgb.values())
    rgb["R"][5, 5] = -1e-6  # a filter's ringing: 1e-6 is far below 1e-4 x the maximum
    path = tmp_path / "beauty.exr"
    write_exr(path, rgb)
    rc, _, _, err = _score(tmp_path, capsys, path, "--channel", "color")
    assert rc == 0 and peak > 0.01
    (line,) = _warnings(err)
    assert "clamped 1 color values" in line and "min -1e-06" in line
    rgb["R"][5, 5] = -2e-4 * peak  # beyond the tolerance: refused, the value named
    write_exr(path, rgb)
    rc, _, _, err = _score(tmp_path, capsys, path, "--channel", "color")
    assert rc == 2 and f"min {float(np.float32(-2e-4 * peak)):.6g}" in err


# 4 ------------------------------------------------------------------------------------------


BIG = ["--width", "96", "--height", "54", "--spp", "64"]


def _noisy_plate(tmp_path):
    """A 4-spp render of the plate at 96x54 as an engine's mask: at 64 spp a few of its
    pixels differ significantly from the reference (the issue's 0.0034)."""
    args = ["reference", "plate", *BIG[:4], "--spp", "4", "--seed", "7", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "noisy")]) == 0
    path = tmp_path / "noisy.exr"
    write_exr(path, {"visibility": read_exr(tmp_path / "noisy" / "reference.exr")["visibility"]})
    return path


def _score_big(tmp_path, capsys, candidate, *extra, out):
    out_dir = tmp_path / out
    argv = ["score", "plate", *BIG, "--candidate", str(candidate), "--quiet"]
    rc = main([*argv, "--out", str(out_dir), *extra])
    said = capsys.readouterr()
    return rc, out_dir, said.out, said.err


def test_unchanged_candidate_against_a_rerendered_reference_is_no_regression(
    tmp_path, capsys, cands
):
    """``significant_fraction`` had a noise floor of 0: the same candidate scored against a
    reference rendered with ``--seed 1`` was a regression. Its floor is now the binomial
    bound of the flagged fraction; a run is approved with ``baseline accept`` per platform,
    keeping the previous approval and its note."""
    noisy = _noisy_plate(tmp_path)
    vis = ["--channel", "visibility", "--platform", "linux-llvm"]
    rc, first, _, _ = _score_big(tmp_path, capsys, noisy, *vis, out="first")
    m = json.loads((first / "metrics.json").read_text())
    assert rc == 0 and m["platform"] == "linux-llvm"
    p, n = m["significant_fraction"], 96 * 54
    assert 0 < p < 0.5
    assert m["noise_floor"]["significant_fraction"] == pytest.approx(2 * np.sqrt(p * (1 - p) / n))
    base = tmp_path / "baselines"
    note = ["--note", "first approved run"]
    assert main(["baseline", "accept", str(first), "--into", str(base), *note]) == 0
    assert (base / "linux-llvm" / "metrics.json").is_file()
    # the same candidate against the seed-1 reference: every metric within both floors
    extra = ["--seed", "1", "--baseline", str(base)]
    rc, second, text, err = _score_big(tmp_path, capsys, noisy, *vis, *extra, out="s2")
    assert rc == 0, text + err
    assert "REGRESSION" not in text and "0 regressed" in text
    # approving the second keeps the first under previous/001 with its note
    note2 = ["--note", "oracle seed 1"]
    assert main(["baseline", "accept", str(second), "--into", str(base), *note2]) == 0
    approved = json.loads((base / "linux-llvm" / "baseline.json").read_text())
    kept = json.loads((base / "linux-llvm" / "previous" / "001" / "baseline.json").read_text())
    assert approved["note"] == "oracle seed 1" and approved["previous"] == "previous/001"
    assert kept["note"] == "first approved run"
    assert (
        json.loads((base / "linux-llvm" / "previous" / "001" / "metrics.json").read_text())[
            "reference"
        ]["seed"]
        == 0
    )
    # another platform has no baseline there: exit 2 naming the ones it has
    capsys.readouterr()
    other = ["--channel", "visibility", "--platform", "win-d3d12", "--baseline", str(base)]
    rc, _, _, err = _score_big(tmp_path, capsys, noisy, *other, out="s3")
    assert rc == 2 and "win-d3d12" in err and "linux-llvm" in err
    # a run's own folder given as a baseline of another platform: refused before scoring
    rc, _, _, err = _score_big(tmp_path, capsys, noisy, *other[:-1], str(first), out="s4")
    assert rc == 2 and "platform linux-llvm vs win-d3d12" in err
    # an approval needs a note
    assert main(["baseline", "accept", str(second), "--into", str(base), "--note", " "]) == 2


# 5 and 6 ------------------------------------------------------------------------------------


def test_mask_off_receivers_only_scores_like_the_exact_one(tmp_path, capsys):
    """Engines write 1 (lit) outside a spot light's cone, where the oracle's visibility is 0:
    a mask exact on the receivers and flipped everywhere else scores exactly as the exact
    mask (FLIP, SSIM, PSNR and the Z-test used to see those pixels); they are counted."""
    from raster_oracle.oracle.scoring.score import reference_receivers
    from raster_oracle.scenes.inputs import load_input

    args = ["reference", "spot", *SIZE, *SPP, "--quiet", "--out", str(tmp_path / "ref")]
    assert main(args) == 0
    ref = read_exr(tmp_path / "ref" / "reference.exr")
    rec = reference_receivers(ref, load_input("spot", width=48, height=27).light)
    vis = ref["visibility"]
    n = int((~rec).sum())
    assert n > 100  # outside the cone
    exact, engine = tmp_path / "exact.exr", tmp_path / "engine.exr"
    write_exr(exact, {"visibility": vis})
    write_exr(engine, {"visibility": np.where(rec, vis, 1.0 - vis).astype(np.float32)})
    got = {}
    for path in (exact, engine):
        out = tmp_path / path.stem
        argv = ["score", "spot", *SIZE, *SPP, "--candidate", str(path), "--quiet"]
        assert main([*argv, "--channel", "visibility", "--out", str(out)]) == 0
        got[path.stem] = json.loads((out / "metrics.json").read_text())
    text = capsys.readouterr().out
    for key in ("visibility_mae", "flip_mean", "ssim", "psnr_db", "significant_fraction"):
        assert got["engine"][key] == got["exact"][key], key
    differ = int(((1.0 - vis != vis) & ~rec).sum())  # a 0.5 pixel flips to itself
    assert got["engine"]["outside_receivers"] == {"pixels": n, "differing": differ}
    assert differ > 100 and f"{differ} of the {n} pixels off the oracle's receivers" in text
    assert got["exact"]["outside_receivers"]["differing"] == 0


def test_visibility_convention_is_stated(tmp_path, capsys, cands):
    vis = cands["exact_ref"]["visibility"]
    path = tmp_path / "shadow_factor.exr"
    write_exr(path, {"visibility": (1.0 - vis).astype(np.float32)})
    args = ["--channel", "visibility", "--visibility", "1-is-shadowed"]
    rc, out, _, _ = _score(tmp_path, capsys, path, *args)
    m = json.loads((out / "metrics.json").read_text())
    assert rc == 0 and m["visibility_mae"] == 0.0
    assert m["candidate_layout"]["visibility"] == "1-is-shadowed"
    rc, _, _, _ = _score(tmp_path, capsys, path, "--channel", "visibility", out="as-lit")
    assert rc == 0
    rc, _, _, err = _score(
        tmp_path,
        capsys,
        cands["exact_rgb"],
        "--channel",
        "color",
        "--visibility",
        "1-is-shadowed",
        out="colour",
    )
    assert rc == 2 and "applies to shadow masks" in err
    # the Python API states it the same way
    import raster_oracle as ro

    rec = ro.score_image(cands["exports"] / "plate", 1.0 - vis, spp=16, visibility="1-is-shadowed")
    assert rec["visibility_mae"] == 0.0


def test_exports_record_their_path_and_frames_need_one(tmp_path, capsys, cands):
    """``--frames`` without a camera path silently scored ``dolly``: now exit 2, unless the
    export records the path it was made for (it does, with every frame's camera)."""
    export = tmp_path / "pan"
    args = ["export", "plate", *SIZE, "--camera-path", "subpixel-pan", "--frames", "2"]
    assert main([*args, "--out", str(export)]) == 0
    raw = json.loads((export / "export.json").read_text())
    # the sequence is recorded once (camera.json), export.json points at it
    assert raw["sequence"] == "camera.json#/sequence" and "camera_path" not in raw
    rec = read_export_record(export)
    assert rec["camera_path"] == "subpixel-pan" and rec["frame"] == 0 and rec["n_frames"] == 2
    assert (rec["width"], rec["height"]) == (48, 27)
    cams = [json.loads((export / "cameras" / f"frame_{k:03d}.json").read_text()) for k in (0, 1)]
    assert cams[0] == json.loads((export / "camera.json").read_text()) and cams[0] != cams[1]
    for k in (0, 1):
        write_exr(tmp_path / f"f_{k}.exr", {"visibility": cands["exact_ref"]["visibility"]})
    pattern = str(tmp_path / "f_{frame}.exr")
    base = ["--candidate", pattern, "--channel", "visibility", "--frames", "2", *SPP, "--quiet"]
    capsys.readouterr()
    rc = main(["score", "plate", *SIZE, *base, "--out", str(tmp_path / "no-path")])
    err = capsys.readouterr().err
    assert rc == 2 and "--camera-path" in err and not (tmp_path / "no-path").exists()
    rc = main(["score", str(export), *base, "--out", str(tmp_path / "export")])
    m = json.loads((tmp_path / "export" / "metrics.json").read_text())
    assert rc == 0 and m["camera_path"] == "subpixel-pan" and len(m["frames"]) == 2
    assert m["export"]["camera_path"] == "subpixel-pan" and m["export"]["frame"] == 0


# 7 ------------------------------------------------------------------------------------------


def _png(path, rgb8):
    from PIL import Image

    Image.fromarray(rgb8).save(path)


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("flipped", "flipped vertically"),
        ("inverted", "inverted"),
        ("shifted", "shifted by one pixel"),
        ("srgb-exr", "sRGB-encoded values in a linear file"),
        ("linear-png", "linear values in an sRGB file"),
        ("rgb-mask-png", "R, G and B are equal"),
    ],
)
def test_large_errors_get_a_likely_cause(tmp_path, capsys, cands, case, expected):
    """Each usual way an engine's image goes wrong on its way out is named as the likely
    cause, in the output, ``metrics.json`` and the report's first screen."""
    from raster_oracle.metrics import srgb_encode

    ref = cands["exact_ref"]
    vis = ref["visibility"]
    rgb = np.stack([ref[f"color.{c}"] for c in "RGB"], -1)
    path, channel = tmp_path / "c.exr", "visibility"
    if case == "flipped":
        write_exr(path, {"visibility": vis[::-1].copy()})
    elif case == "inverted":
        write_exr(path, {"visibility": 1.0 - vis})
    elif case == "shifted":
        write_exr(path, {"visibility": np.roll(vis, 1, axis=1)})
    elif case == "srgb-exr":
        enc = srgb_encode(np.clip(rgb, 0, 1)).astype(np.float32)
        write_exr(path, {c: enc[..., i] for i, c in enumerate("RGB")})
        channel = "color"
    elif case == "linear-png":
        path = tmp_path / "c.png"
        _png(path, np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8))
        channel = "color"
    else:
        path, channel = tmp_path / "c.png", "color"
        _png(path, np.repeat(np.round(vis * 255).astype(np.uint8)[..., None], 3, axis=-1))
    rc, out, text, _ = _score(tmp_path, capsys, path, "--channel", channel)
    m = json.loads((out / "metrics.json").read_text())
    assert rc == 0
    (found,) = [d for d in m["diagnoses"] if expected in d["message"]]
    assert found["message"] in text
    page = (out / "report.html").read_text()
    verdict = page[page.index('id="verdict"') : page.index('id="summary"')]
    assert expected in verdict


def test_an_exact_candidate_needs_no_diagnosis(tmp_path, capsys, cands):
    rc, out, text, _ = _score(tmp_path, capsys, cands["exact_vis"], "--channel", "visibility")
    m = json.loads((out / "metrics.json").read_text())
    assert rc == 0 and m["diagnoses"] == [] and m["diagnosis"]["tried"] == {}
    assert "likely cause" not in text


# 8 ------------------------------------------------------------------------------------------


def test_manifest_scores_layers_frames_and_a_missing_layer_as_its_own_error(
    tmp_path, capsys, cands
):
    """One run: two layers of one EXR with their own gates, a two-frame scene beside a
    one-frame one, and a layer the file lacks: that case is a JUnit error, the others are
    scored (``score-folder`` took one ``--channel`` and aborted on a missing layer)."""
    ref = cands["exact_ref"]
    root = tmp_path / "shots"
    (root / "pan").mkdir(parents=True)
    layers = {"shadow.Y": ref["visibility"]} | {f"msaa.{c}": ref[f"color.{c}"] for c in "RGB"}
    write_exr(root / "plate.exr", layers)
    for k in (0, 1):
        write_exr(root / "pan" / f"f_{k}.exr", {"shadow.Y": ref["visibility"]})
    export = cands["exports"] / "plate"
    manifest = tmp_path / "ci.toml"
    manifest.write_text(
        f"""
[defaults]
spp = 16

[scenes.plate]
scene = "{export}"
file = "plate.exr"
[scenes.plate.channels.shadow]
fail_above = {{ misclassified_fraction = 0.01 }}
[scenes.plate.channels.msaa]
fail_below = {{ ssim = 0.9 }}
[scenes.plate.channels.beauty]

[scenes.pan]
scene = "{export}"
file = "pan/f_{{frame}}.exr"
frames = 2
camera_path = "subpixel-pan"
channels = {{ shadow = {{ fail_above = {{ flicker = 1.0 }} }} }}
"""
    )
    out, junit = tmp_path / "out", tmp_path / "j.xml"
    argv = ["score-folder", str(root), "--manifest", str(manifest), "--quiet"]
    rc = main([*argv, "--out", str(out), "--junit", str(junit)])
    said = capsys.readouterr()
    assert rc == 1, said.err
    m = json.loads((out / "metrics.json").read_text())
    assert sorted(m["scenes"]) == ["pan/shadow", "plate/msaa", "plate/shadow"]
    assert list(m["errors"]) == ["plate/beauty"] and "beauty" in m["errors"]["plate/beauty"]
    assert m["failed"] == {}  # every scored case passed its gates
    assert m["scenes"]["plate/shadow"]["channel"] == "visibility"
    assert m["scenes"]["plate/msaa"]["channel"] == "color"
    assert len(m["scenes"]["pan/shadow"]["frames"]) == 2
    assert m["scenes"]["pan/shadow"]["camera_path"] == "subpixel-pan"
    cases = list(ET.parse(junit).getroot().iter("testcase"))
    errors = [c for c in cases if c.find("error") is not None]
    assert [e.get("classname") for e in errors] == ["plate/beauty"]
    names = {(c.get("classname"), c.get("name")) for c in cases}
    assert ("plate/shadow", "misclassified_fraction <= 0.01") in names
    assert ("plate/msaa", "ssim >= 0.9") in names and ("pan/shadow", "flicker <= 1") in names
    assert "plate/beauty: error:" in said.err
    # without a manifest, --channel that one scene's file lacks: that scene's own error
    plain = tmp_path / "plain"
    plain.mkdir()
    write_exr(plain / "plate.exr", {"shadow.Y": ref["visibility"]})
    write_exr(plain / "spot.exr", {"Y": ref["visibility"][:, ::-1].copy()})
    exports = tmp_path / "exports"
    exports.mkdir()
    (exports / "plate").symlink_to(export, target_is_directory=True)
    argv2 = ["score-folder", str(plain), "--exports", str(exports), "--channel", "shadow"]
    junit2 = tmp_path / "j2.xml"
    rc = main([*argv2, *SPP, "--quiet", "--out", str(tmp_path / "o2"), "--junit", str(junit2)])
    capsys.readouterr()
    m2 = json.loads((tmp_path / "o2" / "metrics.json").read_text())
    assert rc == 1 and list(m2["scenes"]) == ["plate"] and list(m2["errors"]) == ["spot"]
    errors = [c for c in ET.parse(junit2).getroot().iter("testcase") if c.find("error") is not None]
    assert [c.get("classname") for c in errors] == ["spot"]
    # a manifest with an unknown key is exit 2 before anything is scored
    manifest.write_text('[scenes.plate]\nfiel = "plate.exr"\n')
    rc = main([*argv, "--out", str(tmp_path / "bad")])
    assert rc == 2 and "unknown key 'fiel'" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


# 10 -----------------------------------------------------------------------------------------


def test_which_gate_catches_a_one_pixel_shift(tmp_path, capsys):
    """The README's gate ``misclassified_fraction=0.01`` passed a shadow moved by one pixel;
    the edge band, the edge-aware profile and Unreal's local error fail it, and an exact
    mask passes them all (docs/metrics.md's table)."""
    ref_args = ["reference", "plate", *BIG, "--quiet", "--out", str(tmp_path / "ref")]
    assert main(ref_args) == 0
    vis = read_exr(tmp_path / "ref" / "reference.exr")["visibility"]
    write_exr(tmp_path / "exact.exr", {"visibility": vis})
    write_exr(tmp_path / "shift.exr", {"visibility": np.roll(vis, 1, axis=1)})
    gates = ["--fail-above", "misclassified_fraction=0.01"]
    gates += ["--fail-above", "edge_band_misclassified_fraction=0.03"]
    for name in ("unreal-low", "unreal-high", "unity", "edge-aware"):
        gates += ["--gate-profile", name]
    got = {}
    for name in ("exact", "shift"):
        argv = ["score", "plate", *BIG, "--candidate", str(tmp_path / f"{name}.exr")]
        rc = main(
            [*argv, "--channel", "visibility", "--quiet", *gates, "--out", str(tmp_path / name)]
        )
        got[name] = (rc, json.loads((tmp_path / name / "metrics.json").read_text()))
    capsys.readouterr()
    assert got["exact"][0] == 0 and got["exact"][1]["failed"] == []
    rc, m = got["shift"]
    assert rc == 1
    assert set(m["failed"]) == {
        "edge_band_misclassified_fraction <= 0.03",
        "edge_aware_error_fraction <= 0.005",
        "unreal_low_local_error <= 0.1",
        "unreal_high_local_error <= 0.1",
    }
    assert 0.003 < m["misclassified_fraction"] < 0.01  # the old README gate passes it


def test_an_export_record_of_schema_1_still_reads(tmp_path):
    """Exports of earlier releases held the sequence in export.json itself (schema 1)."""
    rec = {
        "schema": "raster-oracle/export/1",
        "scene": "plate",
        "width": 48,
        "height": 27,
        "light": 0,
        "camera_path": "dolly",
        "light_path": None,
        "frame": 0,
        "n_frames": 4,
    }
    (tmp_path / "export.json").write_text(json.dumps(rec))
    assert read_export_record(tmp_path) == rec
    (tmp_path / "export.json").write_text(json.dumps({**rec, "schema": "raster-oracle/export/9"}))
    with pytest.raises(SceneError, match="not an export record"):
        read_export_record(tmp_path)
