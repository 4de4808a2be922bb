"""The sweep report from hand-made rows: fronts, best-at-equal-cost, sensitivity, escaping."""

from __future__ import annotations

import json

import pytest
from raster_oracle.oracle.sweeps.report import family_defaults
from raster_oracle.reports.sections import failed_section
from raster_oracle.reports.sweep import best_at_equal_cost, sweep_record, write_sweep_report

#: The registry's per-family defaults, as the oracle passes them.
FAMILIES = family_defaults()


def _row(i, technique, resolution, cost, error, *, scene="plate", status="done", family="shadow"):
    return {
        "key": f"{i:012x}" + "0" * 52,
        "scene": scene,
        "technique": technique,
        "family": family,
        "params": {"resolution": resolution, "filter": "pcf"},
        "frame": 0,
        "path": None,
        "width": 48,
        "height": 27,
        "spp": 4,
        "metrics": None
        if status != "done"
        else {"misclassified_fraction": error, "visibility_mae": error / 2, "noise_floor": {}},
        "cost": None if status != "done" else {"shadow_map_bytes": cost, "texels_rendered": cost},
        "status": status,
        "error": None if status == "done" else "RuntimeError: boom",
        "wall_seconds": 0.1,
    }


ROWS = [
    _row(1, "shadow-map", 256, 100, 0.30),
    _row(2, "shadow-map", 512, 400, 0.10),
    _row(3, "shadow-map", 1024, 1600, 0.12),  # dominated by row 2 (dearer and worse)
    _row(4, "csm", 256, 400, 0.05),  # dominates row 2 at equal cost
    _row(5, "csm", 512, 1600, 0.02),
    _row(6, "csm", 1024, 6400, 0.02),  # equal error, dearer: dominated by row 5
    _row(7, "sdsm", 2048, 0, 0.0, status="failed"),
    _row(8, "shadow-map", 256, 100, 0.01, scene="city"),
]


def test_fronts_hold_exactly_the_non_dominated_cases():
    rec = sweep_record(ROWS, title="t", families=FAMILIES)
    plate = next(g for g in rec["groups"] if g["scene"] == "plate")
    assert plate["n_cases"] == 7 and plate["n_done"] == 6
    front = next(
        f
        for f in plate["fronts"]
        if f["cost_key"] == "memory_bytes" and f["metric"] == "misclassified_fraction"
    )
    on = sorted(p["case_id"] for p in front["points"] if p["on_front"])
    assert on == sorted(f"case-{i:012x}" for i in (1, 4, 5))
    # the front's indices run by increasing cost
    assert [front["points"][i]["cost"] for i in front["front"]] == [100, 400, 1600]
    # city is its own group: its single case is its front
    city = next(g for g in rec["groups"] if g["scene"] == "city")
    assert city["fronts"][0]["points"][0]["on_front"]


def test_best_at_equal_cost_picks_the_lowest_error_per_technique():
    rows = best_at_equal_cost(
        [
            {"cost": 400, "error": 0.10, "technique": "a", "case_id": "x"},
            {"cost": 400, "error": 0.05, "technique": "b", "case_id": "y"},
            {"cost": 400, "error": 0.07, "technique": "b", "case_id": "z"},
            {"cost": 100, "error": 0.30, "technique": "a", "case_id": "w"},
        ]
    )
    assert [(r["cost_lo"], sorted(r["best"])) for r in rows] == [(100, ["a"]), (400, ["a", "b"])]
    assert rows[1]["best"]["b"]["case_id"] == "y"
    # more distinct costs than table rows: power-of-two bins [2^k, 2^(k+1))
    many = [
        {"cost": c, "error": 1.0 / c, "technique": "a", "case_id": str(c)} for c in range(1, 40)
    ]
    binned = best_at_equal_cost(many)
    assert [(r["cost_lo"], r["cost_hi"]) for r in binned][:3] == [(1, 2), (2, 4), (4, 8)]
    assert binned[-1]["best"]["a"]["cost"] == 39  # lowest error in [32, 64) is the dearest


def test_sensitivity_lists_the_varying_parameter_only():
    rec = sweep_record(ROWS, title="t", families=FAMILIES)
    plate = next(g for g in rec["groups"] if g["scene"] == "plate")
    items = {(s["technique"], s["param"]) for s in plate["sensitivity"]}
    assert items == {("shadow-map", "resolution"), ("csm", "resolution")}
    sm = next(s for s in plate["sensitivity"] if s["technique"] == "shadow-map")
    assert [lv["x"] for lv in sm["levels"]] == [256, 512, 1024]
    assert [lv["mean"] for lv in sm["levels"]] == [0.30, 0.10, 0.12]


