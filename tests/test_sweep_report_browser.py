"""The main job's report in headless Chromium (issue 19): the summary in the first screen,
readable ticks and data in every plot, sortable and filterable cases, links into collapsed
sections, the pixel viewers of the summary's cases (linked from its rows, zoom without
smoothing, exposure), one self-contained file.

The report comes from a reduced main job (``run_main`` on two scenes at 80x45 px, 4 spp, no
Dask) whose studies are replaced by fixed records (the claims and the extremes take minutes;
their sections are what is rendered here). Needs Playwright and Chromium, as
``test_reports_browser.py``.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

VIEWPORT = {"width": 1400, "height": 900}

CLAIMS = {
    "resolution": [80, 45],
    "reference_spp": 4,
    "counts": {"reproduced": 1, "not reproduced": 1},
    "claims": [
        {
            "id": "claim-one",
            "claim": "it is better",
            "source": "seed",
            "rule": "lower",
            "verdict": "reproduced",
            "value": {"mean": 0.5, "stderr": 0.1, "min": 0.2, "max": 0.8, "n": 4},
            "value_text": "difference",
        },
        {
            "id": "claim-two",
            "claim": "it is cheaper",
            "source": "seed",
            "rule": "cheaper",
            "verdict": "not reproduced",
            "value": None,
            "note": "measured nothing",
        },
    ],
}


def _extremes() -> dict:
    cell = {
        "family": "shadow",
        "metric": "misclassified_fraction",
        "reason": "documented",
        "params": {},
        "finite": True,
        "message": None,
        "seconds": 0.1,
        "detail": {},
        "scene": "plate",
    }
    cells = [
        {**cell, "technique": "pcf", "extreme": "far", "status": "ok", "error": 0.002,
         "expected": "finite, misclassified_fraction <= 0.05", "expected_short": "<= 0.05",
         "outcome_met": True},
        {**cell, "technique": "pcf", "extreme": "tiny", "status": "ok", "error": 0.4,
         "expected": "finite, misclassified_fraction <= 0.05", "expected_short": "<= 0.05",
         "outcome_met": False},
        {**cell, "technique": "vsm", "extreme": "far", "status": "ok", "error": 0.3,
         "expected": "finite, 0.1 <= misclassified_fraction <= 0.6", "expected_short": "0.1..0.6",
         "outcome_met": True},
        {**cell, "technique": "vsm", "extreme": "tiny", "status": "n/a", "error": None,
         "expected": None, "outcome_met": None},
    ]  # fmt: skip
    return {
        "resolution": [80, 45],
        "reference_spp": 4,
        "cell_map": 256,
        "huge_map": 4096,
        "base_scenes": {"shadow": "plate"},
        "extremes": {"far": {"description": "far"}, "tiny": {"description": "tiny"}},
        "techniques": ["pcf", "vsm"],
        "cells": cells,
        "unexpected": ["pcf x tiny"],
    }


@pytest.fixture(scope="module")
def report_path(tmp_path_factory) -> Path:
    from raster_oracle.oracle.reference.cache import ReferenceCache
    from raster_oracle.oracle.sweeps import mainjob
    from raster_oracle.reports.sections import claims_section, extremes_section

    out = tmp_path_factory.mktemp("main")
    sections = (
        mainjob.Section("claims", "claims", "Claims", claims_section, local=lambda out: CLAIMS),
        mainjob.Section(
            "extremes", "extremes", "Extremes", extremes_section, local=lambda out: _extremes()
        ),
    )
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(mainjob, "SECTIONS", sections)
        report, failed = mainjob.run_main(
            ["plate", "decal"],
            out,
            spp=4,
            size=(80, 45),
            workers=0,
            cache=ReferenceCache(out / "cache"),
            quiet=True,
            echo=lambda *a: None,
        )
    assert failed == []
    return report


@pytest.fixture
def page(browser, report_path):
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page.problems = []
    page.on("console", lambda m: page.problems.append(m.text) if m.type == "error" else 0)
    page.on("pageerror", lambda e: page.problems.append(str(e)))
    page.goto(report_path.as_uri())
    page.wait_for_load_state("load")
    yield page
    assert page.problems == []
    context.close()


def _open_all(page) -> None:
    page.evaluate("document.querySelectorAll('details').forEach(d => { d.open = true; })")


def test_summary_is_in_the_first_screen_and_links_down(page, report_path):
    summary = page.locator("#summary")
    box = summary.bounding_box()
    assert box is not None and box["y"] < VIEWPORT["height"]
    first_table = summary.locator("table.mini").first
    assert first_table.bounding_box()["y"] < VIEWPORT["height"]
    assert summary.locator("table.mini tbody tr").count() > 0
    # one line per claim, with its verdict; the extremes' failed cell named
    lines = summary.locator(".claims-line li")
    assert lines.count() == 2
    assert "reproduced" in lines.nth(0).inner_text() and "claim-two" in lines.nth(1).inner_text()
    assert "pcf x tiny" in summary.inner_text()
    # a group's link opens its collapsed detail
    link = summary.locator(".summary-group h3 a").first
    target = link.get_attribute("href")[1:]
    assert not page.locator(f"#{target}").evaluate("d => d.open")
    link.click()
    page.wait_for_function(f"document.getElementById('{target}').open")
    # the page is a few screens until a section is expanded
    height = page.evaluate("document.documentElement.scrollHeight")
    assert height < 8 * VIEWPORT["height"], height
    assert page.evaluate("document.documentElement.scrollWidth") <= VIEWPORT["width"]
    record = json.loads(report_path.with_suffix(".json").read_text())
    groups = [(g["family"], g["scene"]) for g in record["overview"]["groups"]]
    assert groups == [("aa", "decal"), ("shadow", "plate"), ("soft", "plate")]  # pcss: soft


def test_every_plot_has_data_and_no_repeated_tick_labels(page):
    _open_all(page)
    plots = page.locator("svg.plot")
    assert plots.count() >= 4
    for i in range(plots.count()):
        plot = plots.nth(i)
        label = plot.get_attribute("aria-label")
        assert plot.locator("a.point").count() > 0, label
        for axis in ("xtick", "ytick"):
            ticks = [t.strip() for t in plot.locator(f"g.{axis} text").all_text_contents()]
            ticks = [t for t in ticks if t]
            assert len(ticks) >= 2, (label, axis, ticks)
            assert len(ticks) == len(set(ticks)), (label, axis, ticks)
        # each marker says its values on hover and links to its case
        first = plot.locator("a.point").first
        assert first.locator("title").text_content()
        href = first.get_attribute("href")
        assert page.locator(href).count() == 1, href


def test_clicking_a_point_opens_the_cases_and_shows_its_row(page):
    page.locator("#fronts details").first.evaluate("d => { d.open = true; }")
    # a marker no other marker covers (markers of close cases overlap), clicked as a user would
    index = page.evaluate(
        """() => [...document.querySelectorAll('#fronts svg.plot a.point')].findIndex(a => {
            const r = a.getBoundingClientRect();
            if (!r.width || !r.height) return false;
            a.scrollIntoView({block: 'center'});
            const q = a.getBoundingClientRect();
            const hit = document.elementFromPoint(q.x + q.width / 2, q.y + q.height / 2);
            return hit !== null && a.contains(hit);
        })"""
    )
    assert index >= 0
    point = page.locator("#fronts svg.plot a.point").nth(index)
    row_id = point.get_attribute("href")[1:]
    point.click()
    page.wait_for_function("document.getElementById('cases-detail').open")
    row = page.locator(f"tr#{row_id}")
    assert row.is_visible()


def test_cases_table_sorts_and_filters(page):
    page.locator("#cases-detail > summary").click()
    rows = page.locator("#cases-table tbody tr")
    total = rows.count()
    assert total > 4

    def column(index):
        cells = page.locator(f"#cases-table tbody tr:not([hidden]) td:nth-child({index})")
        return [c.get_attribute("data-v") for c in cells.all()]

    page.locator("#cases-table th:nth-child(10) button").click()  # seconds, ascending
    secs = [float(v) for v in column(10)]
    assert secs == sorted(secs)
    page.locator("#cases-table th:nth-child(10) button").click()  # descending
    secs = [float(v) for v in column(10)]
    assert secs == sorted(secs, reverse=True)
    # filters: by scene, then technique, then a parameter
    page.select_option(".filters select[data-filter=scene]", "decal")
    shown = page.locator("#cases-table tbody tr:not([hidden])")
    assert 0 < shown.count() < total
    assert {r.get_attribute("data-scene") for r in shown.all()} == {"decal"}
    page.select_option(".filters select[data-filter=scene]", "")
    page.select_option(".filters select[data-filter=technique]", "shadow-map")
    assert {r.get_attribute("data-technique") for r in shown.all()} == {"shadow-map"}
    page.fill(".filters input[data-filter=params]", "resolution=1024")
    assert shown.count() == 1
    assert "of" in page.locator(".filters [data-count]").inner_text()
    # the parameter column is on screen, not behind a horizontal scrollbar
    box = page.locator("#cases-table th:nth-child(4)").bounding_box()
    assert box["x"] + box["width"] <= VIEWPORT["width"]


def test_extremes_cells_coloured_by_error_and_the_failed_one_stands_out(page):
    page.locator("#extremes details.group > summary").click()
    cells = page.locator("#extremes td.cell:not(.na)")
    shade = {}
    for c in cells.all():
        rgb = c.evaluate("e => getComputedStyle(e).backgroundColor")
        r, g, b = (int(v) for v in re.findall(r"\d+", rgb)[:3])
        shade[float(c.inner_text().split()[0])] = 0.2126 * r + 0.7152 * g + 0.0722 * b
    assert sorted(shade) == [0.002, 0.3, 0.4]
    # a larger error is a darker colour, whether it was expected or not
    assert shade[0.002] > shade[0.3] > shade[0.4]
    failed = page.locator("#extremes td.cell.failed")
    assert failed.count() == 1 and "✗" in failed.inner_text()
    assert failed.evaluate("e => getComputedStyle(e).outlineStyle") == "solid"
    assert "0.4" in failed.get_attribute("title") and "NOT as documented" in failed.get_attribute(
        "title"
    )
    assert page.locator("#extremes .error-legend .tick").count() >= 3


def test_one_self_contained_file(report_path):
    html = report_path.read_text()
    assert report_path.stat().st_size < 15e6
    assert 'id="inspect"' in html and "DecompressionStream" in html  # the viewers are inline
    refs = re.findall(
        r"""<(?:script|link|img|style|iframe)\b[^>]*(?:src|href)=["']([^"']+)""", html
    )
    assert not [r for r in refs if re.match(r"(?i)https?:|//", r)]
    assert "http://" not in html.replace("http://www.w3.org/2000/svg", "")


