"""Where a sweep's work runs: a scene group's references and cases together on one worker
(sequence groups first), and side tasks (the main job's sections) beside the cases on the same
local cluster, with the same records as in one process."""

from __future__ import annotations

import os

from raster_oracle.oracle.studies.claims.run import run_claims
from raster_oracle.oracle.sweeps.cases import reference_jobs
from raster_oracle.oracle.sweeps.mainjob import aa_memory_study
from raster_oracle.oracle.sweeps.placement import group_homes, grouped
from raster_oracle.oracle.sweeps.run import SideTask, run_sweep
from raster_oracle.oracle.sweeps.spec import expand_spec
from raster_oracle.oracle.sweeps.store import SweepStore

SIZE = {"width": 48, "height": 27, "spp": 4, "seed": 0}


def _rec(scene: str, technique: str = "shadow-map", **kw) -> dict:
    rec = {
        "scene": scene,
        "technique": technique,
        "params": {},
        "light": 0,
        "camera_path": None,
        "light_path": None,
        "frame": 0,
        "n_frames": 1,
        **SIZE,
    }
    return {**rec, **kw}


def _todo(recs):
    return [(f"k{i}", rec, {}) for i, rec in enumerate(recs)]


def test_grouped_keeps_a_scene_group_together_sequences_first():
    recs = [
        _rec("plate"),
        _rec("decal", "noaa"),
        _rec("plate", params={"resolution": 256}),
        # a temporal family on a camera path: a sequence case (8 frames)
        _rec("slide", "taa", camera_path="static", n_frames=8),
        _rec("decal", "fxaa"),
        _rec("slide", "noaa", camera_path="static", n_frames=8),
    ]
    order = [rec["scene"] for _, rec, _ in grouped(_todo(recs))]
    assert order == ["slide", "slide", "plate", "plate", "decal", "decal"]
    # stable inside a group: the spec's order
    keys = [k for k, _, _ in grouped(_todo(recs))]
    assert keys == ["k3", "k5", "k0", "k2", "k1", "k4"]


def test_group_homes_put_a_groups_references_and_cases_on_one_worker():
    recs = [_rec(s) for s in ("plate", "plate", "spot", "decal", "decal", "decal")]
    recs.append(_rec("plate", width=96, height=54))  # another film: another group
    todo = _todo(recs)
    workers = ["tcp://a", "tcp://b"]
    homes = group_homes(todo, workers)
    assert set(homes.values()) == set(workers)  # both workers get work
    load = dict.fromkeys(workers, 0)
    for _, rec, _ in todo:
        load[homes[(rec["scene"], rec["width"], rec["height"], 4, 0, None, None)]] += (
            rec["width"] * rec["height"]
        )
    # largest group first, each next one on the less loaded worker: 5184 | 3888 + 2592,
    # then spot's 1296 on the first: equal loads
    assert load == {"tcp://a": 6480, "tcp://b": 6480}

    # every reference a case needs has the case's home
    def group(r):
        return tuple(r[k] for k in ("scene", "width", "height", "spp", "light"))

    for _, rec, _ in todo:
        for job in reference_jobs(rec):
            assert group(job) == group(rec) and len(homes) == 4
    assert group_homes(todo, ["tcp://a"]) == {}  # one worker: nothing to prefer


SPEC = {
    "name": "placement",
    "defaults": {"width": 48, "height": 27, "spp": 4, "seed": 0},
    "case": [
        {"scenes": ["plate", "spot"], "technique": "shadow-map",
         "params": {"resolution": [64, 256]}},
        {"scenes": ["decal"], "technique": "noaa"},
    ],
}  # fmt: skip


def _metrics(db) -> dict:
    with SweepStore(db, readonly=True) as store:
        return {r["key"]: (r["metrics"], r["cost"], r["params"]) for r in store.rows()}


def test_side_tasks_run_beside_the_cases_and_records_match_one_process(tmp_path):
    cache = os.environ["RASTER_ORACLE_CACHE"]
    side = [
        SideTask("memory", aa_memory_study, {"quick": True}),
        # a part that raises: its error comes back, the sweep goes on
        SideTask("broken", run_claims, {"out": None, "only": ["no-such-claim"]}),
    ]
    inline = run_sweep(
        expand_spec(SPEC), tmp_path / "a.db", cache_root=cache, workers=0, quiet=True, side=side
    )
    cluster = run_sweep(
        expand_spec(SPEC), tmp_path / "b.db", cache_root=cache, workers=2, quiet=True, side=side
    )
    for summary in (inline, cluster):
        assert summary["done"] == 5 and summary["failed"] == 0
        assert set(summary["side"]) == {"memory", "broken"}
        memory, broken = summary["side"]["memory"], summary["side"]["broken"]
        assert memory["error"] is None and memory["seconds"] >= 0.0
        assert memory["value"]["schema"] == "raster-oracle.aa-memory/1"
        assert broken["value"] is None and "no-such-claim" in broken["error"]
        assert broken["error"].startswith("ValueError: ")
    assert inline["side"]["memory"]["value"] == cluster["side"]["memory"]["value"]
    assert _metrics(tmp_path / "a.db") == _metrics(tmp_path / "b.db")
    # a store with every case done still runs the side tasks
    again = run_sweep(
        expand_spec(SPEC), tmp_path / "b.db", cache_root=cache, workers=0, quiet=True, side=side
    )
    assert again["ran"] == 0 and set(again["side"]) == {"memory", "broken"}
