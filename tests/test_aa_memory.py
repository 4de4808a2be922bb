"""AA framebuffer memory from the models' accounting, against the quoted figures (closed form).

The bytes per pixel follow from the formats: RGBA8 colour 4, D32 depth 4, AGAA's prepass
normal and aggregate record (the model's constants); restated at 1280x736 (942,080 px) and
1920x1080 (2,073,600 px). The slides' AGAA figures (41 / 71 / 112 MB) are checked for what
they can be: not a layout with an 8x 32-bit depth buffer plus equal aggregates.
"""

from __future__ import annotations

import json

import jinja2
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.studies import aa_memory
from raster_oracle.raster_models.aa.agaa import model as agaa

from raster_oracle import scenes

PX_736 = 1280 * 736
PX_1080 = 1920 * 1080
RGBA8 = D32 = 4


@pytest.fixture(scope="module")
def report():
    from raster_oracle.scenes import backend

    backend.select()
    return aa_memory.memory_report()


def _rows(report):
    return {r["label"]: r for r in report["rows"]}


def test_pixel_counts():
    assert PX_736 == 942_080 and PX_1080 == 2_073_600


def test_msaa_rows_are_n_times_colour_plus_depth_plus_resolve(report):
    rows = _rows(report)
    for n in (2, 4, 8, 16):
        r = rows[f"MSAA {n}x"]
        assert r["bytes_per_pixel"]["color"] == n * RGBA8
        assert r["bytes_per_pixel"]["depth"] == n * D32
        assert r["bytes_per_pixel"]["resolve"] == RGBA8
        assert r["framebuffer_bytes_per_pixel"] == n * (RGBA8 + D32)
        at = r["at"]["1280x736"]
        assert at["framebuffer_bytes"] == n * 8 * PX_736
        assert at["total_bytes"] == (n * 8 + 4) * PX_736
        assert r["at"]["1920x1080"]["total_bytes"] == (n * 8 + 4) * PX_1080
    # by hand: 8x RGBA8 + D32 at 1280x736 is 64 B/px = 60,293,120 bytes = 57.5 MiB exactly
    at = rows["MSAA 8x"]["at"]["1280x736"]
    assert at["framebuffer_bytes"] == 60_293_120 and at["framebuffer_MiB"] == 57.5
    assert rows["MSAA 8x"]["at"]["1920x1080"]["framebuffer_bytes"] == 132_710_400


def test_acaa_rows_are_n_depths_plus_one_accumulation_target(report):
    rows = _rows(report)
    assert rows["ACAA 8x (RGBA8 accumulation)"]["bytes_per_pixel"]["total"] == 8 * D32 + 4
    assert rows["ACAA 8x (float accumulation)"]["bytes_per_pixel"]["total"] == 8 * D32 + 16
    assert rows["ACAA 16x (RGBA8 accumulation)"]["bytes_per_pixel"]["total"] == 16 * D32 + 4
    assert rows["ACAA 8x (RGBA8 accumulation)"]["bytes_per_pixel"]["resolve"] == 0


def test_agaa_rows_follow_the_model_formats(report):
    rows = _rows(report)
    nb = agaa.NORMAL_FORMATS[rows["AGAA 8x, 1 aggregate"]["params"]["normal_format"]]
    for n, k in ((8, 1), (8, 2), (16, 2)):
        label = f"AGAA {n}x, {k} aggregate" + ("s" if k > 1 else "")
        per = rows[label]["bytes_per_pixel"]
        assert per["aggregates"] == k * agaa.AGGREGATE_BYTES
        assert per["total"] == n * (D32 + nb) + k * agaa.AGGREGATE_BYTES + RGBA8


def test_deferred_msaa_rows_are_n_times_the_gbuffer_plus_resolve(report):
    """Deferred MSAA: W x H x N x 16 bytes (D32F depth 4, RGB10A2 normal 4, RGBA8
    albedo/specular 4, RGBA8 emissive/material 4) plus the 1x RGBA8 target."""
    rows = _rows(report)
    for n in (4, 8, 16):
        r = rows[f"Deferred MSAA {n}x"]
        per = r["bytes_per_pixel"]
        assert per["depth"] == n * 4 and per["normal"] == n * 4 and per["color"] == n * 8
        assert r["framebuffer_bytes_per_pixel"] == n * 16 and per["resolve"] == RGBA8
        assert r["at"]["1280x736"]["framebuffer_bytes"] == 1280 * 736 * n * 16
        assert r["at"]["1920x1080"]["total_bytes"] == 1920 * 1080 * (n * 16 + 4)
    # by hand: 8x at 1280x736 is 120,586,240 bytes = 115.0 MiB (the slides: 112 MB)
    at = rows["Deferred MSAA 8x"]["at"]["1280x736"]
    assert at["framebuffer_bytes"] == 120_586_240 and at["framebuffer_MiB"] == 115.0
    # forward MSAA stays beside it
    assert rows["MSAA 8x"]["framebuffer_bytes_per_pixel"] == 64