# ---- the pixel viewers of the summary's cases ------------------------------------------------


def _viewer_data(report_path) -> dict:
    """The page's viewer records by case id (its report-data block)."""
    html = report_path.read_text()
    pattern = r'<script type="application/json" id="report-data">(.*?)</script>'
    block = re.search(pattern, html, re.S)
    assert block, "the page has no viewer data"
    return {c["id"]: c for c in json.loads(block.group(1))["cases"]}


def _array(viewer: dict, key: str) -> np.ndarray:
    from raster_oracle.reports.viewer import decode_array

    h, w, c = viewer["height"], viewer["width"], viewer["channels"]
    shape = (h, w) if c == 1 or key == "error" else (h, w, c)
    return decode_array(viewer["frames"][0][key], shape)


def _canvas(page, case_id: str, source: str):
    return page.locator(
        f'.pv[data-viewer="{case_id}"] .pv-pane[data-source="{source}"] .pv-canvas-box canvas'
    )


def _pixels(page, case_id: str, source: str) -> np.ndarray:
    """The RGB pixels of one view's canvas, (h, w, 3) uint8."""
    w, h, text = _canvas(page, case_id, source).evaluate(
        "c => { const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        " let s = ''; for (let i = 0; i < d.length; i += 8192)"
        " s += String.fromCharCode.apply(null, d.subarray(i, i + 8192));"
        " return [c.width, c.height, btoa(s)]; }"
    )
    return np.frombuffer(base64.b64decode(text), dtype=np.uint8).reshape(h, w, 4)[..., :3]


