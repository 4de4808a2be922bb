"""The score and report commands on external candidates."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.oracle.scoring.score import METRIC_KEYS

SIZE = ["--width", "48", "--height", "27"]
REQUIRED = (
    "visibility_mae",
    "misclassified_fraction",
    "false_lit_fraction",
    "false_shadow_fraction",
    "edge_band_mae",
    "flip_mean",
    "ssim",
    "psnr_db",
    "delta_e2000_mean",
    "significant_fraction",
    "noise_floor",
    "cost",
    "reference",
)


@pytest.fixture(scope="module")
def refs(tmp_path_factory):
    """A 16-spp reference of the plate (what scoring renders) and a 4-spp one (a noisy
    'engine' image)."""
    root = tmp_path_factory.mktemp("refs")
    assert (
        main(["reference", "plate", *SIZE, "--spp", "16", "--out", str(root / "exact"), "--quiet"])
        == 0
    )
    assert (
        main(
            [
                "reference",
                "plate",
                *SIZE,
                "--spp",
                "4",
                "--seed",
                "7",
                "--out",
                str(root / "noisy"),
                "--quiet",
            ]
        )
        == 0
    )
    return read_exr(root / "exact" / "reference.exr"), read_exr(root / "noisy" / "reference.exr")


def _score(tmp_path, candidate, *extra, out="s"):
    out_dir = tmp_path / out
    rc = main(
        [
            "score",
            "plate",
            *SIZE,
            "--spp",
            "16",
            "--candidate",
            str(candidate),
            "--out",
            str(out_dir),
            "--quiet",
            *extra,
        ]
    )
    return rc, out_dir


def test_identity_scores_zero(tmp_path, refs):
    exact, _ = refs
    write_exr(tmp_path / "same.exr", {"visibility": exact["visibility"]})
    rc, out = _score(tmp_path, tmp_path / "same.exr", "--channel", "visibility")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["visibility_mae"] == 0 and m["misclassified_fraction"] == 0
    assert m["flip_mean"] == 0 and m["significant_fraction"] == 0 and m["ssim"] == 1


def test_color_candidate_metrics_and_files(tmp_path, refs):
    _, noisy = refs
    write_exr(tmp_path / "c.exr", {c: noisy[f"color.{c}"] for c in "RGB"})
    rc, out = _score(tmp_path, tmp_path / "c.exr")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in REQUIRED:
        assert key in m, key
    assert m["channel"] == "color" and m["visibility_mae"] is None
    assert 0 < m["flip_mean"] < 0.2 and 0.8 < m["ssim"] < 1 and m["delta_e2000_mean"] > 0
    # the noise floor of a 16-spp reference is below a 4-spp image's error
    assert m["noise_floor"]["flip_mean"] < m["flip_mean"]
    assert m["reference"]["channels"] == ["color", "edge", "id"]
    for name in (
        "metrics.json",
        "report.html",
        "report.json",
        "error_maps.exr",
        "candidate.exr",
        "reference.exr",
        "flip.png",
        "delta_e2000.png",
    ):
        assert (out / name).is_file(), name
    assert set(read_exr(out / "error_maps.exr")) >= {"flip", "delta_e2000", "neg_log10_p"}


def test_visibility_candidate_renders_only_needed_channels(tmp_path, refs):
    _, noisy = refs
    write_exr(tmp_path / "v.exr", {"visibility": noisy["visibility"]})
    rc, out = _score(tmp_path, tmp_path / "v.exr", "--channel", "visibility")
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["delta_e2000_mean"] is None
    assert m["reference"]["channels"] == ["visibility", "edge", "id", "normal", "position"]
    assert m["false_lit_fraction"] + m["false_shadow_fraction"] == pytest.approx(
        m["misclassified_fraction"]
    )


def test_fail_above_exit_codes(tmp_path, refs):
    _, noisy = refs
    write_exr(tmp_path / "v.exr", {"visibility": noisy["visibility"]})
    rc, out = _score(
        tmp_path,
        tmp_path / "v.exr",
        "--channel",
        "visibility",
        "--fail-above",
        "visibility_mae=0",
        out="fail",
    )
    assert rc == 1
    assert json.loads((out / "metrics.json").read_text())["failed"] == ["visibility_mae <= 0"]
    rc, _ = _score(
        tmp_path,
        tmp_path / "v.exr",
        "--channel",
        "visibility",
        "--fail-above",
        "visibility_mae=0.5",
        out="pass",
    )
    assert rc == 0


def _write_png(path, arr):
    from PIL import Image

    Image.fromarray(arr).save(path)


@pytest.mark.parametrize(
    ("make", "channel", "message"),
    [
        (
            lambda p, e: write_exr(p / "x.exr", {c: np.ones((20, 30)) for c in "RGB"}),
            "color",
            "candidate is 30x20, the reference is 48x27",
        ),
        (
            lambda p, e: write_exr(p / "x.exr", {"Z": e["depth"], "A2": e["depth"]}),
            "visibility",
            "channel",
        ),
        (
            lambda p, e: write_exr(p / "x.exr", {c: np.full((27, 48), np.nan) for c in "RGB"}),
            "color",
            "NaN",
        ),
        (
            lambda p, e: write_exr(p / "x.exr", {c: np.full((27, 48), np.inf) for c in "RGB"}),
            "color",
            "inf",
        ),
        (
            lambda p, e: write_exr(p / "x.exr", {c: -np.ones((27, 48)) for c in "RGB"}),
            "color",
            "negative",
        ),
        (
            lambda p, e: (p / "x.exr").write_bytes(b"v/1\x01" + b"\0" * 40),
            "color",
            "cannot read|truncated|unreadable",
        ),
        (lambda p, e: (p / "x.txt").write_text("hi"), "color", "extension"),
    ],
)
def test_bad_candidates_exit_2_nothing_written(tmp_path, refs, capsys, make, channel, message):
    import re

    make(tmp_path, refs[0])
    cand = next(p for p in tmp_path.iterdir() if p.name.startswith("x."))
    rc, out = _score(tmp_path, cand, "--channel", channel)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert re.search(message, err, re.IGNORECASE), err
    assert len(err.splitlines()) == 1 and "Traceback" not in err


def test_truncated_exr_is_a_clear_error(tmp_path, refs, capsys):
    write_exr(tmp_path / "full.exr", {c: refs[1][f"color.{c}"] for c in "RGB"})
    data = (tmp_path / "full.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    rc, out = _score(tmp_path, tmp_path / "cut.exr")
    assert rc == 2 and not out.exists()
    assert "cut.exr" in capsys.readouterr().err


def test_png_candidate(tmp_path, refs):
    exact, _ = refs
    vis = np.round(exact["visibility"] * 255).astype(np.uint8)
    _write_png(tmp_path / "v.png", vis)
    rc, out = _score(tmp_path, tmp_path / "v.png", "--channel", "visibility")
    assert rc == 0
    assert json.loads((out / "metrics.json").read_text())["visibility_mae"] < 0.01


def test_unknown_threshold_metric(tmp_path, refs, capsys):
    write_exr(tmp_path / "v.exr", {"visibility": refs[0]["visibility"]})
    rc, out = _score(
        tmp_path, tmp_path / "v.exr", "--channel", "visibility", "--fail-above", "beauty=3"
    )
    assert rc == 2 and not out.exists()
    assert "unknown metric 'beauty'" in capsys.readouterr().err


def test_frames_add_temporal_metrics(tmp_path):
    for k in range(3):
        assert (
            main(
                [
                    "reference",
                    "plate",
                    *SIZE,
                    "--spp",
                    "4",
                    "--seed",
                    "3",
                    "--camera-path",
                    "subpixel-pan",
                    "--frame",
                    str(k),
                    "--frames",
                    "3",
                    "--channels",
                    "visibility",
                    "--out",
                    str(tmp_path / f"f{k}"),
                    "--quiet",
                ]
            )
            == 0
        )
        ch = read_exr(tmp_path / f"f{k}" / "reference.exr")
        write_exr(tmp_path / f"cand_{k}.exr", {"visibility": ch["visibility"]})
    rc, out = _score(
        tmp_path,
        tmp_path / "cand_{frame}.exr",
        "--channel",
        "visibility",
        "--frames",
        "3",
        "--camera-path",
        "subpixel-pan",
    )
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert len(m["frames"]) == 3 and m["camera_path"] == "subpixel-pan"
    assert m["flicker"] is not None and m["temporal_error"] is not None
    assert set(METRIC_KEYS) <= set(m)


def test_report_combines_folders(tmp_path, refs):
    _, noisy = refs
    write_exr(tmp_path / "v.exr", {"visibility": noisy["visibility"]})
    write_exr(tmp_path / "c.exr", {c: noisy[f"color.{c}"] for c in "RGB"})
    _score(tmp_path, tmp_path / "v.exr", "--channel", "visibility", out="a")
    _score(tmp_path, tmp_path / "c.exr", out="b")
    assert (
        main(
            [
                "report",
                str(tmp_path / "a"),
                str(tmp_path / "b"),
                "--out",
                str(tmp_path / "all" / "report.html"),
            ]
        )
        == 0
    )
    data = json.loads((tmp_path / "all" / "report.json").read_text())
    assert len(data["cases"]) == 2
    html = (tmp_path / "all" / "report.html").read_text()
    assert "../a/reference.exr" in html
