"""TAA in a sweep over a moving scene, next to the spatial techniques: every case scores the
whole sequence (steady error and ghosting), and the report puts the TAA variants on the
anti-aliasing fronts, cost against steady error and against ghosting."""

from __future__ import annotations

import os

from raster_oracle.oracle.sweeps.report import sweep_report
from raster_oracle.oracle.sweeps.run import run_sweep
from raster_oracle.oracle.sweeps.spec import load_spec
from raster_oracle.oracle.sweeps.store import SweepStore

SPEC = """
name = "taa"
[defaults]
width = 48
height = 27
spp = 4
seed = 0

[[case]]
scenes = ["slide"]
technique = "taa"
frames = [0]
camera_path = "static"
n_frames = 4
[case.params]
preset = "hdrp"
reprojection = ["motion", "off"]

[[case]]
scenes = ["slide"]
technique = "msaa"
frames = [0]
camera_path = "static"
n_frames = 4
[case.params]
samples = 4
"""


def test_taa_sweep_scores_sequences_and_shares_the_anti_aliasing_fronts(tmp_path):
    spec = tmp_path / "taa.toml"
    spec.write_text(SPEC)
    db = tmp_path / "taa.db"
    cache = os.environ["RASTER_ORACLE_CACHE"]
    summary = run_sweep(load_spec(spec), db, cache_root=cache, workers=0, quiet=True)
    assert summary["done"] == 3 and summary["failed"] == 0
    with SweepStore(db, readonly=True) as store:
        rows = store.rows()
    by = {(r["technique"], r["params"].get("reprojection")): r for r in rows}
    on, off = by[("taa", "motion")], by[("taa", "off")]
    msaa = next(r for r in rows if r["technique"] == "msaa")
    for r in (on, off, msaa):
        assert r["metrics"]["steady_error"] is not None
        assert r["metrics"]["ghosting_error"] is not None
    assert off["metrics"]["ghosting_error"] > on["metrics"]["ghosting_error"]
    assert on["cost"]["history_bytes"] == 2 * 8 * 48 * 27
    out = tmp_path / "report.html"
    sweep_report(db, out)
    import json

    record = json.loads(out.with_suffix(".json").read_text())
    (group,) = record["groups"]  # TAA joins the anti-aliasing techniques' group
    assert group["family"] == "aa"
    fronts = {(f["cost_key"], f["metric"]) for f in group["fronts"]}
    assert ("framebuffer_bytes", "ghosting_error") in fronts
    assert ("framebuffer_bytes", "steady_error") in fronts
