"""The detection-power study (oracle/studies/detection.py) at its smallest published cell:
every injected fault is caught by the recommended gate and the correct engine is not
flagged (docs/metrics.md, "Detection power"); the README's former misclassified-only gate
misses the one-texel fault there (issue 43, item 2)."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.studies import detection


@pytest.fixture(scope="module")
def rows(_backend):
    return {r["fault"]: r for r in detection.run_cell("plate", (320, 180), 1024)}


def test_every_fault_is_caught_and_the_correct_engine_passes(rows):
    assert set(rows) == set(detection.FAULTS)
    for fault, r in rows.items():
        assert r["effect"], fault
        assert r["caught"], (fault, r["faulty"])
        assert not r["correct_flagged"], (fault, r["correct"])


def test_a_misclassified_only_gate_misses_the_one_texel_fault(rows):
    bad = rows["one_texel_offset"]["faulty"]
    # the README's former gate (misclassified <= 0.005) passes it; the edges moved a texel
    assert bad["conformance_misclassified_fraction"] < 0.005
    assert bad["conformance_edge_displacement_px"] > 0.5
    assert "conformance_edge_displacement_px" in detection.gate_fails(bad)


def test_image_shifts_are_measured_in_pixels(rows):
    for fault, px in (("image_shift_1px", 1.0), ("image_shift_0.3px", 0.3)):
        got = rows[fault]["faulty"]["conformance_edge_displacement_px"]
        assert got == pytest.approx(px, abs=0.05)


def test_gate_and_table():
    assert detection.gate_fails({"conformance_edge_displacement_px": 0.2}) == [
        "conformance_edge_displacement_px"
    ]
    assert detection.gate_fails({"conformance_misclassified_fraction": 0.0}) == []
    vals = dict.fromkeys(detection.METRICS, 0.0)
    row = {
        "scene": "s",
        "width": 4,
        "height": 2,
        "map": 8,
        "fault": "f",
        "correct": vals,
        "faulty": vals,
        "effect": False,
        "caught": False,
        "correct_flagged": False,
    }
    table = detection.markdown_table({"rows": [row]})
    assert "| s | 4x2 | 8 | f |" in table and "no effect" in table


def test_conformance_values_are_zero_for_identical_masks():
    m = np.zeros((20, 30), np.float32)
    m[:, 15:] = 1.0
    rec = np.ones_like(m, dtype=bool)
    v = detection.conformance_values(m, m.copy(), rec)
    assert v["conformance_misclassified_fraction"] == 0.0
    assert v["conformance_edge_displacement_px"] == 0.0
    assert v["changed_pixels"] == 0 and v["receivers"] == 600


def test_bench_detection_command(tmp_path, capsys, _backend):
    import json

    from raster_oracle.oracle.cli import main

    argv = ["bench", "detection", "--scenes", "plate", "--screens", "96x54", "--maps", "256"]
    rc = main([*argv, "--faults", "image_shift_1px", "--out", str(tmp_path), "--quiet"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["summary"]["caught"] == 1 and out["summary"]["rows"] == 1
    rows = json.loads((tmp_path / "detection.json").read_text())["rows"]
    assert rows[0]["fault"] == "image_shift_1px" and rows[0]["caught"]
    assert "| image_shift_1px |" in (tmp_path / "detection.md").read_text()
    for bad, say in (
        (["--screens", "96"], "--screens expects WxH"),
        (["--faults", "nope"], "unknown fault(s) nope"),
        (["--scenes", "nosuch"], "unknown scene 'nosuch'"),
    ):
        assert main(["bench", "detection", *bad, "--quiet"]) == 2
        assert say in capsys.readouterr().err
    assert main(["bench", "models", "--maps", "256"]) == 2
    assert "applies to 'bench detection' only" in capsys.readouterr().err
