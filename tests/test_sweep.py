"""Sweeps: spec expansion, bad specs, the SQLite store (resume after SIGKILL, integrity),
failing cases, determinism across runs and across Dask/in-process execution."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.sweeps.cases import WorkerCache
from raster_oracle.oracle.sweeps.run import run_sweep, sweep_keys
from raster_oracle.oracle.sweeps.spec import SpecError, expand_spec, expand_values, load_spec
from raster_oracle.oracle.sweeps.store import SweepStore
from raster_oracle.raster_models import params, registry
from raster_oracle.raster_models.shadowmaps import shadow_map

from raster_oracle import raster_models

SIZE = "width = 48\nheight = 27\n"
#: How long the SIGKILL test waits for the first committed rows / for the killed sweep's
#: stragglers, in seconds (generous: the machine is shared).
WAIT_S = 240.0


def _spec(tmp_path: Path, text: str, name: str = "spec.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- expansion ---------------------------------------------------------------------------


def test_range_is_inclusive_and_exact():
    assert expand_values("x", {"range": [0.1, 0.3, 0.1]}) == [0.1, 0.2, 0.3]
    assert expand_values("x", {"range": [1, 10, 3]}, kind="int") == [1, 4, 7, 10]
    # the end is not reached exactly: 1, 4, 7 (10 > 9)
    assert expand_values("x", {"range": [1, 9, 3]}, kind="int") == [1, 4, 7]
    assert expand_values("x", {"range": [2, 2, 1]}, kind="int") == [2]


def test_logrange_is_geometric_and_rounded_for_ints():
    assert expand_values("x", {"logrange": [64, 4096, 4]}, kind="int") == [64, 256, 1024, 4096]
    assert expand_values("x", {"logrange": [1, 100, 3]}) == pytest.approx([1.0, 10.0, 100.0])
    # 1, 3^(1/4) = 1.32, 3^(1/2) = 1.73, 3^(3/4) = 2.28, 3: rounded, repeats dropped
    assert expand_values("x", {"logrange": [1, 3, 5]}, kind="int") == [1, 2, 3]
    assert expand_values("x", {"logrange": [5, 50, 1]}) == [5.0]


def test_lists_scalars_and_tuple_parameters():
    assert expand_values("x", ["pcf", "hw_pcf"], kind="str") == ["pcf", "hw_pcf"]
    assert expand_values("x", 3, kind="int") == [3]
    # a list parameter: a flat list is one value, a list of lists is several
    assert expand_values("x", [0.1, 0.5], kind="floats") == [[0.1, 0.5]]
    assert expand_values("x", [[0.1], [0.2, 0.4]], kind="floats") == [[0.1], [0.2, 0.4]]


def test_grid_is_the_cartesian_product_of_scenes_params_and_frames():
    data = {
        "name": "grid",
        "defaults": {"width": 48, "height": 27, "spp": 4},
        "case": [
            {
                "scenes": ["plate", "city"],
                "technique": "shadow-map",
                "frames": [0, 2],
                "camera_path": "dolly",
                "params": {
                    "resolution": {"logrange": [256, 1024, 3]},
                    "filter": ["hw_pcf", "pcf"],
                    "bias": 0.004,
                },
            },
            # csm needs a directional light: skipped on spot, kept on plate
            {"scenes": ["spot", "plate"], "technique": "csm", "spp": 8},
        ],
    }
    exp = expand_spec(data)
    shadow = [c for c in exp.cases if c.technique == "shadow-map"]
    assert len(shadow) == 2 * 3 * 2 * 2
    combos = {(c.scene, c.params["resolution"], c.params["filter"], c.frame) for c in shadow}
    assert len(combos) == 24
    assert {c.params["resolution"] for c in shadow} == {256, 512, 1024}
    assert all(c.params["bias"] == 0.004 and c.n_frames == 8 for c in shadow)
    csm = [c for c in exp.cases if c.technique == "csm"]
    assert [(c.scene, c.spp, c.frame) for c in csm] == [("plate", 8, 0)]
    assert len(exp.skipped) == 1 and "csm on spot" in exp.skipped[0]


def test_keys_cover_every_parameter_default_included():
    base = {"name": "k", "defaults": {"width": 48, "height": 27, "spp": 4}}
    explicit = {"scenes": ["plate"], "technique": "shadow-map", "params": {"resolution": 2048}}
    implicit = {"scenes": ["plate"], "technique": "shadow-map"}
    other_spp = {**implicit, "spp": 8}
    other_res = {"scenes": ["plate"], "technique": "shadow-map", "params": {"resolution": 1024}}
    cases = expand_spec({**base, "case": [explicit, implicit, other_spp, other_res]}).cases
    keys = [k for k, _, _ in sweep_keys(cases, "llvm_ad_rgb")]
    assert shadow_map.ShadowMapParams().resolution == 2048
    assert keys[0] == keys[1]  # the default written out is the same case
    assert len({keys[1], keys[2], keys[3]}) == 3
    assert sweep_keys(cases[:1], "cuda_ad_rgb")[0][0] != keys[0]  # the backend is in the key


# --- bad specs ----------------------------------------------------------------------------

_OK = f'name = "t"\n[defaults]\n{SIZE}spp = 4\n'
BAD_SPECS = {
    "unknown top key": ("nmae = 'x'\n", "nmae: unknown key"),
    "not TOML": ("[[case]\n", "not valid TOML"),
    "no case": (_OK, "case: a spec needs at least one"),
    "technique given as a list": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = ["csm"]\n',
        "case[0].technique: unknown technique ['csm']",
    ),
    "arrays nested 10^5 deep": (
        _OK + "x = " + "[" * 100000 + "]" * 100000 + "\n",
        "nested too deeply",
    ),
    "larger than the spec size cap": (
        _OK + "# " + "x" * (1 << 20) + "\n",
        "larger than 1048576 bytes",
    ),
    "range whose value count overflows": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "bias = {range = [0.0, 1e308, 1e-308]}\n",
        "more than",
    ),
    "range whose span overflows": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "bias = {range = [-1e308, 1e308, 1.0]}\n",
        "more than",
    ),
    "integer logrange whose ratio overflows": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "resolution = {logrange = [1e-300, 1e300, 3]}\n",
        "end / start overflows",
    ),
    "seed beyond 32 bits": (
        'name = "t"\n[defaults]\nseed = 1180591620717411303424\n'
        '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n',
        r"defaults.seed: must be >= 0 and <= 4294967295",
    ),
    "unknown technique": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "pcs"\n',
        "case[0].technique: unknown technique 'pcs'",
    ),
    "unknown parameter": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\nresoltion = 5\n',
        "case[0].params.resoltion: unknown parameter",
    ),
    "value out of range": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\nresolution = -4\n',
        "case[0].params: csm: parameter resolution",
    ),
    "zero step": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "resolution = {range = [64, 128, 0]}\n",
        "case[0].params.resolution.range: step must be > 0",
    ),
    "logrange from zero": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "resolution = {logrange = [0, 128, 3]}\n",
        "case[0].params.resolution.logrange: bounds must be > 0",
    ),
    "bad table value": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n[case.params]\n'
        "resolution = {steps = [1, 2]}\n",
        "case[0].params.resolution: a table value must be",
    ),
    "unknown scene": (
        _OK + '[[case]]\nscenes = ["plaet"]\ntechnique = "csm"\n',
        "case[0].scenes[0]: unknown scene 'plaet'",
    ),
    "frames without path": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\nframes = [0, 1]\n',
        "case[0].frames: frames other than 0 need",
    ),
    "unknown camera path": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\nframes = [1]\n'
        'camera_path = "orbit"\n',
        "case[0].camera_path: unknown camera path 'orbit'",
    ),
    "width without height": (
        '[defaults]\nwidth = 48\n[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n',
        "defaults: give both width and height",
    ),
    "spp zero": ("[defaults]\nspp = 0\n", "defaults.spp: must be >= 1"),
    "unknown case key": (
        _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\nresolution = 5\n',
        "case[0].resolution: unknown key",
    ),
}


@pytest.mark.parametrize("name", list(BAD_SPECS))
def test_bad_spec_is_one_line_exit_2_nothing_written(tmp_path, capsys, name):
    text, message = BAD_SPECS[name]
    spec = _spec(tmp_path, text)
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not out.exists()


def test_unreachable_scheduler_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("raster_oracle.oracle.sweeps.run.SCHEDULER_TIMEOUT_S", 1)
    spec = _spec(tmp_path, _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n')
    args = ["sweep", str(spec), "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "o")]
    assert main([*args, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler tcp://127.0.0.1:1: cannot connect" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_spec_that_is_not_a_regular_file_exit_2(tmp_path, capsys, kind):
    """A FIFO nobody writes would block the read forever, /dev/zero would never end: both
    are refused before reading."""
    import os

    if kind == "fifo":
        spec = tmp_path / "spec.toml"
        os.mkfifo(spec)
    else:
        spec = "/dev/zero"
    out = tmp_path / "o"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a regular file" in err, err
    assert not out.exists()


def test_missing_spec_file_exit_2(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_database_that_is_not_sqlite_exit_2(tmp_path, capsys):
    spec = _spec(tmp_path, _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n')
    db = tmp_path / "junk.db"
    db.write_bytes(b"not a database, just bytes " * 100)
    rc = main(["sweep", str(spec), "--db", str(db), "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 2
    assert "junk.db" in capsys.readouterr().err


def test_expand_spec_messages_name_the_key():
    with pytest.raises(SpecError, match=r"^case\[0\]\.params\.bias\.range: end"):
        expand_spec(
            {
                "case": [
                    {
                        "scenes": ["plate"],
                        "technique": "shadow-map",
                        "params": {"bias": {"range": [0.5, 0.1, 0.1]}},
                    }
                ]
            }
        )


# --- running, the store, determinism -----------------------------------------------------

SMALL = f"""name = "small"
[defaults]
{SIZE}spp = 4
[[case]]
scenes = ["plate", "spot"]
technique = "shadow-map"
[case.params]
resolution = {{logrange = [64, 256, 3]}}
[[case]]
scenes = ["plate"]
technique = "csm"
frames = [0, 2]
camera_path = "dolly"
"""


def _rows(db) -> dict:
    with SweepStore(db, readonly=True) as store:
        return {r["key"]: r for r in store.rows()}


def test_worker_cache_loads_each_base_scene_once():
    cache = WorkerCache()
    rec = {"scene": "plate", "width": 48, "height": 27, "light": 0, "frame": 0}
    first = cache.base_scene(rec)
    assert (first.width, first.height) == (48, 27)
    assert cache.base_scene({**rec, "frame": 3}) is first  # frames share the base scene
    other = cache.base_scene({**rec, "width": 32})
    assert other is not first and other.width == 32
    assert len(cache.scenes) == 2
    cache.ensure_backend(None)  # no variant named: nothing selected
    assert cache.variant is None


def test_same_spec_twice_gives_identical_metrics_inline_and_on_a_dask_scheduler(tmp_path):
    spec = load_spec(_spec(tmp_path, SMALL))
    cache = os.environ["RASTER_ORACLE_CACHE"]
    a = run_sweep(spec, tmp_path / "a.db", cache_root=cache, workers=0, quiet=True)
    assert a["cases"] == 8 and a["done"] == 8 and a["failed"] == 0
    # a cluster of its own, reached with --scheduler (the SIGKILL test uses a LocalCluster)
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=":0") as cluster:
        b = run_sweep(
            spec,
            tmp_path / "b.db",
            cache_root=cache,
            scheduler=cluster.scheduler_address,
            quiet=True,
        )
    assert b["done"] == 8
    ra, rb = _rows(tmp_path / "a.db"), _rows(tmp_path / "b.db")
    assert ra.keys() == rb.keys()
    for key in ra:
        assert ra[key]["metrics"] == rb[key]["metrics"]
        assert ra[key]["cost"] == rb[key]["cost"] and ra[key]["params"] == rb[key]["params"]
    # resolution helps: on plate the misclassified fraction does not grow with resolution
    plate = sorted(
        (r["params"]["resolution"], r["metrics"]["misclassified_fraction"])
        for r in ra.values()
        if r["scene"] == "plate" and r["technique"] == "shadow-map"
    )
    assert [m for _, m in plate] == sorted((m for _, m in plate), reverse=True)
    # a second run finds everything done
    again = run_sweep(spec, tmp_path / "a.db", cache_root=cache, workers=0, quiet=True)
    assert again["skipped_done"] == 8 and again["ran"] == 0


@dataclasses.dataclass(frozen=True)
class _FlakyParams:
    resolution: int = params.param(512, source="test", help="13 fails", lo=1, hi=16384)


def _flaky_run(scene, p):
    if p.resolution == 13:
        raise RuntimeError("boom: unlucky resolution")
    return shadow_map.run(scene, shadow_map.ShadowMapParams(resolution=p.resolution))


@pytest.fixture
def flaky(monkeypatch):
    tech = registry.Technique("flaky", "test", (), _FlakyParams, _flaky_run, ("directional",))
    monkeypatch.setitem(registry.TECHNIQUES, "flaky", tech)
    assert raster_models.TECHNIQUES["flaky"] is tech
    return tech


def test_failing_case_is_recorded_and_the_sweep_goes_on(tmp_path, capsys, flaky):
    spec = _spec(
        tmp_path,
        f'name = "flaky"\n[defaults]\n{SIZE}spp = 4\n[[case]]\nscenes = ["plate"]\n'
        'technique = "flaky"\n[case.params]\nresolution = [64, 13, 128]\n',
    )
    out = tmp_path / "o"
    args = ["sweep", str(spec), "--out", str(out), "--workers", "0", "--quiet"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "1 case(s) failed" in err and "boom: unlucky resolution" in err
    rows = list(_rows(out / "sweep.db").values())
    status = {r["params"]["resolution"]: (r["status"], r["error"]) for r in rows}
    assert status[64] == ("done", None) and status[128] == ("done", None)
    assert status[13][0] == "failed" and "RuntimeError: boom" in status[13][1]
    assert (out / "report.html").is_file()
    # a rerun counts the failure as finished; --retry-failed runs it (and it fails again)
    assert main(args) == 1
    assert "0 already" not in capsys.readouterr().out
    first = {r["key"]: r["finished"] for r in rows}
    assert main([*args, "--retry-failed"]) == 1
    after = {r["key"]: r for r in _rows(out / "sweep.db").values()}
    changed = [k for k in first if after[k]["finished"] != first[k]]
    assert len(changed) == 1 and after[changed[0]]["status"] == "failed"


KILL_SPEC = f"""name = "kill"
[defaults]
{SIZE}spp = 4
[[case]]
scenes = ["plate", "city"]
technique = "sdsm"
[case.params]
resolution = {{range = [256, 1024, 64]}}
"""


def _done_count(db: Path) -> int:
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as conn:
            return conn.execute("SELECT count(*) FROM sweep_cases").fetchone()[0]
    except sqlite3.OperationalError:  # tables not created yet
        return 0


def test_sigkill_loses_only_cases_in_flight_and_resume_skips_finished(tmp_path):
    spec = _spec(tmp_path, KILL_SPEC)
    total = len(load_spec(spec).cases)
    assert total == 2 * 13
    db = tmp_path / "kill.db"
    cmd = [sys.executable, "-m", "raster_oracle.oracle.cli", "sweep", str(spec), "--db", str(db)]
    cmd += ["--out", str(tmp_path / "o"), "--workers", "1", "--quiet"]
    proc = subprocess.Popen(
        cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    try:
        deadline = time.monotonic() + WAIT_S
        while _done_count(db) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, proc.stderr.read().decode()
        os.killpg(proc.pid, signal.SIGKILL)  # the client and its Dask workers, mid-sweep
    finally:
        proc.wait(timeout=60)
        proc.stderr.close()
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    before = _rows(db)
    assert 3 <= len(before) < total
    assert all(r["status"] == "done" for r in before.values())
    summary = run_sweep(
        load_spec(spec),
        db,
        cache_root=os.environ["RASTER_ORACLE_CACHE"],
        workers=0,
        quiet=True,
    )
    assert summary["skipped_done"] == len(before)
    assert summary["ran"] == total - len(before) and summary["failed"] == 0
    after = _rows(db)
    assert len(after) == total
    for key, row in before.items():  # finished rows were not redone
        assert after[key]["run_id"] == row["run_id"] and after[key]["finished"] == row["finished"]
    with SweepStore(db) as store:
        assert store.integrity_ok()


def test_report_of_a_sweep_database(tmp_path, capsys):
    spec = _spec(tmp_path, SMALL)
    out = tmp_path / "o"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    assert "8 cases, 0 already" in capsys.readouterr().out
    html = (out / "report.html").read_text()
    for section in ("Pareto fronts", "Parameter sensitivity", "Best at equal cost", "Cases"):
        assert section in html
    report = tmp_path / "r.html"
    rc = main(["report", "--sweep", str(out / "sweep.db"), "--out", str(report)])
    assert rc == 0
    assert report.is_file() and report.with_suffix(".json").is_file()
    # the summary's cases have pixel viewers with the reference's stderr; same store, same bytes
    inspect = json.loads(report.with_suffix(".json").read_text())["inspect"]
    assert inspect
    again = tmp_path / "again.html"
    assert main(["report", "--sweep", str(out / "sweep.db"), "--out", str(again)]) == 0
    assert again.read_bytes() == report.read_bytes()
    with SweepStore(out / "sweep.db", readonly=True) as store:
        viewers = store.viewers([c["key"] for c in inspect])
    assert len(viewers) == len(inspect)
    assert all(v["frames"][0]["stderr"] and v["channels"] == 1 for v in viewers.values())
    bad = ["report", "--sweep", str(out / "sweep.db"), "--out", str(tmp_path / "b.html")]
    assert main([*bad, "--cost", "shadow_map_byte"]) == 2
    err = capsys.readouterr().err
    assert "--cost shadow_map_byte: in no finished case" in err and "shadow_map_bytes" in err
    assert main([*bad, "--metric", "flip"]) == 2
    assert "--metric flip: in no finished case" in capsys.readouterr().err
    assert not (tmp_path / "b.html").exists()
    rc = main([*bad, "--cost", "render_passes", "--metric", "edge_mae"])
    assert rc == 0
    fronts = json.loads((tmp_path / "b.json").read_text())["groups"][0]["fronts"]
    assert {(f["cost_key"], f["metric"]) for f in fronts} == {("render_passes", "edge_mae")}
    rc = main(["report", "--sweep", str(tmp_path / "none.db"), "--out", str(report)])
    assert rc == 2 and "no such file" in capsys.readouterr().err
    rc = main(["report", str(out), "--sweep", str(out / "sweep.db"), "--out", str(report)])
    assert rc == 2 and "one of them" in capsys.readouterr().err


def test_light_path_frames_are_cases_of_their_own(tmp_path):
    spec = _spec(
        tmp_path,
        f'name = "lp"\n[defaults]\n{SIZE}spp = 4\n[[case]]\nscenes = ["plate", "spot"]\n'
        'technique = "shadow-map"\nframes = [0, 3]\nlight_path = "orbit-sun"\n',
    )
    exp = load_spec(spec)
    # the orbiting sun needs a directional light: spot is skipped, with the reason
    assert [(c.scene, c.frame, c.light_path) for c in exp.cases] == [
        ("plate", 0, "orbit-sun"),
        ("plate", 3, "orbit-sun"),
    ]
    assert len(exp.skipped) == 1 and "spot" in exp.skipped[0]
    summary = run_sweep(
        exp, tmp_path / "lp.db", cache_root=os.environ["RASTER_ORACLE_CACHE"], workers=0, quiet=True
    )
    assert summary["done"] == 2 and summary["references"] == 4  # 2 frames x (seed, seed + 1)
    rows = list(_rows(tmp_path / "lp.db").values())
    assert {r["path"] for r in rows} == {"orbit-sun"} and {r["frame"] for r in rows} == {0, 3}


def test_store_leaves_one_file_when_the_last_writer_closes(tmp_path):
    """WAL while writing; back to a single file on close, also after read-only opens."""
    db = tmp_path / "s.db"
    first, second = SweepStore(db), SweepStore(db)
    assert (tmp_path / "s.db-wal").exists()
    second.close()  # another connection is still open: it keeps WAL
    assert first.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    first.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.db"]
    with SweepStore(db, readonly=True) as reader:
        assert reader.conn.execute("SELECT count(*) FROM sweep_meta").fetchone()[0] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.db"]


@pytest.mark.parametrize("kind", ["other schema version", "foreign database"])
def test_store_of_another_kind_is_refused_unchanged(tmp_path, capsys, kind):
    """``sweep --db`` on a SQLite file that is not a store of this schema: exit 2 and the file
    byte for byte as it was (it used to be switched to WAL and given the store's tables)."""
    import sqlite3

    db = tmp_path / "other.db"
    conn = sqlite3.connect(db)
    if kind == "other schema version":
        conn.execute("CREATE TABLE sweep_meta (name TEXT PRIMARY KEY, value TEXT)")
        conn.execute("INSERT INTO sweep_meta VALUES ('schema', '999')")
    else:
        conn.execute("CREATE TABLE photos (id INTEGER PRIMARY KEY, blob BLOB)")
    conn.commit()
    conn.close()
    before = db.read_bytes()
    spec = _spec(tmp_path, _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n')
    rc = main(["sweep", str(spec), "--db", str(db), "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "other.db" in err, err
    assert db.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.db", "spec.toml"]


def test_scheduler_without_workers_stops_with_no_workers(tmp_path, capsys):
    """A scheduler whose workers are all gone used to make the sweep wait forever: after
    --worker-timeout it stops with one line, exit 2 (issue 20)."""
    from distributed import LocalCluster

    spec = _spec(tmp_path, _OK + '[[case]]\nscenes = ["plate"]\ntechnique = "csm"\n')
    db = tmp_path / "s.db"
    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        t0 = time.monotonic()
        rc = main(
            [
                "sweep",
                str(spec),
                "--scheduler",
                cluster.scheduler_address,
                "--worker-timeout",
                "1",
                "--db",
                str(db),
                "--out",
                str(tmp_path / "o"),
                "--quiet",
            ]
        )
        waited = time.monotonic() - t0
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert "no workers connected within 1 s" in err, err
    assert waited < 60


def test_cases_left_without_workers_stop_the_wait():
    """The watchdog of a running sweep: pending cases with no worker connected end in a
    SweepError after the timeout instead of a wait that never ends."""
    from distributed import Client, LocalCluster
    from raster_oracle.oracle.sweeps.run import SweepError, completed_while_workers

    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        with Client(cluster) as client:
            fut = client.submit(sum, [1, 2], pure=False)
            with pytest.raises(SweepError, match=r"no workers for 1 s; 1 case\(s\) not run"):
                list(completed_while_workers(client, {fut: None}, worker_timeout=1, where="w"))


def test_progress_in_a_log_is_plain_lines(capsys):
    """Not a terminal (CI logs): no bar redraws, a line per tenth of the cases and the end."""
    from raster_oracle.oracle.sweeps.run import LogProgress, _progress

    bar = _progress(25, quiet=False, desc="sweep x")
    assert isinstance(bar, LogProgress)  # pytest's captured stderr is not a terminal
    with bar:
        for _ in range(25):
            bar.update()
    lines = capsys.readouterr().err.splitlines()
    assert "\r" not in "".join(lines)
    assert 2 <= len(lines) <= 11
    assert lines[-1].startswith("sweep x: 25/25 cases (100%)")
    assert _progress(25, quiet=True, desc="q").disable  # quiet: nothing at all
