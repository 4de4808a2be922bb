"""Unit tests of the report records, their plots and the HTML they render to."""

from __future__ import annotations

import base64
import io
import json
import math
import re

import numpy as np
import pytest
from PIL import Image
from raster_oracle.reports import formatting, images, stats, svg
from raster_oracle.reports.formatting import json_script

from raster_oracle import reports

# Heights/widths of the small synthetic images; tile-aligned planted errors sit at multiples
# of the 32 px tile.
H, W = 192, 320
#: Planted false-shadowed block (x0, y0, x1, y1), exactly one 32 px tile.
PLANTED = (160, 96, 192, 128)
#: The HTML size budget the brief sets for 10 cases at 960 x 540.
SIZE_BUDGET_BYTES = 15_000_000
XSS = "<script>alert(1)</script>"


def _visibility_pair(*, height=H, width=W, seed=0):
    """A lit plane with a soft-edged shadow disc; the candidate adds a planted error block."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    d = np.hypot((x - width * 0.3) / (width * 0.15), (y - height * 0.5) / (height * 0.25))
    reference = np.clip((d - 0.9) / 0.2, 0.0, 1.0).astype(np.float32)
    candidate = (reference > 0.5).astype(np.float32)  # hard-edged approximation
    x0, y0, x1, y1 = PLANTED
    candidate[y0:y1, x0:x1] = 0.0
    return reference, candidate


def _color_pair(*, height=H, width=W, noise=0.03, seed=0):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    reference = np.stack(
        [x / width, y / height, 0.5 + 0.4 * np.sin(x / 17.0) * np.cos(y / 13.0)], axis=-1
    ).astype(np.float32)
    candidate = reference + rng.normal(0.0, noise, reference.shape).astype(np.float32)
    return reference, np.clip(candidate, 0.0, 1.0).astype(np.float32)


def _visibility_case(**overrides):
    reference, candidate = _visibility_pair()
    error = candidate - reference
    kwargs = dict(
        name="pcf 1024",
        scene="plane",
        reference=reference,
        candidate=candidate,
        kind="visibility",
        metrics={"misclassified": float(np.mean(np.abs(error) > 0.5)), "mae": 0.02},
        error_maps={"visibility_error": {"data": error, "style": "signed"}},
        thresholds={"misclassified": 0.01},
        noise_floor={"mae": 0.001},
        cost={"memory_bytes": 4 * 1024 * 1024, "texels_rendered": 1024 * 1024},
        technique="pcf",
        family="shadow maps",
        params={"resolution": 1024, "bias": 0.002},
        exr_links={"candidate": "candidate.exr"},
    )
    kwargs.update(overrides)
    return reports.make_case(**kwargs)


def _decode(uri: str) -> Image.Image:
    header, payload = uri.split(",", 1)
    assert header.startswith("data:image/") and header.endswith(";base64")
    return Image.open(io.BytesIO(base64.b64decode(payload)))


# ---- case records -------------------------------------------------------------------------


def test_case_is_json_serialisable_and_round_trips():
    case = _visibility_case(metrics={"misclassified": 0.5, "psnr": math.inf, "odd": math.nan})
    text = json.dumps(case, allow_nan=False)
    assert json.loads(text) == case
    assert case["metrics"] == {"misclassified": 0.5, "psnr": "inf", "odd": "nan"}
    report = reports.build_report([json.loads(text)], title="t", provenance={"seed": 1})
    assert json.loads(json.dumps(report, allow_nan=False)) == report


def test_case_images_decode_to_thumbnail_size():
    case = _visibility_case()
    for uri in case["images"].values():
        image = _decode(uri)
        assert image.format == "PNG"
        assert image.size == (W, H)
    reference, _ = _visibility_pair()
    decoded = np.asarray(_decode(case["images"]["reference"]), dtype=np.float32) / 255.0
    np.testing.assert_allclose(decoded, reference, atol=0.5 / 255.0 + 1e-6)


def test_color_case_uses_lossy_thumbnails_and_png_crops():
    reference, candidate = _color_pair()
    case = reports.make_case(
        name="msaa 4x",
        scene="plane",
        reference=reference,
        candidate=candidate,
        kind="color",
        metrics={"flip": 0.1},
    )
    assert _decode(case["images"]["candidate"]).format in {"WEBP", "JPEG"}
    assert [m["name"] for m in case["error_maps"]] == ["abs_difference"]
    assert case["status"] == "unchecked"
    for tile in case["worst_tiles"]["tiles"]:
        assert _decode(tile["candidate"]).format == "PNG"
        assert _decode(tile["candidate"]).size == (tile["w"], tile["h"])


def test_worst_tiles_find_the_planted_error():
    case = _visibility_case()
    tiles = case["worst_tiles"]["tiles"]
    assert case["worst_tiles"]["map"] == "visibility_error"
    assert len(tiles) == 4
    x0, y0, x1, y1 = PLANTED
    assert (tiles[0]["x"], tiles[0]["y"], tiles[0]["w"], tiles[0]["h"]) == (x0, y0, 32, 32)
    assert tiles[0]["mean_abs_error"] == pytest.approx(1.0)
    assert [t["rank"] for t in tiles] == [1, 2, 3, 4]
    means = [t["mean_abs_error"] for t in tiles]
    assert means == sorted(means, reverse=True)
    crop = np.asarray(_decode(tiles[0]["candidate"]))
    assert crop.shape == (32, 32) and crop.max() == 0  # the planted block is black


def test_worst_tiles_unaligned_error_and_partial_edge_tiles():
    error = np.zeros((70, 90), dtype=np.float32)
    error[40:50, 20:30] = 0.5  # straddles no tile edge: inside tile (0, 32)
    error[64:70, 80:90] = -1.0  # bottom-right partial tile of 6 x 10 px
    tiles = stats.worst_tiles(error, tile=32, count=4)
    assert [(t["x"], t["y"], t["w"], t["h"]) for t in tiles] == [(64, 64, 26, 6), (0, 32, 32, 32)]
    assert tiles[0]["mean_abs_error"] == pytest.approx(60.0 / (26 * 6))
    assert tiles[1]["mean_abs_error"] == pytest.approx(0.5 * 100 / 1024)


def test_worst_tiles_empty_when_identical():
    reference, _ = _visibility_pair()
    case = reports.make_case(
        name="identical",
        scene="plane",
        reference=reference,
        candidate=reference.copy(),
        kind="visibility",
        metrics={"mae": 0.0},
    )
    assert case["worst_tiles"]["tiles"] == []
    assert '<p class="note">No pixel differs' in reports.render_html(
        reports.build_report([case], title="t", provenance={})
    )


@pytest.mark.parametrize(
    ("style", "data"),
    [
        ("signed", np.linspace(-1.5, 1.5, H * W, dtype=np.float32).reshape(H, W)),
        ("magma", np.random.default_rng(3).random((H, W), dtype=np.float32) * 1.2),
    ],
)
def test_histogram_counts_sum_to_pixel_count(style, data):
    lo, hi = (-1.0, 1.0) if style == "signed" else (0.0, 1.0)
    hist = stats.histogram(data, style=style, value_range=(lo, hi))
    assert sum(hist["counts"]) == hist["total"] == H * W
    assert len(hist["edges"]) == len(hist["counts"]) + 1
    assert hist["below"] == int(np.sum(data < lo))
    assert hist["above"] == int(np.sum(data > hi))


def test_case_histograms_sum_to_pixel_count_and_centre_zero():
    case = _visibility_case()
    hist = case["error_maps"][0]["histogram"]
    assert sum(hist["counts"]) == H * W
    centre = len(hist["counts"]) // 2
    assert hist["edges"][centre] < 0.0 < hist["edges"][centre + 1]
    reference, candidate = _visibility_pair()
    assert hist["counts"][centre] == int(np.sum(np.abs(candidate - reference) < 1 / 51))


def test_signed_heatmap_colours_and_fixed_range():
    data = np.array([[-1.0, 0.0, 1.0, 3.0]], dtype=np.float32)
    rgb = np.asarray(
        _decode(images.encode_heatmap(data, style="signed", value_range=(-1, 1))).convert("RGB")
    )
    assert tuple(rgb[0, 0]) == images.SIGNED_NEGATIVE  # false-shadowed: red
    assert tuple(rgb[0, 1]) == (0, 0, 0)
    assert tuple(rgb[0, 2]) == images.SIGNED_POSITIVE  # false-lit: green
    assert tuple(rgb[0, 3]) == images.SIGNED_POSITIVE  # saturates, range is fixed


def test_magma_heatmap_matches_matplotlib_ends():
    data = np.array([[0.0, 1.0]], dtype=np.float32)
    rgb = np.asarray(
        _decode(images.encode_heatmap(data, style="magma", value_range=(0, 1))).convert("RGB")
    )
    lut = images.palette("magma")
    assert tuple(rgb[0, 0]) == tuple(lut[0]) and tuple(rgb[0, 1]) == tuple(lut[-1])


def test_large_images_are_reduced_and_thin_errors_survive():
    height, width = 1080, 1920
    reference = np.ones((height, width), dtype=np.float32)
    candidate = reference.copy()
    candidate[500, :] = 0.0  # a one-pixel line of false shadow
    case = reports.make_case(
        name="line",
        scene="plane",
        reference=reference,
        candidate=candidate,
        kind="visibility",
        metrics={"mae": float(np.mean(candidate != reference))},
    )
    assert case["thumbnail"]["factor"] == 2
    heat = np.asarray(_decode(case["error_maps"][0]["image"]).convert("RGB"))
    assert heat.shape == (540, 960, 3)
    assert (heat[250, :, 0] == images.SIGNED_NEGATIVE[0]).all()  # max-magnitude pooling
    assert case["worst_tiles"]["tiles"][0]["y"] == 480


def test_reduce_image_averages_srgb_in_linear_light():
    half = np.zeros((2, 2, 3), dtype=np.float32)
    half[0] = 1.0
    mean = images.reduce_image(half, 2, srgb=True)[0, 0, 0]
    assert mean == pytest.approx(0.7353569, abs=1e-5)  # sRGB encoding of linear 0.5


def test_thresholds_min_max_nan_and_noise_floor():
    case = _visibility_case(
        metrics={"a": 0.5, "b": 20.0, "c": math.nan, "d": 0.0005},
        thresholds={"a": 0.4, "b": {"min": 25.0}, "c": 1.0, "d": 0.01},
        noise_floor={"d": 0.001},
    )
    assert case["failing"] == ["a", "b", "c"]
    assert case["status"] == "fail"
    assert case["thresholds"]["a"] == {"max": 0.4}
    assert case["within_noise"] == ["d"]
    assert _visibility_case(metrics={"a": 0.1}, thresholds={"a": 0.4})["status"] == "pass"


@pytest.mark.parametrize(
    ("overrides", "error", "match"),
    [
        ({"kind": "depth"}, ValueError, r"kind must be one of \['visibility', 'color'\]"),
        (
            {"candidate": np.zeros((H, W - 1), np.float32)},
            ValueError,
            r"same shape, got \(192, 320\) and \(192, 319\)",
        ),
        (
            {"candidate": np.full((H, W), np.nan, np.float32)},
            ValueError,
            "candidate must be finite",
        ),
        ({"reference": np.full((H, W), 2.0, np.float32)}, ValueError, r"reference must lie in"),
        ({"reference": np.zeros((H, W), np.uint8)}, TypeError, "float array"),
        ({"reference": np.zeros((H, W, 3), np.float32)}, ValueError, r"shape \(H, W\)"),
        ({"metrics": {}}, ValueError, "at least one metric"),
        ({"metrics": {"a": "x"}}, TypeError, r"metrics\['a'\] must be a number"),
        ({"thresholds": {"nope": 1.0}}, ValueError, r"thresholds\['nope'\] names no metric"),
        (
            {"error_maps": {"e": {"data": np.zeros((H, W), np.float32), "style": "jet"}}},
            ValueError,
            r"style'\] must be one of \['magma', 'signed'\]",
        ),
        (
            {"error_maps": {"e": {"data": np.zeros((2, 2), np.float32), "style": "magma"}}},
            ValueError,
            r"must have shape \(192, 320\), got \(2, 2\)",
        ),
        ({"cost": {"memory_bytes": -math.inf}}, ValueError, "must be a finite number"),
        ({"params": {"f": object()}}, TypeError, "params"),
        ({"tile_size": 0}, ValueError, "tile_size must be a positive integer"),
    ],
)
def test_make_case_validates_inputs(overrides, error, match):
    with pytest.raises(error, match=match):
        _visibility_case(**overrides)


# ---- Pareto front and the report record ---------------------------------------------------


def test_pareto_front_hand_built():
    cost = [1, 2, 3, 4, 5, 2, 6]
    error = [5, 3, 4, 1, 1, 3, 0.5]
    # (3, 4) is dominated by (2, 3); (5, 1) by (4, 1); the duplicate (2, 3) points keep
    # each other on the front; (6, 0.5) is the most accurate.
    expected = [True, True, False, True, False, True, True]
    assert reports.pareto_front(cost, error).tolist() == expected


def test_pareto_front_single_point_and_shape_check():
    assert reports.pareto_front([3.0], [1.0]).tolist() == [True]
    with pytest.raises(ValueError, match="1-D of one length"):
        reports.pareto_front([1.0, 2.0], [1.0])


def test_build_report_tradeoff_per_family():
    points = {"pcf": [(1, 0.3), (4, 0.1), (16, 0.12), (64, 0.01)], "vsm": [(2, 0.2), (8, 0.2)]}
    cases = [
        _visibility_case(
            name=f"{family} {cost}",
            technique=family,
            family=family,
            metrics={"misclassified": err},
            thresholds=None,
            cost={"memory_bytes": cost * 2**20},
        )
        for family, pts in points.items()
        for cost, err in pts
    ]
    report = reports.build_report(cases, title="t", provenance={})
    tradeoff = report["tradeoff"]
    assert (tradeoff["cost_key"], tradeoff["metric"]) == ("memory_bytes", "misclassified")
    families = {f["family"]: f for f in tradeoff["families"]}
    assert [families["pcf"]["points"][i]["name"] for i in families["pcf"]["front"]] == [
        "pcf 1",
        "pcf 4",
        "pcf 64",
    ]
    assert [families["vsm"]["points"][i]["name"] for i in families["vsm"]["front"]] == ["vsm 2"]
    plot = svg.scatter_svg(families["pcf"], cost_key="memory_bytes", metric="misclassified")
    assert plot.count('class="point') == 4 and plot.count('class="point on-front"') == 3
    assert 'class="plot scatter"' in plot and "MiB" in plot


def test_build_report_without_costs_has_no_tradeoff():
    report = reports.build_report([_visibility_case(cost=None)], title="t", provenance={})
    assert report["tradeoff"] is None
    assert 'id="tradeoff"' not in reports.render_html(report)


def test_build_report_summary_and_ids():
    cases = [_visibility_case(), _visibility_case(thresholds={"misclassified": 0.5})]
    report = reports.build_report(cases, title="t", provenance={"versions": {"numpy": "2"}})
    assert [c["id"] for c in report["cases"]] == ["case-1", "case-2"]
    assert "id" not in cases[0]  # inputs are not modified
    assert report["summary"]["n_fail"] == 1 and report["summary"]["n_pass"] == 1
    assert report["summary"]["thresholds"]["misclassified"] == "varies"
    assert report["summary"]["noise_floor"] == {"mae": 0.001}
    assert report["metric_names"] == ["misclassified", "mae"]
    assert report["cost_names"] == ["memory_bytes", "texels_rendered"]


def test_build_report_rejects_foreign_records():
    with pytest.raises(ValueError, match=r"cases\[0\] must be a record from make_case"):
        reports.build_report([{"name": "x"}], title="t", provenance={})
    with pytest.raises(ValueError, match="tradeoff_cost 'nope' is in no case"):
        reports.build_report([_visibility_case()], title="t", provenance={}, tradeoff_cost="nope")


# ---- HTML and files -----------------------------------------------------------------------


def test_html_escapes_every_user_string():
    case = _visibility_case(
        name="<img src=x onerror=alert(2)>",
        scene=XSS,
        technique=XSS,
        params={"note": XSS, XSS: 1},
        metrics={"<b>m</b>": 0.5},
        thresholds={"<b>m</b>": 0.1},
        noise_floor=None,
        exr_links={XSS: "javascript:alert(3)"},
    )
    report = reports.build_report([case], title=XSS, provenance={"scene": XSS})
    html = reports.render_html(report)
    assert XSS not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "<img src=x" not in html and "&lt;img src=x onerror=alert(2)&gt;" in html
    assert "<b>m</b>" not in html
    assert 'href="javascript:' not in html and 'href="javascript%3Aalert%283%29"' in html
    # Only the page's own two script elements close; the JSON block escapes "<".
    assert html.count("</script>") == 2
    data = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', html)
    assert json.loads(data.group(1))["cases"][0]["name"] == "<img src=x onerror=alert(2)>"


def test_json_script_escapes_html_specials():
    text = str(json_script({"a": "</script><!-- & ' \u2028"}))
    assert "<" not in text and ">" not in text and "&" not in text and "'" not in text
    assert json.loads(text) == {"a": "</script><!-- & ' \u2028"}


def test_summary_table_marks_failing_cells_and_sort_keys():
    case = _visibility_case(metrics={"misclassified": 0.5, "psnr": math.inf})
    html = reports.render_html(reports.build_report([case], title="t", provenance={}))
    cell = re.search(r'<td class="num fail" data-sort="0.5"[^>]*>(.*?)</td>', html, re.S)
    assert cell is not None and "✗" in cell.group(1)
    assert 'data-sort="Infinity"' in html and "∞" in html
    assert "≤ 0.01" in html  # thresholds row
    assert "4 MiB" in html and "1,048,576" in html  # costs formatted by the Python filters


def test_write_report_writes_html_and_json_atomically(tmp_path):
    report = reports.build_report([_visibility_case()], title="t", provenance={"seed": 3})
    out = tmp_path / "run" / "report.html"
    reports.write_report(report, out)
    assert json.loads(out.with_suffix(".json").read_text(encoding="utf-8")) == report
    html = out.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and "</html>" in html
    assert sorted(p.name for p in out.parent.iterdir()) == ["report.html", "report.json"]
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)  # nothing remote
    with pytest.raises(ValueError, match="must name the HTML file"):
        reports.write_report(report, tmp_path / "report.json")
    with pytest.raises(ValueError, match="must be a record from build_report"):
        reports.write_report({"cases": []}, out)


def test_read_cases_rebases_exr_links(tmp_path):
    report = reports.build_report([_visibility_case()], title="t", provenance={})
    reports.write_report(report, tmp_path / "a" / "report.html")
    cases = reports.read_cases(tmp_path / "a" / "report.json", relative_to=tmp_path / "all")
    assert cases[0]["exr_links"] == [
        {"label": "candidate", "path": "../a/candidate.exr", "href": "../a/candidate.exr"}
    ]
    combined = reports.build_report(cases + cases, title="all", provenance={})
    assert [c["id"] for c in combined["cases"]] == ["case-1", "case-2"]


def test_formatting_filters():
    assert formatting.fmt_bytes(4 * 2**20) == "4 MiB"
    assert formatting.fmt_cost(1536, "memory_bytes") == "1.5 KiB"
    assert formatting.fmt_cost(1048576, "texels_rendered") == "1,048,576"
    assert formatting.fmt_number(-0.0123456) == "−0.01235"
    assert formatting.fmt_number("inf") == "∞" and formatting.fmt_number(None) == "—"
    assert formatting.fmt_threshold({"min": 25.0}) == "≥ 25"
    assert formatting.flatten({"a": {"b": 1}, "c": 2}) == [("a.b", 1), ("c", 2)]
    assert formatting.sort_key("nan") == "" and formatting.sort_key(0.25) == "0.25"


@pytest.mark.slow
def test_ten_cases_at_960x540_fit_the_size_budget(tmp_path):
    """Worst case: Monte Carlo-like noise everywhere, two error maps per colour case."""
    rng = np.random.default_rng(7)
    cases = []
    for i in range(10):
        if i % 2 == 0:
            reference, candidate = _color_pair(height=540, width=960, noise=0.08, seed=i)
            flip = np.clip(np.abs(candidate - reference).mean(axis=2) * 4.0, 0, 1)
            maps = {
                "flip": {"data": flip.astype(np.float32), "style": "magma"},
                "noise": {"data": rng.random((540, 960), dtype=np.float32), "style": "magma"},
            }
            kind = "color"
        else:
            reference = rng.random((540, 960), dtype=np.float32)
            candidate = rng.random((540, 960), dtype=np.float32)
            maps = {"visibility_error": {"data": candidate - reference, "style": "signed"}}
            kind = "visibility"
        cases.append(
            reports.make_case(
                name=f"case {i}",
                scene="noise",
                reference=reference,
                candidate=candidate,
                kind=kind,
                metrics={"m": float(i)},
                error_maps=maps,
                cost={"memory_bytes": 2**20 * (i + 1)},
                technique="t",
            )
        )
    out = tmp_path / "report.html"
    reports.write_report(reports.build_report(cases, title="size", provenance={}), out)
    assert out.stat().st_size < SIZE_BUDGET_BYTES


def test_empty_report_renders_and_output_is_deterministic():
    empty = reports.build_report([], title="empty", provenance={})
    assert empty["tradeoff"] is None and empty["summary"]["n_cases"] == 0
    assert "0 cases" in reports.render_html(empty)
    first, second = _visibility_case(), _visibility_case()
    assert json.dumps(first) == json.dumps(second)


def _regression(metric: str) -> dict:
    return {
        "name": f"baseline {metric}",
        "kind": "baseline",
        "metric": metric,
        "passed": False,
        "line": f"REGRESSION {metric}",
        "value": 0.2,
        "previous": 0.1,
        "noise_floor": 0.001,
        "previous_noise_floor": 0.001,
    }


def test_first_screen_orders_cases_by_severity_and_groups_regressions_readably():
    """Issue 43 item 8: the "Where" crops of the first screen come worst case first (not in
    case order), and a case's grouped regressions say what they are, not "— / —"."""
    reference, candidate = _visibility_pair()
    mild = candidate.copy()
    mild[96:128, 160:192] = 0.7  # a milder planted error than the severe case's 0
    error = {"visibility_error": {"data": mild - reference, "style": "signed"}}
    checks = [_regression("mae"), _regression("misclassified")]
    cases = [
        _visibility_case(name="mild", candidate=mild, error_maps=error, checks=checks[:1]),
        _visibility_case(name="severe", checks=checks),
    ]
    report = reports.build_report(cases, title="t", provenance={})
    assert [report["cases"][i]["name"] for i in report["summary"]["where_cases"]] == [
        "severe",
        "mild",
    ]
    html = reports.render_html(report)
    first = html.split('id="verdict"')[1].split("</section>")[0]
    where = first[first.index("Where: <a") :]
    assert where.index(">severe<") < where.index(">mild<")
    assert "— / —" not in first
    assert "2 metrics past their baselines" in first