def test_page_escapes_text_and_holds_every_section(tmp_path):
    rows = [dict(r) for r in ROWS]
    rows[0]["scene"] = "<script>alert(1)</script>"
    failed = failed_section(
        kind="claims", section_id="claims", title="Claims", error="ValueError: <i>claims broke</i>"
    )
    out = tmp_path / "r.html"
    write_sweep_report(
        rows,
        out,
        title="a <b>title</b>",
        extra_sections=[failed],
        families=FAMILIES,
    )
    html = out.read_text()
    assert "<script>alert(1)</script>" not in html and "&lt;script&gt;" in html
    assert "a &lt;b&gt;title&lt;/b&gt;" in html
    section = html[html.index('<section id="claims"') : html.index('<section id="cases"')]
    assert "<h2>Claims</h2>" in section and "This section failed" in section
    assert "&lt;i&gt;claims broke&lt;/i&gt;" in section and "<i>claims" not in html
    assert "RuntimeError: boom" in html
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["summary"]["n_failed"] == 1
    assert record["sections"] == [failed]
    assert "http://" not in html.replace("http://www.w3.org/2000/svg", "")


def test_front_plot_colours_each_technique_and_fills_the_front():
    import re

    from raster_oracle.reports.sections.sweep import PALETTE, front_svg

    rec = sweep_record(ROWS, title="t", families=FAMILIES)
    plate = next(g for g in rec["groups"] if g["scene"] == "plate")
    front = plate["fronts"][0]
    svg = str(front_svg(front))
    # one linked marker per case, with its values in a <title>; the front's marked on-front
    links = re.findall(r'<a href="#(case-[0-9a-f]+)" class="(point[^"]*)"><title>([^<]*)', svg)
    assert sorted(i for i, _, _ in links) == sorted(p["case_id"] for p in front["points"])
    on = {p["case_id"] for p in front["points"] if p["on_front"]}
    assert {i for i, c, _ in links if c == "point on-front"} == on
    assert all(front["metric"] in tip for _, _, tip in links)
    # shadow-map first (blue), csm second (orange); on-front points filled, others hollow
    marks = re.findall(
        r'<a href="#(case-[0-9a-f]+)"[^>]*><title>[^<]*</title>\s*(?:<g [^>]*>\s*)?<use [^>]*'
        r'style="fill: (#[0-9a-f]+); stroke: (#[0-9a-f]+)',
        svg,
    )
    assert len(marks) == len(front["points"])
    tech = {p["case_id"]: p["technique"] for p in front["points"]}
    for case_id, fill, stroke in marks:
        colour = PALETTE[0] if tech[case_id] == "shadow-map" else PALETTE[1]
        assert stroke == colour and (fill == colour) == (case_id in on)
    assert ">csm</text>" in svg  # the legend


def test_memory_axis_takes_a_techniques_own_memory_or_its_shadow_maps():
    from raster_oracle.reports.sweep import with_memory

    assert with_memory({"shadow_map_bytes": 64})["memory_bytes"] == 64
    assert with_memory({"memory_bytes": 10, "shadow_map_bytes": 64})["memory_bytes"] == 10
    assert "memory_bytes" not in with_memory({"framebuffer_bytes": 8})
    izb = _row(9, "izb", 512, 0, 0.04)
    izb["cost"] = {"memory_bytes": 200}
    rec = sweep_record([*ROWS, izb], title="t", families=FAMILIES)
    plate = next(g for g in rec["groups"] if g["scene"] == "plate")
    front = plate["fronts"][0]
    assert front["cost_key"] == "memory_bytes"
    # 200 bytes at 0.04: dominates nothing it costs more than, and sits on the front
    point = next(p for p in front["points"] if p["technique"] == "izb")
    assert point["cost"] == 200 and point["on_front"]


