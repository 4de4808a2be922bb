"""The model, techniques, score --technique, main and bench commands."""

from __future__ import annotations

import json

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr

SIZE = ["--width", "64", "--height", "36"]


def test_techniques_lists_parameters_with_sources(capsys):
    assert main(["techniques"]) == 0
    out = capsys.readouterr().out
    for name in ("shadow-map:", "csm:", "sdsm:", "split_lambda", "partitions", "latency"):
        assert name in out
    assert "Intel SDSM" in out


def test_model_writes_output_and_sidecar(tmp_path):
    out = tmp_path / "m"
    assert (
        main(
            [
                "model",
                "sdsm",
                "city",
                *SIZE,
                "--set",
                "resolution=256",
                "--set",
                "partitions=2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    ch = read_exr(out / "output.exr")
    assert set(ch) == {"visibility", "cascade", "texels_per_pixel", "resolution_error", "uncovered"}
    meta = json.loads((out / "model.json").read_text())
    assert meta["technique"] == "sdsm" and meta["params"]["partitions"] == 2
    # sdsm defaults to EVSM4 (Intel sample): a D32F depth map plus four fp32 moments a texel
    assert meta["params"]["filter"] == "evsm4"
    assert meta["cost"]["shadow_map_bytes"] == 2 * 256 * 256 * (4 + 16)
    assert len(meta["diagnostics"]["partitions"]) == 2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["model", "pcss", "plate"], "unknown technique 'pcss'.*shadow-map"),
        (["model", "csm", "plate", "--set", "cascades=4"], "unknown parameter 'cascades'"),
        (["model", "csm", "plate", "--set", "split=cubic"], "split.*uniform"),
        (["model", "csm", "plate", "--set", "resolution=-5"], "resolution"),
        (["model", "csm", "spot"], "needs a directional light"),
        (["score", "plate", "--technique", "nope"], "unknown technique"),
    ],
)
def test_model_errors_exit_2(tmp_path, capsys, args, message):
    import re

    out = tmp_path / "o"
    rc = main([*args, "--out", str(out), *SIZE])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert re.search(message, err), err
    assert len(err.splitlines()) == 1


def test_score_technique_records_cost(tmp_path):
    out = tmp_path / "s"
    assert (
        main(
            [
                "score",
                "plate",
                *SIZE,
                "--technique",
                "csm",
                "--set",
                "resolution=512",
                "--spp",
                "16",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert m["technique"] == "csm" and m["params"]["resolution"] == 512
    assert m["cost"]["shadow_map_bytes"] > 0
    assert 0 <= m["misclassified_fraction"] < 0.05
    assert (out / "report.html").is_file()


def test_bench_commands_print_ratios(capsys):
    assert main(["bench", "oracle", "--width", "48", "--height", "27", "--spp", "4"]) == 0
    fig = json.loads(capsys.readouterr().out)
    assert fig["oracle_over_bare_ratio"] > 0 and fig["color_over_mitsuba_direct_ratio"] > 0
    assert all(fig["adaptive"][s]["rays_ratio_vs_uniform"] > 0 for s in ("thin", "city", "plate"))
    assert main(["bench", "models", "--width", "48", "--height", "27", "--spp", "4"]) == 0
    fig = json.loads(capsys.readouterr().out)
    assert fig["sdsm_over_oracle_ratio"] > 0
