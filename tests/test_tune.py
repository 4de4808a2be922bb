"""``tune``: the cheapest shadow-map resolution meeting an error target on ``plate``, an answer
known from scoring every resolution directly (error falls with resolution, memory grows)."""

from __future__ import annotations

import json

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.cache import ReferenceCache
from raster_oracle.oracle.sweeps.cases import evaluate_case
from raster_oracle.oracle.sweeps.tune import TuneError, parse_space, parse_target, run_tune

from raster_oracle import scenes

SCENE = "plate"
W, H, SPP = 96, 54, 16
RESOLUTIONS = (32, 64, 128, 256, 512)
METRIC = "misclassified_fraction"


@pytest.fixture(scope="module")
def truth():
    """The metric of every resolution, scored directly (no Optuna)."""
    loaded = scenes.load(SCENE, width=W, height=H)
    out = {}
    for res in RESOLUTIONS:
        rec = evaluate_case(
            loaded, "shadow-map", {"resolution": res}, spp=SPP, seed=0, cache=ReferenceCache()
        )
        out[res] = (rec["metrics"][METRIC], rec["cost"]["shadow_map_bytes"])
    return out


def test_known_answer_on_the_grid(tmp_path, truth):
    errors = [truth[r][0] for r in RESOLUTIONS]
    # the premise: error does not grow with resolution, and the target separates 64 from 128
    assert errors == sorted(errors, reverse=True)
    assert errors[1] > errors[2]
    target = 0.5 * (errors[1] + errors[2])
    answer = min(r for r in RESOLUTIONS if truth[r][0] <= target)
    assert answer == 128
    db = tmp_path / "tune.db"
    kw = dict(
        technique="shadow-map",
        target=(METRIC, target),
        trials=len(RESOLUTIONS),
        vary=[f"resolution={','.join(map(str, RESOLUTIONS))}"],
        width=W,
        height=H,
        spp=SPP,
        db=db,
        cache=ReferenceCache(),
    )
    result = run_tune(SCENE, **kw)
    assert result["sampler"] == "grid" and result["trials"] == len(RESOLUTIONS)
    assert result["best"]["params"] == {"resolution": answer}
    assert result["best"]["cost"] == truth[answer][1] == answer * answer * 4
    assert result["best"]["metric"] == truth[answer][0]
    assert result["minimize"] == "shadow_map_bytes"
    # the study lives in the same file and continues: nothing left to try, same answer
    again = run_tune(SCENE, **kw)
    assert again["study"] == result["study"] and again["trials"] == len(RESOLUTIONS)
    assert again["best"] == result["best"]


def test_tpe_search_returns_a_feasible_configuration_never_cheaper_than_the_optimum(
    tmp_path, truth
):
    target = truth[128][0]  # met at 128 and above: half of the log-uniform range
    optimum = min(truth[r][1] for r in RESOLUTIONS if truth[r][0] <= target)
    result = run_tune(
        SCENE,
        technique="shadow-map",
        target=(METRIC, target),
        trials=10,
        vary=["resolution=32:512"],
        width=W,
        height=H,
        spp=SPP,
        db=tmp_path / "tune.db",
        cache=ReferenceCache(),
    )
    assert result["sampler"] == "tpe"
    best = result["best"]
    assert best is not None and best["metric"] <= target
    assert best["cost"] >= optimum
    # its cost is its resolution's memory: 4-byte D32F texels
    assert best["cost"] == best["params"]["resolution"] ** 2 * 4


def test_target_and_space_parsing():
    assert parse_target("flip_mean<=0.05") == ("flip_mean", 0.05)
    with pytest.raises(TuneError, match="unknown metric 'flip'"):
        parse_target("flip<=0.05")
    with pytest.raises(TuneError, match="METRIC<=VALUE"):
        parse_target("flip_mean=0.05")
    with pytest.raises(TuneError, match="finite"):
        parse_target("flip_mean<=nan")
    assert parse_space("shadow-map", []) == {"resolution": ("int", 64, 4096)}
    assert parse_space("shadow-map", ["bias=0.001:0.01"]) == {"bias": ("float", 0.001, 0.01)}
    space = parse_space("shadow-map", ["filter=pcf,hw_pcf"])
    assert [json.loads(v) for v in space["filter"][1]] == ["pcf", "hw_pcf"]
    with pytest.raises(TuneError, match="unknown parameter 'resolutoin'"):
        parse_space("shadow-map", ["resolutoin=1:2"])
    with pytest.raises(TuneError, match="0 < lo < hi"):
        parse_space("shadow-map", ["resolution=0:64"])


@pytest.mark.parametrize(
    "args, message",
    [
        (["--target", "nope<=1"], "unknown metric 'nope'"),
        (["--target", "flip_mean<=1", "--vary", "filter=1:2"], "needs a number parameter"),
        (["--target", "flip_mean<=1", "--technique", "pcs"], "unknown technique 'pcs'"),
        (
            ["--target", "misclassified_fraction<=0.1", "--minimize", "nope"],
            "--minimize nope: not a cost of shadow-map; choose from",
        ),
        (
            ["--target", "misclassified_fraction<=0.1", "--minimize", "misclassified_fraction"],
            "--minimize misclassified_fraction: not a cost of shadow-map",
        ),
    ],
)
def test_bad_tune_requests_exit_2(tmp_path, capsys, args, message):
    """One line, exit 2, and no store written (a bad --minimize is found before the study)."""
    db = tmp_path / "t.db"
    argv = ["tune", SCENE, "--technique", "shadow-map", "--db", str(db), *args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not db.exists()
