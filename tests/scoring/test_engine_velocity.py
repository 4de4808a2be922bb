"""An engine's TAA inputs scored over a sequence: its colour frames and its velocity buffer
(the test suite's own NumPy rasterizer, tests/engine_raster.py), written in Unreal's
convention and read back through the convention conversion. Correct vectors pass a velocity
gate; vectors with the classic sign error (previous minus current written where Unreal wants
current minus previous) fail it."""

from __future__ import annotations

import numpy as np
import pytest
from engine_raster import render, velocity, write_engine_exr
from raster_oracle.metrics import from_oracle_motion, to_oracle_motion
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.scoring.ci.checks import Gate
from raster_oracle.oracle.scoring.ci.gates import evaluate_gates
from raster_oracle.oracle.scoring.options import ScoreOptions
from raster_oracle.oracle.scoring.request import ScoreRequest
from raster_oracle.oracle.scoring.score import score
from raster_oracle.scenes.formats.export import export

from raster_oracle import scenes

FRAMES = 3
W, H = 96, 54
#: The velocity gate: at most 1% of the pixels (not disoccluded) off by more than 0.5 px.
GATE = Gate("motion_epe_over_half", "<=", 0.01)
#: Mean end-point error of correct vectors: the engine's float64 reconstruction against the
#: reference's float32 hit points, far below a pixel.
CORRECT_EPE_PX = 1e-2


@pytest.fixture(scope="module")
def engine_frames(tmp_path_factory):
    """The sequence, and per frame the engine's colour and its velocity buffer in Unreal's
    convention (current minus previous, NDC, y up)."""
    base = scenes.load("plate", width=W, height=H, camera_path="rotate", n_frames=FRAMES)
    out = []
    for k in range(FRAMES):
        frame = base.with_frame(k)
        folder = tmp_path_factory.mktemp(f"frame{k}") / "export"
        export(frame, folder)
        mv = velocity(folder, frame.previous().camera.to_json())
        images = render(folder, shadow_map_size=512)
        images["velocity"] = from_oracle_motion(mv, convention="unreal", width=W, height=H)
        out.append((images["color"], images["velocity"], images))
    return base, out


def _score(base, frames, *, sign):
    def candidate(frame_scene, k):
        color, unreal, _ = frames[k]
        # what `score --candidate-motion velocity --motion-convention unreal` does
        mv = to_oracle_motion(sign * unreal, convention="unreal", width=W, height=H)
        return color, {"frame": k, "motion": mv}

    options = ScoreOptions(spp=4, frames=FRAMES, camera_path="rotate")
    return score(ScoreRequest(base, "color", candidate, options=options)).record


def test_correct_engine_motion_vectors_pass_the_velocity_gate(engine_frames):
    base, frames = engine_frames
    rec = _score(base, frames, sign=1.0)
    assert rec["motion_epe_mean"] < CORRECT_EPE_PX
    assert rec["motion_epe_over_half"] == 0.0
    assert all(c.passed for c in evaluate_gates([GATE], rec))
    # the vectors were not trivially zero: the camera turns 0.5 degree a frame, about a pixel
    assert np.abs(frames[1][1][..., 0]).max() * W / 2 > 1.0
    assert rec["frames"][1]["motion_epe_p99"] < 0.05


def test_sign_flipped_engine_motion_vectors_fail_the_velocity_gate(engine_frames):
    base, frames = engine_frames
    rec = _score(base, frames, sign=-1.0)
    (check,) = evaluate_gates([GATE], rec)
    assert not check.passed and check.line.startswith("FAIL motion_epe_over_half")
    assert rec["motion_epe_mean"] > 1.0


def test_conventions_round_trip_and_match_the_table():
    mv = np.array([[[1.5, -2.0]]])
    for conv in ("pixels", "unreal", "unity", "uv"):
        there = from_oracle_motion(mv, convention=conv, width=100, height=50)
        np.testing.assert_allclose(
            to_oracle_motion(there, convention=conv, width=100, height=50), mv
        )
    # docs/conventions.md: Unreal (-2 mx/W, 2 my/H), Unity (-mx/W, my/H), UV (mx/W, my/H)
    np.testing.assert_allclose(
        from_oracle_motion(mv, convention="unreal", width=100, height=50)[0, 0], [-0.03, -0.08]
    )
    np.testing.assert_allclose(
        from_oracle_motion(mv, convention="unity", width=100, height=50)[0, 0], [-0.015, -0.04]
    )
    np.testing.assert_allclose(
        from_oracle_motion(mv, convention="uv", width=100, height=50)[0, 0], [0.015, -0.04]
    )


@pytest.mark.parametrize(("sign", "code"), [(1.0, 0), (-1.0, 1)])
def test_score_cli_reads_the_velocity_layer_and_gates_it(engine_frames, tmp_path, sign, code):
    _, frames = engine_frames
    for k, (_, unreal, images) in enumerate(frames):
        write_engine_exr(tmp_path / f"f_{k}.exr", {**images, "velocity": sign * unreal})
    out = tmp_path / "score"
    argv = ["score", "plate", "--width", str(W), "--height", str(H), "--camera-path", "rotate"]
    argv += ["--frames", str(FRAMES), "--candidate", str(tmp_path / "f_{frame}.exr")]
    argv += ["--channel", "msaa", "--candidate-motion", "velocity"]
    argv += ["--motion-convention", "unreal", "--gate-frames", "2", "--spp", "4"]
    argv += ["--fail-above", "motion_epe_over_half=0.01", "--no-cache", "--quiet"]
    assert main([*argv, "--out", str(out)]) == code
    import json

    rec = json.loads((out / "metrics.json").read_text())
    assert rec["gate_frames"] == 2 and rec["motion_epe_mean"] is not None
    assert (rec["motion_epe_mean"] < CORRECT_EPE_PX) == (sign > 0)
    assert (out / "motion_epe.png").exists() and (out / "flicker.png").exists()


def test_motion_layer_errors_are_one_line(engine_frames, tmp_path, capsys):
    _, frames = engine_frames
    for k, (_, _, images) in enumerate(frames):
        write_engine_exr(tmp_path / f"f_{k}.exr", images)
    argv = ["score", "plate", "--width", str(W), "--height", str(H), "--camera-path", "rotate"]
    argv += ["--frames", str(FRAMES), "--candidate", str(tmp_path / "f_{frame}.exr")]
    argv += ["--channel", "msaa", "--candidate-motion", "motion", "--no-cache", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "has no motion layer 'motion'" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--gate-frames", "5"], "--gate-frames must be in [1, 1]"),
        (["--candidate-motion", "velocity"], "--candidate-motion applies to --candidate"),
    ],
)
def test_temporal_options_misused_are_one_line(tmp_path, capsys, extra, message):
    argv = ["score", "plate", "--width", "32", "--height", "18", "--technique", "noaa"]
    argv += ["--spp", "1", "--no-cache", "--quiet", "--out", str(tmp_path / "o"), *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