def test_front_cases_show_their_thumbnails_and_only_data_images(tmp_path):
    png = "data:image/png;base64,iVBORw0KGgo="
    images = {
        ROWS[0]["key"]: {"reference": png, "candidate": png, "error": png},
        ROWS[3]["key"]: {"reference": png, "candidate": "https://example.com/x.png"},
        ROWS[1]["key"]: {"reference": png, "candidate": png, "error": png},  # dominated
    }
    out = tmp_path / "r.html"
    write_sweep_report(ROWS, out, title="t", images=images, families=FAMILIES)
    html = out.read_text()
    gallery = html[html.index('id="gallery"') : html.index('id="sensitivity"')]
    # plate's headline front: rows 1, 4, 5; row 5 has no thumbnails, row 2 is not on it
    # the reference, row 1's image and error map; row 4's link is dropped, it has no error map
    assert gallery.count("<img") == 3
    assert "example.com" not in html
    assert f"#case-{1:012x}" in gallery and f"#case-{2:012x}" not in gallery


# --- stores that are damaged or edited by hand (issue 20) --------------------------------


def _real_store(path, n=40):
    from raster_oracle.oracle.sweeps.store import SweepStore

    png = "data:image/png;base64,iVBORw0KGgo="
    with SweepStore(path) as store:
        for i in range(n):
            row = _row(i + 1, "shadow-map", 256 + i, 100 + i, 0.3 / (i + 1))
            store.put({**row, "sweep": "s", "seed": 0, "run_id": "r"}, images={"error": png})
    return path


def _report(tmp_path, db, capsys):
    from raster_oracle.oracle.cli import main

    out = tmp_path / "r.html"
    rc = main(["report", "--sweep", str(db), "--out", str(out)])
    return rc, capsys.readouterr().err, out


def _sql(db, *statements):
    import sqlite3

    conn = sqlite3.connect(db)
    for s in statements:
        conn.execute(s)
    conn.commit()
    conn.close()