def _open_viewer(page, case_id: str) -> None:
    """Follow the summary's "view" link of the case and wait for its viewer's data."""
    page.locator(f'#summary a.inspect-link[href="#{case_id}-inspect"]').click()
    page.wait_for_function(f"document.getElementById('{case_id}-inspect').open")
    page.wait_for_selector(f'.pv[data-viewer="{case_id}"][data-ready="1"]')


def test_every_summary_row_links_to_its_cases_viewer(page, report_path):
    record = json.loads(report_path.with_suffix(".json").read_text())
    named = [lv["case_id"] for g in record["overview"]["groups"] for lv in g["levels"]]
    assert named and [c["id"] for c in record["inspect"]] == named
    data = _viewer_data(report_path)
    assert list(data) == named
    rows = page.locator("#summary table.mini tbody tr")
    assert rows.count() == len(named)
    for i, case_id in enumerate(named):
        assert rows.nth(i).locator("a.inspect-link").get_attribute("href") == f"#{case_id}-inspect"
    # the viewers are collapsed until a link opens one (the page stays a few screens long)
    assert not page.locator(f"#{named[-1]}-inspect").evaluate("d => d.open")
    _open_viewer(page, named[-1])
    assert page.locator(f"#{named[-1]}-inspect .pv-pane").first.is_visible()
    key = {c["id"]: c["key"] for c in record["cases"]}[named[-1]]
    assert record["inspect"][-1]["key"] == key
    # the page states which cases have a viewer
    assert "summary names" in page.locator("#inspect > p.note").inner_text()


