"""No gate on nothing (issue 43, item 3): a gated metric whose support is empty (no receiver
in view, no edge-band pixel) is exit 2 with one line naming the case, the metric and the
empty set; the record says ``support: 0`` and holds no value for it (never a perfect score
from nothing)."""

from __future__ import annotations

import pytest
from raster_oracle.oracle.scoring.ci.checks import GateError
from raster_oracle.oracle.scoring.ci.gates import evaluate_gates, parse_gates, support_record

SCENE = {"name": "plate", "resolution": [320, 180], "light_index": 0}


def _record(receivers, band, frames=None):
    return {
        "channel": "visibility",
        "reference": {"scene": SCENE},
        "misclassified_fraction": 0.0,
        "edge_band_misclassified_fraction": 0.0,
        "flip_mean": 0.0,
        "receiver_count": receivers,
        "edge_band_count": band,
        "frames": frames,
        "noise_floor": {},
    }


def test_a_view_without_receivers_is_exit_2_naming_case_metric_and_set():
    record = _record(0, 0)
    support = support_record(record)
    assert support == {
        "misclassified_fraction": 0,
        "edge_band_misclassified_fraction": 0,
        "flip_mean": 0,
    }
    assert record["misclassified_fraction"] is None and record["support"] == support
    with pytest.raises(
        GateError,
        match=r"case plate: misclassified_fraction is computed over "
        r"the receivers, and this run has none \(support: 0\)",
    ):
        evaluate_gates(parse_gates(["misclassified_fraction=0.01"]), record)


def test_an_empty_edge_band_alone_stops_only_its_gates():
    record = _record(5000, 0)
    support_record(record)
    (ok,) = evaluate_gates(parse_gates(["misclassified_fraction=0.01"]), record)
    assert ok.passed
    with pytest.raises(GateError, match="edge-band receivers"):
        evaluate_gates(parse_gates(["edge_band_misclassified_fraction=0.01"]), record)


def test_frames_are_summed_and_colour_is_not_counted():
    frames = [
        {"receiver_count": 0, "edge_band_count": 0, "misclassified_fraction": 0.0},
        {"receiver_count": 10, "edge_band_count": 2, "misclassified_fraction": 0.1},
    ]
    record = _record(5, 1, frames)
    assert support_record(record)["misclassified_fraction"] == 10
    colour = {"channel": "color", "flip_mean": 0.0, "reference": {"scene": SCENE}}
    assert support_record(colour) == {} and colour["flip_mean"] == 0.0