def _damage(kind, db):
    if kind == "no sweep_cases table":
        _sql(db, "DROP TABLE sweep_cases")
    elif kind == "sweep_cases of another shape":
        _sql(db, "DROP TABLE sweep_cases", "CREATE TABLE sweep_cases (key TEXT, other TEXT)")
    elif kind == "truncated to 95%":
        data = db.read_bytes()
        db.write_bytes(data[: len(data) * 95 // 100])
    elif kind == "corrupted pages":
        data = bytearray(db.read_bytes())
        page = 4096
        for start in range(2 * page, len(data) - page, 3 * page):
            data[start + 100 : start + 900] = bytes(range(256)) * 3 + bytes(32)
        db.write_bytes(bytes(data))
    elif kind == "params not JSON":
        _sql(db, "UPDATE sweep_cases SET params = 'not json{' WHERE rowid = 3")
    elif kind == "metrics a JSON list":
        _sql(db, "UPDATE sweep_cases SET metrics = '[1, 2]' WHERE rowid = 3")
    elif kind == "cost of the wrong type":
        _sql(db, "UPDATE sweep_cases SET cost = '\"cheap\"' WHERE rowid = 3")


DAMAGED = [
    "no sweep_cases table",
    "sweep_cases of another shape",
    "truncated to 95%",
    "corrupted pages",
    "params not JSON",
    "metrics a JSON list",
    "cost of the wrong type",
]


@pytest.mark.parametrize("kind", DAMAGED)
def test_damaged_or_edited_store_is_one_line_exit_2(tmp_path, capsys, kind):
    db = _real_store(tmp_path / "s.db")
    _damage(kind, db)
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 2, err
    assert err.count("\n") == 1 and "s.db" in err and "Traceback" not in err, err
    assert not out.exists() and not out.with_suffix(".json").exists()


@pytest.mark.parametrize(
    "stored",
    [
        "X'00ff10'",  # raw bytes
        '\'{"error": "<script>alert(1)</script>"}\'',  # markup
        "'[1, 2, 3]'",  # a JSON list
        '\'{"error": "https://example.com/x.png"}\'',  # a remote image
    ],
)
def test_hand_edited_thumbnails_are_left_out(tmp_path, capsys, stored):
    """Thumbnails are decoration: a bad one is dropped and the report is still written."""
    db = _real_store(tmp_path / "s.db", n=4)
    _sql(db, f"UPDATE sweep_images SET images = {stored}")
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    html = out.read_text()
    assert "<script>alert(1)" not in html and "example.com" not in html
    assert "iVBORw0KGgo=" not in html  # every stored thumbnail was replaced by the bad one


def _aa_row(i, technique, samples, cost, flip, *, floor=0.01):
    row = _row(i, technique, 0, cost, 0.0, scene="decal", family="aa")
    row["params"] = {"samples": samples}
    row["metrics"] = {
        "flip_mean": flip,
        "coverage_edge_rmse": 0.0,  # the backdrop covers every pixel: undefined here
        "noise_floor": {"flip_mean": floor},
    }
    row["cost"] = {"framebuffer_bytes": cost, "shading_events_mean": 1.0 + samples}
    return row


AA_ROWS = [
    _aa_row(20, "noaa", 1, 1000, 0.20),
    _aa_row(21, "fxaa", 1, 1000, 0.15),  # same cost as noaa, better: the level's best
    _aa_row(22, "msaa", 4, 4000, 0.05),
    _aa_row(23, "ssaa", 4, 4000, 0.004),  # within the noise floor (0.01)
    _aa_row(24, "msaa", 8, 8000, 0.06),  # dominated
]


def test_a_metric_undefined_on_a_scene_is_left_out_with_its_reason(tmp_path):
    rec = sweep_record(AA_ROWS, title="t", families=FAMILIES)
    (group,) = rec["groups"]
    assert [o["metric"] for o in group["omitted"]] == ["coverage_edge_rmse"]
    assert "0 for all 5 cases" in group["omitted"][0]["why"]
    assert {f["metric"] for f in group["fronts"]} == {"flip_mean"}
    out = tmp_path / "r.html"
    write_sweep_report(AA_ROWS, out, title="t", families=FAMILIES)
    html = out.read_text()
    assert "coverage_edge_rmse is not plotted: 0 for all 5 cases" in html
    assert 'aria-label="coverage_edge_rmse against' not in html
    assert html.count('<svg class="plot front"') == 2  # flip_mean by each of the two costs


def test_summary_is_the_best_per_cost_level_with_its_noise_floor():
    from raster_oracle.reports.sections.overview import overview_record

    record = sweep_record(AA_ROWS, title="t", families=FAMILIES)
    claims = {
        "kind": "claims",
        "id": "claims",
        "failed": False,
        "data": {"claims": [{"id": "c1", "verdict": "partly", "value_text": "x", "value": None}]},
    }
    record["sections"] = [claims]
    (group,) = overview_record(record)["groups"]
    assert group["anchor"] == "group-aa-decal" and group["metric"] == "flip_mean"
    levels = [(lv["cost"], lv["technique"], lv["error"]) for lv in group["levels"]]
    assert levels == [(1000, "fxaa", 0.15), (4000, "ssaa", 0.004)]
    assert [lv["floors_from_truth"] for lv in group["levels"]] == pytest.approx([15.0, 0.4])
    assert [lv["within_noise"] for lv in group["levels"]] == [False, True]
    assert overview_record(record)["claims"][0]["verdict"] == "partly"


def test_plots_refuse_to_be_empty():
    from raster_oracle.reports import plots

    front = {"family": "x", "cost_key": "memory_bytes", "metric": "m", "front": []}
    with pytest.raises(plots.EmptyPlotError, match="no point"):
        plots.front_plot({**front, "points": [{"cost": 1.0, "error": float("nan")}]})
    item = {"technique": "t", "scene": "s", "param": "p", "metric": "m", "numeric": True}
    with pytest.raises(plots.EmptyPlotError):
        plots.sensitivity_plot({**item, "points": [], "levels": []})
    with pytest.raises(plots.EmptyPlotError):
        plots.loglog_plot([{"name": "a", "x": [1, 2], "y": [0, -1]}], x_label="x", y_label="y")


def test_tick_labels_are_told_apart_and_plots_are_deterministic():
    from raster_oracle.reports import plots

    labels = plots.DistinctFormatter(is_bytes=True).format_ticks([100, 101, 102, 102.5, 2048])
    assert labels == ["100 B", "101 B", "102 B", "102.5 B", "2 KiB"]
    assert plots.DistinctFormatter(is_bytes=False).format_ticks([0.1, 0.10001]) == [
        "0.1",
        "0.10001",
    ]
    rec = sweep_record(ROWS, title="t", families=FAMILIES)
    front = rec["groups"][1]["fronts"][0]
    a = str(plots.front_plot(front, salt="s"))
    assert a == str(plots.front_plot(front, salt="s"))
    assert "<dc:date>" not in a and "<metadata>" not in a
    assert "svg.fonttype" not in a and "<text" in a  # text kept as text, not glyph paths


def test_cases_show_a_metric_defined_on_their_scene():
    rows = [dict(r) for r in AA_ROWS]
    for r in rows:  # coverage_edge_rmse would be the headline if flip_mean were missing
        r["metrics"] = {"coverage_edge_rmse": 0.0, "flip_mean": r["metrics"]["flip_mean"]}
    rec = sweep_record(rows, title="t", families=FAMILIES)
    assert {c["metric"] for c in rec["cases"]} == {"flip_mean"}
    star = [dict(r, scene="star") for r in ROWS[:3]]
    for r in star:  # no shadow on the scene: misclassified is 0 everywhere
        r["metrics"] = {
            "misclassified_fraction": 0.0,
            "visibility_mae": 0.01 * r["cost"]["texels_rendered"] / 100,
        }
    rec = sweep_record(star, title="t", families=FAMILIES)
    assert {c["metric"] for c in rec["cases"]} == {"visibility_mae"}
    assert rec["groups"][0]["omitted"][0]["metric"] == "misclassified_fraction"


# --- pixel viewers of the summary's cases (issue 19) --------------------------------------


def _viewer(value: float, size=(27, 48)) -> dict:
    import numpy as np
    from raster_oracle.reports.viewer import viewer_record

    image = np.full(size, value, dtype=np.float32)
    image[:, size[1] // 2 :] = 1.0 - value  # an edge, so reductions change the data
    return viewer_record(
        [{"reference": image, "candidate": image, "stderr": image * 0.01, "error": image - 0.5}],
        error_name="visibility_error",
        error_style="signed",
        error_range=(-1.0, 1.0),
    )


def _viewer_store(path, rows, viewers):
    from raster_oracle.oracle.sweeps.store import SweepStore

    png = "data:image/png;base64,iVBORw0KGgo="
    with SweepStore(path) as store:
        for row in rows:
            images = {"error": png}
            if row["key"] in viewers:
                images["viewer"] = viewers[row["key"]]
            store.put({**row, "sweep": "s", "seed": 0, "run_id": "r"}, images=images)
    return path


def test_summary_cases_get_viewers_in_summary_order_and_rows_link_to_them(tmp_path, capsys):
    import sqlite3

    viewers = {r["key"]: _viewer(0.1 * i) for i, r in enumerate(ROWS) if r["status"] == "done"}
    db = _viewer_store(tmp_path / "s.db", ROWS, viewers)
    conn = sqlite3.connect(db)
    assert conn.execute("SELECT count(*) FROM sweep_viewers").fetchone()[0] == 7
    # the thumbnails' table holds no viewer (it has a table of its own)
    assert all(
        "viewer" not in json.loads(t) for (t,) in conn.execute("SELECT images FROM sweep_images")
    )
    conn.close()
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    record = json.loads(out.with_suffix(".json").read_text())
    named = [lv["case_id"] for g in record["overview"]["groups"] for lv in g["levels"]]
    # city's single case, then plate's front: rows 1, 4, 5 (not the dominated 2, 3, 6)
    assert named == [f"case-{i:012x}" for i in (8, 1, 4, 5)]
    assert [c["id"] for c in record["inspect"]] == named
    assert all(
        c["factor"] == 1 and (c["width"], c["height"]) == (48, 27) for c in record["inspect"]
    )
    html = out.read_text()
    for case_id in named:
        assert f'href="#{case_id}-inspect"' in html and f'id="{case_id}-inspect"' in html
    assert html.count('class="group pv-case"') == 4 and f"case-{2:012x}-inspect" not in html


def test_viewers_are_fitted_to_the_page_budget(tmp_path):
    from raster_oracle.reports.sections.page import summary_viewer_cases
    from raster_oracle.reports.sweep import sweep_record
    from raster_oracle.reports.viewer import viewer_bytes

    rec = sweep_record(ROWS, title="t", families=FAMILIES)
    viewers = {r["key"]: _viewer(0.1 * i) for i, r in enumerate(ROWS)}
    asked = []

    def lookup(keys):  # only the named cases are read from the store
        asked.extend(keys)
        return {k: viewers[k] for k in keys}

    full = summary_viewer_cases(rec, lookup)
    assert sorted(asked) == sorted(ROWS[i]["key"] for i in (7, 0, 3, 4))
    total = sum(viewer_bytes(c["viewer"]) for c in full)
    fitted = summary_viewer_cases(rec, viewers, max_bytes=total // 3)
    assert sum(viewer_bytes(c["viewer"]) for c in fitted) <= total // 3
    factors = {c["viewer"]["factor"] for c in fitted}
    assert len(factors) == 1 and factors.pop() > 1  # one common further factor
    assert fitted[0]["level"]["scene"] == "city" and fitted[0]["level"]["cost"] == 100


def test_store_without_viewer_table_is_read_and_migrated(tmp_path, capsys):
    """A store written before viewers were kept: read only it has none (the report is still
    written); opened for writing it gains the table and keeps its rows."""
    from raster_oracle.oracle.sweeps.store import SweepStore

    db = _viewer_store(tmp_path / "s.db", ROWS, {ROWS[0]["key"]: _viewer(0.2)})
    _sql(db, "DROP TABLE sweep_viewers")
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    assert json.loads(out.with_suffix(".json").read_text())["inspect"] == []
    assert 'id="inspect"' not in out.read_text()
    with SweepStore(db) as store:
        assert len(store.rows()) == len(ROWS) and store.viewers([ROWS[0]["key"]]) == {}
        store.put(
            {**ROWS[0], "sweep": "s", "seed": 0, "run_id": "r"}, images={"viewer": _viewer(0.3)}
        )
        assert set(store.viewers([r["key"] for r in ROWS])) == {ROWS[0]["key"]}


@pytest.mark.parametrize(
    "stored", ["X'00ff10'", "'[1, 2]'", '\'{"schema": "raster-oracle.viewer/1"}\'', "'{not json'"]
)
def test_hand_edited_viewers_are_left_out(tmp_path, capsys, stored):
    db = _viewer_store(tmp_path / "s.db", ROWS, {r["key"]: _viewer(0.4) for r in ROWS})
    _sql(db, f"UPDATE sweep_viewers SET viewer = {stored} WHERE key = '{ROWS[0]['key']}'")
    rc, err, out = _report(tmp_path, db, capsys)
    assert rc == 0, err
    ids = [c["id"] for c in json.loads(out.with_suffix(".json").read_text())["inspect"]]
    assert ids == [f"case-{i:012x}" for i in (8, 4, 5)]  # row 1's bad viewer is left out


def test_fronts_of_a_higher_is_better_metric_keep_the_highest_values():
    """SSIM: 1 is perfect. Ranked as an error (metrics.catalog via the sweep report's
    metric_error), the cheapest case with the highest SSIM is on the front and the summary's
    best; ranked as a raw value (lower is better) the worst SSIM would be."""
    from raster_oracle.oracle.sweeps.report import metric_error

    rows = [dict(r) for r in ROWS[:3]]
    for r, ssim in zip(rows, (0.80, 0.99, 0.95), strict=True):
        r["metrics"] = {"ssim": ssim, "noise_floor": {"ssim": 0.999}}
    rec = sweep_record(rows, title="t", metrics=["ssim"], rank=metric_error)
    front = rec["groups"][0]["fronts"][0]
    on = {front["points"][i]["error"] for i in front["front"]}
    assert on == {0.80, 0.99}  # 0.95 is dearer and worse than 0.99
    raw = sweep_record(rows, title="t", metrics=["ssim"])["groups"][0]["fronts"][0]
    assert {raw["points"][i]["error"] for i in raw["front"]} == {0.80}
    assert metric_error("psnr_db", 20.0) == pytest.approx(0.01)
    assert metric_error("not_a_metric", 3.0) == 3.0


def test_the_page_does_not_depend_on_the_order_cases_finished_in(tmp_path):
    """On several workers cases finish in a different order each run; the page is made of
    their content in one order (oracle.sweeps.report.canonical_order), so it is the same."""
    from raster_oracle.oracle.sweeps.report import sweep_report
    from raster_oracle.oracle.sweeps.store import SweepStore

    rows = [*ROWS, _row(9, "csm", 2048, 25600, 0.01, scene="city")]
    pages = []
    for name, order in (("a", rows), ("b", rows[::-1])):
        db = tmp_path / name / "sweep.db"
        db.parent.mkdir()
        with SweepStore(db) as store:
            for row in order:  # finished in this order
                store.put({**row, "sweep": "s", "seed": 0, "run_id": "r"})
        out = sweep_report(db, tmp_path / name / "report.html", sweep="s", title="t")
        pages.append(out.read_text().replace(str(db.resolve()), "DB"))
    assert pages[0] == pages[1]
    with SweepStore(tmp_path / "b" / "sweep.db", readonly=True) as store:
        finished = [r["key"] for r in store.rows()]
    assert finished[0] == rows[-1]["key"]  # the store itself keeps the finishing order
