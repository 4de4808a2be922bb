"""The main job's anti-aliasing ranking: rows of a sweep store ranked by coverage edge error,
neighbours closer than their noise floors marked, the section rendered."""

from __future__ import annotations

from raster_oracle.oracle.studies.aa_ranking import aa_ranking
from raster_oracle.oracle.sweeps.store import SweepStore
from raster_oracle.reports.sections import aa_ranking_section, render_section


def _row(key, technique, params, cov, floor, *, scene="star", status="done"):
    return {
        "key": key, "sweep": "s", "scene": scene, "technique": technique, "family": "aa",
        "params": params, "frame": 0, "width": 64, "height": 36, "spp": 4, "seed": 0,
        "metrics": {"coverage_edge_rmse": cov, "edge_mae": cov / 2, "flip_mean": 0.1,
                    "noise_floor": {"coverage_edge_rmse": floor}},
        "cost": {"framebuffer_bytes": 100}, "wall_seconds": 1.0, "status": status,
        "run_id": "r",
    }  # fmt: skip


def test_ranking_orders_by_coverage_edge_error_and_marks_the_floor(tmp_path):
    db = tmp_path / "sweep.db"
    with SweepStore(db) as store:
        store.put(_row("a", "noaa", {}, 0.30, 0.01))
        store.put(_row("b", "smaa", {"preset": "low", "mode": "1x"}, 0.19, 0.01))
        store.put(_row("c", "smaa", {"preset": "high", "mode": "1x"}, 0.185, 0.01))
        store.put(_row("d", "msaa", {"samples": 8}, 0.05, 0.01))
        store.put(_row("e", "agaa", {}, 0.01, 0.01))  # not a ranked technique
        store.put(_row("f", "noaa", {}, 0.3, 0.01, scene="plate"))  # no SMAA there
        store.put(_row("g", "smaa", {"preset": "ultra"}, 0.1, 0.01, status="failed"))
    with SweepStore(db, readonly=True) as store:
        data = aa_ranking(store.rows())
    (table,) = data["scenes"]
    rows = table["rows"]
    assert [r["label"] for r in rows] == [
        "msaa (samples=8)",
        "smaa (preset=high, mode=1x)",
        "smaa (preset=low, mode=1x)",
        "noaa",
    ]
    assert [r["rank"] for r in rows] == [1, 2, 3, 4]
    # 0.19 - 0.185 is within the 0.01 floor: not separated; the others are
    assert [r["separated"] for r in rows] == [True, True, False, True]
    html = render_section(aa_ranking_section(data))
    assert "not separated" in html and "0.185 (floor 0.01)" in html


def test_no_rows_give_an_empty_ranking():
    data = aa_ranking([])
    assert data["scenes"] == []
    assert "No SMAA case" in render_section(aa_ranking_section(data))
