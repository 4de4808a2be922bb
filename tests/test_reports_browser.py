"""The generated report in headless Chromium: interactions, escaping, no console errors.

Needs Playwright for Python and Debian's Chromium at /usr/bin/chromium. Without them the
tests skip, except under CI (the ``CI`` environment variable set), where they fail.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raster_oracle import reports

pytestmark = pytest.mark.browser

REPO_ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS = REPO_ROOT / "test-artifacts"
XSS = "<script>alert(1)</script>"
H, W = 270, 480
#: Planted false-lit region (x0, y0, x1, y1): two 32 px tiles side by side.
PLANTED = (320, 160, 384, 192)
#: Tolerance of on-screen positions, in CSS pixels (sub-pixel layout rounding).
POSITION_TOLERANCE_PX = 1.5


def _cases() -> list[dict]:
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    reference = (np.hypot(x - 140.0, y - 135.0) > 60.0).astype(np.float32)
    candidate = reference.copy()
    x0, y0, x1, y1 = PLANTED
    reference[y0:y1, x0:x1] = 0.0  # the reference is shadowed here, the candidate lit
    error = candidate - reference
    cases = [
        reports.make_case(
            name="planted",
            scene=XSS,
            reference=reference,
            candidate=candidate,
            kind="visibility",
            metrics={"misclassified": float(np.mean(np.abs(error) > 0.5)), "mae": 0.5},
            error_maps={"visibility_error": {"data": error, "style": "signed"}},
            thresholds={"misclassified": 0.001},
            cost={"memory_bytes": 2**22},
            technique="pcf",
            params={"resolution": 1024},
            exr_links={"candidate": "candidate.exr"},
        )
    ]
    rng = np.random.default_rng(0)
    for i, (misclassified, memory) in enumerate([(0.002, 2**24), (0.0005, 2**26)]):
        colour = np.stack([x / W, y / H, 0.5 + 0 * x], axis=-1).astype(np.float32)
        noisy = np.clip(colour + rng.normal(0, 0.02 * (i + 1), colour.shape), 0, 1)
        cases.append(
            reports.make_case(
                name=f"<img src=x onerror=alert(2)> {i}",
                scene="plane",
                reference=colour,
                candidate=noisy.astype(np.float32),
                kind="color",
                metrics={"misclassified": misclassified, "flip": 0.05 * (i + 1)},
                thresholds={"flip": 0.08},
                cost={"memory_bytes": memory},
                technique="pcf",
            )
        )
    return cases


@pytest.fixture(scope="module")
def page_url(tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("report") / "report.html"
    report = reports.build_report(
        _cases(), title="Browser test", provenance={"scene": XSS, "spp": 64, "seed": 1}
    )
    reports.write_report(report, out)
    return out.as_uri()


@pytest.fixture
def page(browser, page_url):
    context = browser.new_context(viewport={"width": 1480, "height": 1000})
    page = context.new_page()
    page.problems = []
    page.dialogs = []
    page.on(
        "console",
        lambda m: page.problems.append(f"console {m.type}: {m.text}") if m.type == "error" else 0,
    )
    page.on("pageerror", lambda e: page.problems.append(f"page error: {e}"))

    def on_dialog(dialog):
        page.dialogs.append(dialog.message)
        dialog.dismiss()

    page.on("dialog", on_dialog)
    page.goto(page_url)
    page.wait_for_load_state("load")
    yield page
    context.close()


def test_page_loads_without_errors_and_shows_script_names_as_text(page):
    body = page.inner_text("body")
    assert XSS in body
    assert "<img src=x onerror=alert(2)> 0" in body
    assert page.locator("text=planted").count() >= 1
    page.wait_for_timeout(200)
    assert page.dialogs == []
    assert page.problems == []
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "report.png"), full_page=True)


def test_ab_toggle_and_space_switch_the_displayed_image(page):
    section = page.locator("#case-1")
    base = section.locator(".viewer .layer-base")
    reference = section.locator('img[data-image="reference"]').get_attribute("src")
    candidate = section.locator('img[data-image="candidate"]').get_attribute("src")
    assert reference != candidate
    assert base.get_attribute("src") == candidate

    section.locator("button.ab-toggle").click()
    assert base.get_attribute("src") == reference
    assert section.locator(".viewer").get_attribute("data-showing") == "reference"
    section.locator("button.ab-toggle").click()
    assert base.get_attribute("src") == candidate

    page.evaluate("document.activeElement && document.activeElement.blur()")
    page.keyboard.down("Space")
    assert base.get_attribute("src") == reference
    page.keyboard.up("Space")
    assert base.get_attribute("src") == candidate
    assert page.problems == []


def test_wipe_slider_moves_the_reference_layer(page):
    section = page.locator("#case-1")
    section.locator("input.wipe").fill("20")
    wipe = section.locator(".viewer").evaluate("v => v.style.getPropertyValue('--wipe')")
    assert wipe == "20%"
    clip = section.locator(".viewer .layer-wipe").evaluate("e => getComputedStyle(e).clipPath")
    assert clip.startswith("inset(")


def test_clicking_a_header_sorts_the_rows(page):
    def names():
        return page.locator("#summary-table tbody tr td:nth-child(2)").all_inner_texts()

    def values():
        return [
            float(v)
            for v in page.locator("#summary-table tbody tr").evaluate_all(
                "rows => rows.map(r => r.cells[5].getAttribute('data-sort'))"
            )
        ]

    original = names()
    header = page.locator("#summary-table thead th", has_text="misclassified")
    header.locator("button").click()
    assert header.get_attribute("aria-sort") == "ascending"
    assert values() == sorted(values())
    assert names() != original
    header.locator("button").click()
    assert header.get_attribute("aria-sort") == "descending"
    assert values() == sorted(values(), reverse=True)
    assert names()[0] == "planted"


def test_zoom_crops_are_the_planted_tiles_and_highlight_them(page):
    section = page.locator("#case-1")
    cards = section.locator(".tile-card")
    assert cards.count() == 2  # only the two tiles of the planted region differ
    x0, y0, x1, y1 = PLANTED
    for i in range(cards.count()):
        card = cards.nth(i)
        x, y = int(card.get_attribute("data-x")), int(card.get_attribute("data-y"))
        w, h = int(card.get_attribute("data-w")), int(card.get_attribute("data-h"))
        assert x0 <= x and x + w <= x1 and y0 <= y and y + h <= y1
        rendering = card.locator("img.crop").first.evaluate(
            "e => getComputedStyle(e).imageRendering"
        )
        assert rendering in {"pixelated", "crisp-edges"}

    first = cards.first
    first.hover()
    frame = section.locator(".figures .frame").first
    hot = frame.locator(".tile-box.hot")
    assert hot.count() == 1
    # Four frames (viewer, reference, candidate, error) highlight the same tile.
    assert section.locator(".tile-box.hot").count() == 4
    box, frame_box = hot.bounding_box(), frame.bounding_box()
    scale = frame_box["width"] / W
    x, y = int(first.get_attribute("data-x")), int(first.get_attribute("data-y"))
    assert abs(box["x"] - frame_box["x"] - x * scale) < POSITION_TOLERANCE_PX
    assert abs(box["y"] - frame_box["y"] - y * scale) < POSITION_TOLERANCE_PX
    assert abs(box["width"] - 32 * scale) < POSITION_TOLERANCE_PX
    page.mouse.move(0, 0)
    assert section.locator(".tile-box.hot").count() == 0


def test_tradeoff_plot_and_exr_link(page):
    plot = page.locator("#tradeoff svg.scatter")
    assert plot.count() == 1
    assert plot.locator("a.point").count() == 3
    assert plot.locator("a.point.on-front").count() == 3  # cheaper is worse, dearer is better
    link = page.locator("#case-1 .exr-links a")
    assert link.get_attribute("href") == "candidate.exr"
    assert page.problems == []