def test_agaa_breakdown_names_the_normal_buffer(report):
    by_k = {b["aggregates"]: b for b in report["agaa_vs_slides"]}
    for k, quoted in ((1, 41.0), (2, 71.0)):
        b = by_k[k]
        assert b["quoted_MB"] == quoted
        assert b["buffers_MB"]["depth"] == pytest.approx(32 * PX_736 / 1e6)
        assert b["buffers_MB"]["normal"] == pytest.approx(32 * PX_736 / 1e6)
        assert b["framebuffer_MB"] == pytest.approx((64 + 20 * k) * PX_736 / 1e6)
        assert b["z_prepass_only_total_MB"] == pytest.approx((32 + 20 * k + 4) * PX_736 / 1e6)
    # the model's 79.1 / 98.0 MB; without the normals K = 2 is 71.6 MB against 71
    assert (
        round(by_k[1]["framebuffer_MB"], 1) == 79.1 and round(by_k[2]["framebuffer_MB"], 1) == 98.0
    )
    assert round(by_k[2]["z_prepass_only_total_MB"], 1) == 71.6


def test_accounting_does_not_depend_on_the_probe_size(report):
    small = scenes.load("star", width=5, height=3)
    configs = [c for c in aa_memory.DEFAULT_CONFIGS if c.technique in ("msaa", "acaa", "agaa")]
    again = aa_memory.memory_table(configs, scene=small)
    rows = _rows(report)
    for r in again:
        assert r["bytes_per_pixel"] == rows[r["label"]]["bytes_per_pixel"], r["label"]


def test_quoted_figures_against_the_accounting(report):
    q = {x["key"]: x for x in report["quoted"]}
    assert set(q) == {x.key for x in aa_memory.QUOTED}
    # ACAA: 36 / 68 = 0.529, "half" at the quote's one significant figure
    assert q["acaa_fraction"]["computed"] == pytest.approx(36 / 68)
    assert q["acaa_fraction"]["reproduced"]
    # AGAA vs deferred MSAA 8x (16-byte G-buffer): 108 / 132 B/px, 18 % less, not 37 %
    assert q["agaa_2a_saving_slides"]["computed"] == pytest.approx(1 - 108 / 132)
    assert not q["agaa_2a_saving_slides"]["reproduced"]
    assert q["agaa_2a_saving_16x"]["computed"] == pytest.approx(1 - 172 / 260)
    assert q["deferred_8x_mb"]["computed"]["framebuffer_MB"] == pytest.approx(128 * PX_736 / 1e6)
    # ... but the slides' own figures agree with each other: 1 - 71 / 112 = 0.366 -> 37 %
    assert q["agaa_2a_saving_slides"]["from_quotes"] == pytest.approx(1 - 71 / 112)
    assert q["agaa_2a_saving_slides"]["consistent_with_quotes"]
    # the byte figures are not reproduced by the accounting, in MB or MiB
    for key in ("agaa_1a_mb", "agaa_2a_mb", "deferred_8x_mb"):
        assert not q[key]["reproduced"], key
    assert q["agaa_1a_mb"]["computed"]["total_MB"] == pytest.approx(88 * PX_736 / 1e6)


def test_slides_agaa_figures_exclude_an_8x_depth_plus_aggregates_layout():
    b = aa_memory.aggregate_layout_bound()
    # one more aggregate: 30 MB over 942,080 px; the base at most 2 * 41.5 - 70.5 = 12.5 MB
    assert b["MB"]["aggregate_bytes_per_pixel"] == pytest.approx(30e6 / PX_736)
    assert b["MB"]["base_bytes_per_pixel_max"] == pytest.approx(12.5e6 / PX_736)
    assert b["MiB"]["base_bytes_per_pixel_max"] == pytest.approx(12.5 * 2**20 / PX_736)
    assert b["depth_buffer_MB"] == pytest.approx(32 * PX_736 / 1e6)
    assert not b["MB"]["feasible"] and not b["MiB"]["feasible"]
    # the same test accepts figures that such a layout can give (base 40 MB >= 30.1 MB depth)
    assert aa_memory.aggregate_layout_bound(60.0, 80.0)["MB"]["feasible"]


def test_cli_writes_the_section(tmp_path, capsys):
    out = tmp_path / "mem"
    assert main(["aa-memory", "--out", str(out)]) == 0
    data = json.loads((out / "aa_memory.json").read_text())
    assert data["schema"] == "raster-oracle.aa-memory/1"
    html = (out / "aa_memory.html").read_text()
    assert "Anti-aliasing framebuffer memory" in html and "41 MB" in html
    assert "MSAA 8x" in capsys.readouterr().out


def test_cli_refuses_an_output_under_a_file(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["aa-memory", "--out", str(blocker / "mem")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("raster-oracle: error:") and "\n" not in err
    assert blocker.read_text() == "x"


def test_study_files_are_written_together_or_not_at_all(tmp_path, report):
    from raster_oracle.oracle.studies.output import write_study
    from raster_oracle.reports.sections import aa_memory_section, claims_section

    out = tmp_path / "mem"
    json_path, html_path = write_study(
        out, name="aa_memory", data=report, section=aa_memory_section(report), title="<t>"
    )
    assert json.loads(json_path.read_text()) == json.loads(json.dumps(report))
    assert "<title>&lt;t&gt;</title>" in html_path.read_text()
    assert sorted(p.name for p in out.iterdir()) == ["aa_memory.html", "aa_memory.json"]
    # a page that cannot be rendered (a claims section of memory data) writes nothing
    bad = tmp_path / "bad"
    with pytest.raises(jinja2.UndefinedError, match="resolution"):
        write_study(bad, name="x", data=report, section=claims_section(report), title="t")
    assert not bad.exists()
    # nor does data that is not standard JSON
    with pytest.raises(ValueError, match="JSON|NaN|nan"):
        aa_memory_section({**report, "formats": float("nan")})