def test_main_viewer_zooms_without_smoothing_on_an_edge(page, report_path):
    data = _viewer_data(report_path)
    case_id, v = next((k, c["viewer"]) for k, c in data.items() if c["viewer"]["channels"] == 1)
    _open_viewer(page, case_id)
    reference = _array(v, "reference")
    shown = np.round(np.clip(reference, 0.0, 1.0) * 255).astype(int)  # clip, no sRGB
    # a known edge: the largest step between horizontal neighbours of the reference
    steps = np.abs(np.diff(shown, axis=1))
    y, x = np.unravel_index(np.argmax(steps), steps.shape)
    assert steps[y, x] >= 64, "the test scene should hold a shadow edge"
    canvas = _canvas(page, case_id, "reference")
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    page.mouse.move(
        box["x"] + (x + 1) * box["width"] / v["width"],
        box["y"] + (y + 0.5) * box["height"] / v["height"],
    )
    for _ in range(10):
        page.mouse.wheel(0, -100)
    page.mouse.move(0, 0)  # no cursor outline in the views
    zoom = float(page.locator(f'.pv[data-viewer="{case_id}"]').get_attribute("data-zoom"))
    assert zoom > 4  # x9.3, or the deepest zoom (64 CSS px per data pixel) if that is less
    pixels = _pixels(page, case_id, "reference")
    block = pixels.shape[1] / v["width"] * zoom  # canvas pixels per data pixel
    assert block >= 6
    grey = pixels[..., 0].astype(int)
    assert (pixels == pixels[..., :1]).all()  # grey data, grey pixels
    # the edge is in view: both of its values are shown
    assert grey.max() - grey.min() >= 64
    # only the data's values, no intermediate grey of a smoothing filter
    assert set(np.unique(grey)) <= set(np.unique(shown).tolist())
    # in blocks: along a row the colour changes only at block boundaries, one block apart
    changes = np.flatnonzero((np.diff(grey, axis=1) != 0).any(axis=0)) + 1
    assert changes.size
    phase = (changes - changes[0]) / block
    assert np.abs(phase - np.round(phase)).max() * block <= 1.01, (changes, block)


def test_main_viewer_exposure_slider_changes_the_pixels_shown(page, report_path):
    from raster_oracle.metrics.tonemap import tonemap

    data = _viewer_data(report_path)
    case_id, v = next((k, c["viewer"]) for k, c in data.items() if c["viewer"]["channels"] == 3)
    _open_viewer(page, case_id)
    reference = _array(v, "reference")
    h, w = reference.shape[:2]
    y, x = h // 2, w // 2
    before = _pixels(page, case_id, "reference")
    scale = before.shape[1] / w  # fit view: canvas pixels per data pixel

    def centre(pixels):
        return pixels[int((y + 0.5) * scale), int((x + 0.5) * scale)].astype(int)

    def expected(exposure):
        return np.round(tonemap(reference[y : y + 1, x : x + 1], exposure=exposure)[0, 0] * 255)

    assert np.abs(centre(before) - expected(v["exposure"])).max() <= 2
    page.locator(f'.pv[data-viewer="{case_id}"] .pv-exposure').fill(str(v["exposure"] + 2))
    after = _pixels(page, case_id, "reference")
    assert after.mean() > before.mean() + 5
    assert np.abs(centre(after) - expected(v["exposure"] + 2)).max() <= 2
