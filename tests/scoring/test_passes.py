"""The score passes and their plan: one rule for the receivers, and a family registered only
here (a visibility channel judged over frames, its steady state against the reference) that
gets its passes with no file under oracle/scoring/ naming it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from raster_oracle.oracle.reference.cache import ReferenceCache
from raster_oracle.oracle.scoring.channels import CHANNEL_KIND, on_receivers
from raster_oracle.oracle.scoring.ci.gates import evaluate_gates, parse_gates
from raster_oracle.oracle.scoring.options import ScoreOptions
from raster_oracle.oracle.scoring.passes.plan import plan
from raster_oracle.oracle.scoring.request import ScoreRequest
from raster_oracle.oracle.scoring.score import score
from raster_oracle.oracle.scoring.technique import score_model
from raster_oracle.raster_models import registry
from raster_oracle.raster_models.result import ModelResult

from raster_oracle import raster_models, scenes

W, H = 48, 27
SCORING = Path(__file__).resolve().parents[2] / "oracle" / "scoring"


def _names(request) -> list[str]:
    return [p.NAME for p in plan(request)]


def test_the_receivers_rule_is_one_rule_for_hard_and_soft_shadows():
    assert {c for c in CHANNEL_KIND if on_receivers(c)} == {
        "visibility",
        "soft_visibility",
        "light_fraction",
    }


def test_a_soft_shadow_factor_keeps_its_off_receiver_count_and_note(tmp_path):
    """Outside a spot light's cone the oracle's (soft) visibility is 0; an engine writes 1
    there. Those pixels are not scored, and now counted and named for soft channels too."""
    loaded = scenes.load("spot", width=W, height=H)

    def lit(frame_scene, k):
        return np.ones((H, W), np.float32), {"frame": k}

    request = ScoreRequest(
        loaded,
        "soft_visibility",
        lit,
        options=ScoreOptions(spp=4),
        cache=ReferenceCache(tmp_path),
    )
    assert "receivers" in _names(request)
    result = score(request)
    outside = result.record["outside_receivers"]
    assert outside["pixels"] > 100 and outside["differing"] > 100
    assert (
        f"soft_visibility: {outside['differing']} of the {outside['pixels']} pixels off the "
        "oracle's receivers" in " ".join(result.notes)
    )


@dataclass(frozen=True)
class _DenoisedParams:
    """A test technique: a shadow map whose frame-0 error (lit where it is shadowed, by
    ``bias``) halves every frame, as a denoiser's history converges."""

    bias: float = 0.4


def _denoised(scene, p: _DenoisedParams) -> ModelResult:
    hard = raster_models.run("shadow-map", scene, resolution=256)
    vis = np.asarray(hard.outputs["visibility"], np.float32)
    vis = np.clip(vis + p.bias * 0.5**scene.frame * (1.0 - vis), 0.0, 1.0).astype(np.float32)
    return ModelResult(
        technique="denoised-test",
        outputs={"visibility": vis},
        cost={"memory_bytes": 0},
        diagnostics={},
        params={"bias": p.bias},
        wall_seconds=0.0,
    )


@pytest.fixture
def denoised(monkeypatch):
    family = registry.Family(
        "denoised-test",
        None,
        ("visibility",),
        ("visibility_mae",),
        ("memory_bytes",),
        "memory_bytes",
        temporal=True,
        steady_against="reference",
    )
    technique = registry.Technique(
        "denoised-test",
        "a test family: a shadow map converging over frames",
        (),
        _DenoisedParams,
        _denoised,
        ("directional", "spot", "point"),
        family="denoised-test",
    )
    monkeypatch.setitem(registry.FAMILIES, family.name, family)
    monkeypatch.setitem(registry.TECHNIQUES, technique.name, technique)
    return technique.name


def test_a_temporal_visibility_family_registered_here_gets_its_passes(tmp_path, denoised):
    # by construction: nothing under oracle/scoring/ names this family
    assert not any(denoised in f.read_text() for f in SCORING.rglob("*.py"))
    loaded = scenes.load("plate", width=W, height=H)
    options = ScoreOptions(spp=4, frames=4, camera_path="dolly")
    request = ScoreRequest.for_model(
        loaded, denoised, {}, options=options, cache=ReferenceCache(tmp_path)
    )
    names = _names(request)
    for step in ("noise floor", "temporal floor", "summary", "temporal", "receivers"):
        assert step in names, step
    # no colour video, no coverage, no yardstick model: its steady state is the reference's
    for step in ("video", "coverage", "steady yardstick"):
        assert step not in names, step
    rec = score_model(request).record
    assert rec["channel"] == "visibility" and len(rec["frames"]) == 4
    floor = rec["noise_floor"]
    for key in ("visibility_mae", "flicker", "temporal_error", "steady_error"):
        assert floor[key] is not None and floor[key] >= 0, key
    # the error halves frame by frame: converging, the steady level below frame 0's
    errors = rec["temporal_aa"]["frame_errors"]
    assert errors[0] > errors[1] > errors[-1]
    assert rec["steady_error"] == pytest.approx(np.mean(errors))
    assert rec["flicker"] is not None and rec["convergence_frames"] is not None
    assert rec["outside_receivers"]["pixels"] >= 0
    checks = evaluate_gates(parse_gates(["visibility_mae=1", "flicker=1"]), rec)
    assert [c.passed for c in checks] == [True, True]
    tight = evaluate_gates(parse_gates([f"visibility_mae={rec['visibility_mae'] / 2}"]), rec)
    assert not tight[0].passed


def test_score_to_folder_returns_the_record_it_writes(tmp_path):
    import json

    from raster_oracle.oracle.scoring.to_folder import score_to_folder

    loaded = scenes.load("plate", width=W, height=H)
    request = ScoreRequest.for_model(
        loaded,
        "shadow-map",
        {"resolution": 256},
        options=ScoreOptions(spp=4),
        cache=ReferenceCache(tmp_path / "cache"),
    )
    gates = parse_gates(["visibility_mae=1"])
    verdict, record = score_to_folder(request, out=tmp_path / "out", gates=gates)
    assert verdict.exit_code == 0 and record["exit_code"] == 0
    assert record == json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert record["technique"] == "shadow-map" and record["gates"][0]["passed"]
