"""An engine's own denoised ray-traced shadows scored like the models (issue 46): ``score
EXPORT --frames N --candidate 'f{frame:03d}.exr' --channel soft_visibility --family
rtshadows`` on an export of an event scene gets the temporal metrics against the area-light
truth of every frame, equal to ``--technique``'s on the same frames; the recommended gate
(docs/metrics.md) fails an integration that passes the one-ray input through and passes the
denoised output. The temporal metrics are gateable for a temporal family's visibility
channels only: a shadow map's sequence is not judged as a history."""

from __future__ import annotations

import json

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import write_exr
from raster_oracle.oracle.scoring.ci.checks import Gate, GateError
from raster_oracle.oracle.scoring.ci.gates import check_applicable
from raster_oracle.scenes.inputs import load_input

from raster_oracle import raster_models

W, H, N = 48, 27, 6
#: The recommended gate of the rtshadows family (docs/metrics.md): added flicker catches the
#: pass-through; the steady error bounds a denoiser stuck on its history.
GATE = ["--fail-above", "flicker=0.025", "--fail-above", "steady_error=0.1"]
#: Temporal metrics compared between the file and the technique run.
TEMPORAL = (
    "steady_error",
    "convergence_frames",
    "ghosting_error",
    "lag_frames",
    "flicker",
    "flicker_ratio",
    "temporal_error",
)
#: The files hold the model's float32 output as it is: the metrics agree to rounding.
TOL = 1e-9


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("rtfiles")
    exp = root / "exp"
    size = ["--width", str(W), "--height", str(H)]
    path = ["--camera-path", "static", "--frames", str(N)]
    assert main(["export", "occluder-rect", *size, *path, "--out", str(exp)]) == 0
    # the engine: FidelityFX's denoiser over the export's frames, its input and its output
    loaded = load_input(str(exp))
    for name in ("ffx", "noisy"):
        (root / name).mkdir()
    for k in range(N):
        out = raster_models.run("rtshadows-ffx", loaded.with_frame(k, n_frames=N)).outputs
        write_exr(root / "ffx" / f"f{k:03d}.exr", {"soft_visibility": out["soft_visibility"]})
        write_exr(root / "noisy" / f"f{k:03d}.exr", {"soft_visibility": out["noisy"]})
    common = ["score", str(exp), "--frames", str(N), "--gate-frames", "3", "--spp", "4", *GATE]
    rc, rec = {}, {}
    for name in ("ffx", "noisy"):
        pattern = str(root / name / "f{frame:03d}.exr")
        cand = ["--candidate", pattern, "--channel", "soft_visibility", "--family", "rtshadows"]
        rc[name] = main([*common, *cand, "--out", str(root / f"out_{name}")])
        rec[name] = json.loads((root / f"out_{name}" / "metrics.json").read_text())
    rc["model"] = main([*common, "--technique", "rtshadows-ffx", "--out", str(root / "out_m")])
    rec["model"] = json.loads((root / "out_m" / "metrics.json").read_text())
    return root, exp, rc, rec


def test_engine_frames_get_the_models_temporal_metrics(runs):
    _, _, _, rec = runs
    files, model = rec["ffx"], rec["model"]
    assert files["channel"] == model["channel"] == "soft_visibility"
    for key in TEMPORAL:
        assert files[key] is not None, key
        assert abs(files[key] - model[key]) <= TOL, (key, files[key], model[key])
    floor = files["noise_floor"]["steady_error"]
    assert floor == pytest.approx(model["noise_floor"]["steady_error"])


def test_the_recommended_gate_fails_the_pass_through_and_passes_the_denoiser(runs):
    _, _, rc, rec = runs
    assert rc["ffx"] == 0 and rc["model"] == 0
    assert rc["noisy"] == 1
    assert rec["noisy"]["flicker"] > 0.025 > rec["ffx"]["flicker"]
    failed = {c["metric"] for c in rec["noisy"]["gates"] if not c["passed"]}
    assert failed == {"flicker"}, rec["noisy"]["gates"]
    assert all(c["passed"] for c in rec["ffx"]["gates"]) and len(rec["ffx"]["gates"]) == 2


