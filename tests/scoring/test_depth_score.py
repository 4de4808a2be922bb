"""Depth as a scored kind (issue 43): ``score EXPORT --candidate frame.exr --channel depth``
scores an engine's linear view depth against the reference's ``depth`` where the reference
sees a surface, with the relative error gateable and the near-plane precision case named by
``--depth-buffer NEAR,FAR,BITS``. On a 48x27 plate export."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.oracle.scoring.ci.checks import GateError
from raster_oracle.oracle.scoring.ci.gates import evaluate_gates, parse_gates, support_record

NEAR, FAR, BITS = 0.01, 1000.0, 24


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    root = tmp_path_factory.mktemp("depth")
    size = ["--width", "48", "--height", "27"]
    assert main(["export", "plate", *size, "--out", str(root / "e")]) == 0
    ref = ["reference", str(root / "e"), "--spp", "4", "--channels", "depth,id", "--quiet"]
    assert main([*ref, "--out", str(root / "ref")]) == 0
    return root, read_exr(root / "ref" / "reference.exr")["depth"]


def _score(root, tmp_path, channels: dict, *extra):
    tmp_path.mkdir(parents=True, exist_ok=True)
    write_exr(tmp_path / "frame.exr", channels)
    out = tmp_path / "out"
    argv = ["score", str(root / "e"), "--candidate", str(tmp_path / "frame.exr"), "--spp", "4"]
    rc = main([*argv, "--channel", "depth", "--quiet", "--out", str(out), *extra])
    record = json.loads((out / "metrics.json").read_text()) if rc in (0, 1) else None
    return rc, record


def _hyperbolic(z):
    """The reference depth through a 24-bit UNORM hyperbolic buffer and linearized again in
    float32, as an engine's shader would."""
    d = FAR * (z - NEAR) / (z * (FAR - NEAR))
    q = np.round(d * (2.0**BITS - 1)) / (2.0**BITS - 1)
    d32 = q.astype(np.float32)
    return np.float32(NEAR * FAR) / (np.float32(FAR) - d32 * np.float32(FAR - NEAR))


def test_reference_depth_scores_zero_on_every_seen_pixel(plate, tmp_path):
    root, depth = plate
    rc, rec = _score(root, tmp_path, {"depth": depth}, "--fail-above", "depth_rel_error_mean=0")
    assert rc == 0
    assert rec["channel"] == "depth"
    assert rec["depth_rel_error_mean"] == 0.0 and rec["depth_rel_error_max"] == 0.0
    seen = int((depth > 0).sum())
    assert seen > 0 and rec["depth_pixels"] == seen
    assert rec["support"]["depth_rel_error_mean"] == seen
    # no image metric is written for a depth, and no buffer was named
    assert rec["flip_mean"] is None and rec["ssim"] is None
    assert rec["depth_beyond_precision_fraction"] is None


@pytest.mark.parametrize("name", ["depth.Z", "Z", "depth.Y"])
def test_scaled_depth_scores_its_relative_error_and_fails_the_gate(plate, tmp_path, name):
    root, depth = plate
    scaled = (depth.astype(np.float64) * 1.01).astype(np.float32)
    gate = ["--fail-above", "depth_rel_error_mean=0.005"]
    rc, rec = _score(root, tmp_path, {name: scaled, "shadow.Y": np.ones_like(depth)}, *gate)
    assert rc == 1
    assert abs(rec["depth_rel_error_mean"] - 0.01) < 1e-6
    assert abs(rec["depth_rel_error_max"] - 0.01) < 1e-6
    # the error map is drawn and the report written
    assert (tmp_path / "out" / "depth_rel_error.png").is_file()
    assert (tmp_path / "out" / "report.html").is_file()


def test_depth_buffer_names_the_near_plane_precision_case(plate, tmp_path):
    root, depth = plate
    buffer = ["--depth-buffer", f"{NEAR},{FAR},{BITS}"]
    rounded = _hyperbolic(depth.astype(np.float64))
    rc, rec = _score(root, tmp_path / "a", {"depth": rounded}, *buffer)
    assert rc == 0
    # the buffer's own rounding is visible at near 0.01 ...
    assert rec["depth_rel_error_max"] > 1e-6
    # ... and every pixel of it is within the precision the buffer allows
    assert rec["depth_beyond_precision_fraction"] == 0.0
    wrong = (rounded.astype(np.float64) * 1.01).astype(np.float32)
    rc, rec = _score(root, tmp_path / "b", {"depth": wrong}, *buffer)
    assert rec["depth_beyond_precision_fraction"] > 0.99


def test_channel_depth_on_a_file_without_depth_is_one_line(plate, tmp_path, capsys):
    root, depth = plate
    rc, _ = _score(root, tmp_path, {"shadow.Y": np.ones_like(depth)})
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and "has no depth channel" in err[0] and "shadow.Y" in err[0]


def test_depth_buffer_on_a_shadow_mask_is_refused(plate, tmp_path, capsys):
    root, depth = plate
    write_exr(tmp_path / "m.exr", {"shadow.Y": np.ones_like(depth)})
    argv = ["score", str(root / "e"), "--candidate", str(tmp_path / "m.exr"), "--quiet"]
    rc = main([*argv, "--depth-buffer", "0.1,100,24", "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "--depth-buffer applies to a depth candidate" in capsys.readouterr().err


def test_a_depth_gate_over_no_seen_pixel_does_not_pass():
    record = {"channel": "depth", "depth_rel_error_mean": 0.0, "depth_pixels": 0}
    support_record(record)
    assert record["support"]["depth_rel_error_mean"] == 0
    assert record["depth_rel_error_mean"] is None
    gates = parse_gates(fail_above=["depth_rel_error_mean=0.01"])
    with pytest.raises(GateError, match="support: 0"):
        evaluate_gates(gates, record)


def test_a_depth_missing_where_the_reference_sees_a_surface_is_one_line(plate, tmp_path, capsys):
    root, depth = plate
    holed = depth.copy()
    holed[3, 4], holed[5, 5] = 0.0, -1.0
    rc, _ = _score(root, tmp_path, {"depth": holed})
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not (tmp_path / "out").exists()
    seen = int((depth > 0).sum())
    assert len(err) == 1 and f"2 of {seen} such pixels are not (min -1)" in err[0]


def test_a_view_of_the_sky_alone_exits_2_on_a_depth_gate(plate, tmp_path, capsys):
    """The camera turned away from the plate: the reference sees no surface, any depth is
    free there, and a gate over no pixel is exit 2, not a pass."""
    from raster_oracle import scenes

    root, depth = plate
    cam = scenes.load("plate", width=48, height=27).camera
    away = np.asarray(cam.to_world, dtype=float).copy()
    away[:3, 0] *= -1.0
    away[:3, 2] *= -1.0
    path = tmp_path / "away.json"
    path.write_text(json.dumps({"frames": [{"to_world": away.tolist(), "fov_x_deg": cam.fov_x}]}))
    extra = ["--camera-file", str(path), "--fail-above", "depth_rel_error_mean=0.01"]
    rc, _ = _score(root, tmp_path, {"depth": np.zeros_like(depth)}, *extra)
    err = capsys.readouterr().err
    assert rc == 2
    assert "depth_rel_error_mean is computed over the pixels where the reference sees" in err
    assert "support: 0" in err
