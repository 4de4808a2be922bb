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
        (["model", "pcs", "plate"], "unknown technique 'pcs'.*shadow-map"),
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


#: Keys of a kernel profile (oracle.phases.kernel_profile) in the bench figures.
PROFILE_KEYS = {
    "trace_seconds",
    "kernel_seconds",
    "reduction_seconds",
    "copy_seconds",
    "compile_seconds",
    "launches",
    "cache_hits",
    "compiled",
    "wall_seconds",
    "host_seconds",
}


def test_bench_commands_print_ratios(capsys):
    assert main(["bench", "oracle", "--width", "48", "--height", "27", "--spp", "4"]) == 0
    printed = capsys.readouterr()
    fig = json.loads(printed.out)
    assert fig["oracle_over_bare_ratio"] > 0 and fig["color_over_mitsuba_direct_ratio"] > 0
    assert all(fig["adaptive"][s]["rays_ratio_vs_uniform"] > 0 for s in ("thin", "city", "plate"))
    # the device beside the figures, and the colour reference's profile by phase
    assert fig["device"]["variant"] == fig["variant"] and fig["device"]["name"]
    profile = fig["color_profile"]
    assert list(profile["phases"])[:3] == ["record", "tracing", "shading"]
    assert {"reductions", "transfer", "accumulate", "finish"} <= set(profile["phases"])
    assert set(profile["kernels"]) == PROFILE_KEYS == set(profile["mitsuba_direct_kernels"])
    err = printed.err.splitlines()
    assert err[0].startswith("device: ") and fig["device"]["variant"] in err[0]
    assert err[1].startswith("colour reference by phase: ") and err[-1].startswith("kernels: ")
    assert [ln.split()[0] for ln in err[2:-1]] == list(profile["phases"])
    assert main(["bench", "models", "--width", "48", "--height", "27", "--spp", "4"]) == 0
    printed = capsys.readouterr()
    fig = json.loads(printed.out)
    assert fig["sdsm_over_oracle_ratio"] > 0
    assert fig["device"]["name"]
    for family, ref in (("models", "oracle_visibility"), ("aa_models", "oracle_color")):
        assert set(fig[ref]["profile"]) == PROFILE_KEYS | {"phases"}
        for row in fig[family].values():
            assert set(row["profile"]) == PROFILE_KEYS | {"on_new_frame"}
            new = row["profile"]["on_new_frame"]
            assert new["cache_hits"] + new["compiled"] == new["launches"]
    # stderr: the device, then per family a header, a column line and one row per model
    err = printed.err.splitlines()
    assert err[0].startswith("device: ")
    for title, family in (("shadow models", "models"), ("AA models", "aa_models")):
        at = err.index(f"{title} (profiled runs; seconds)")
        assert err[at + 1].split()[:2] == ["wall", "trace"]
        names = [ln.split()[0] for ln in err[at + 2 : at + 3 + len(fig[family])]]
        assert names == ["reference", *fig[family]]