def test_temporal_gates_need_a_temporal_family(runs, capsys):
    root, exp, _, _ = runs
    pattern = str(root / "ffx" / "f{frame:03d}.exr")
    args = ["score", str(exp), "--frames", str(N), "--candidate", pattern]
    args += ["--channel", "soft_visibility", "--fail-above", "steady_error=0.1"]
    assert main([*args, "--out", str(root / "refused")]) == 2
    err = capsys.readouterr().err
    assert "steady_error applies to color candidates" in err and not (root / "refused").exists()
    # a family that does not produce the channel is named
    assert main([*args, "--family", "taa", "--out", str(root / "refused")]) == 2
    assert "--family taa produces color" in capsys.readouterr().err
    assert main([*args, "--family", "nonesuch", "--out", str(root / "refused")]) == 2
    assert "unknown technique family 'nonesuch'" in capsys.readouterr().err
    tech = ["score", str(exp), "--technique", "rtshadows-ffx", "--family", "rtshadows"]
    assert main([*tech, "--out", str(root / "refused")]) == 2
    assert "--family applies to --candidate" in capsys.readouterr().err
    assert not (root / "refused").exists()


def test_the_catalogue_opens_the_temporal_metrics_to_temporal_families_only():
    gate = [Gate("steady_error", "<=", 0.1)]
    check_applicable(gate, kinds=("visibility",), frames=4, temporal=True)
    with pytest.raises(GateError, match="applies to color"):
        check_applicable(gate, kinds=("visibility",), frames=4)
    with pytest.raises(GateError, match="at least 2 frames"):
        check_applicable(gate, kinds=("visibility",), frames=1, temporal=True)


def test_a_shadow_maps_sequence_keeps_its_temporal_metrics_closed(tmp_path, capsys):
    """The shadow family is not temporal: its frames have no steady error to gate (refused
    before anything is rendered or written)."""
    out = tmp_path / "sm"
    args = ["score", "plate", "--technique", "shadow-map", "--frames", "2", "--spp", "1"]
    args += ["--camera-path", "dolly"]
    args += ["--width", "16", "--height", "9", "--fail-above", "steady_error=0.1"]
    assert main([*args, "--out", str(out)]) == 2
    assert "steady_error applies to color candidates" in capsys.readouterr().err
    assert not out.exists()


def test_a_manifest_names_the_family_of_its_frames(runs, tmp_path):
    """``family = "rtshadows"`` in a ``score-folder`` manifest: the case gets the temporal
    metrics and its steady-error gate is judged, as with ``score --family``."""
    root, exp, _, rec = runs
    manifest = tmp_path / "ci.toml"
    manifest.write_text(
        f"""[defaults]
spp = 4
[scenes.occ]
scene = "{exp.as_posix()}"
file = "ffx/f{{frame:03d}}.exr"
frames = {N}
family = "rtshadows"
[scenes.occ.channels.soft_visibility]
fail_above = {{ steady_error = 0.1 }}
"""
    )
    out = tmp_path / "out"
    args = ["score-folder", str(root), "--manifest", str(manifest), "--out", str(out)]
    assert main(args) == 0
    case = json.loads((out / "occ" / "soft_visibility" / "metrics.json").read_text())
    assert case["channel"] == "soft_visibility" and case["temporal_aa"] is not None
    assert [g["metric"] for g in case["gates"]] == ["steady_error"]
    assert case["lag_frames"] == rec["ffx"]["lag_frames"]


def test_soft_channels_gate_and_compare_as_visibility(runs, tmp_path):
    """A soft channel is of the catalogue's kind ``visibility``: the shadow metrics gate a
    PCSS run, and a soft run's baseline is a run of the same kind (both were refused)."""
    root, exp, _, _ = runs
    pcss = ["score", "occluder-rect", "--technique", "pcss", "--width", "24", "--height", "14"]
    pcss += ["--spp", "2", "--fail-above", "visibility_mae=0.5", "--out", str(tmp_path / "p")]
    assert main(pcss) == 0
    again = ["score", str(exp), "--frames", str(N), "--gate-frames", "3", "--spp", "4"]
    again += ["--technique", "rtshadows-ffx", "--baseline", str(root / "out_m" / "metrics.json")]
    assert main([*again, "--out", str(tmp_path / "b")]) == 0
