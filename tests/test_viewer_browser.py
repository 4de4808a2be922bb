"""The score report's pixel viewer in headless Chromium: unsmoothed zoom, exposure, readout,
A/B and wipe, frames (issue 19).

Needs Playwright for Python and Chromium, as ``test_reports_browser.py`` (skips without them,
fails under CI).
"""

from __future__ import annotations

import base64

import numpy as np
import pytest
from raster_oracle.metrics import tonemap

from raster_oracle import reports
from tests.test_reports_browser import ARTIFACTS

pytestmark = pytest.mark.browser

H, W = 27, 48
EXPOSURE = -1.5


def _checker_case() -> dict:
    """Visibility: a 1-pixel checker of 0 and 1 (the candidate inverted in one corner)."""
    y, x = np.mgrid[0:H, 0:W]
    reference = ((x + y) % 2).astype(np.float32)
    candidate = reference.copy()
    candidate[:4, :4] = 1.0 - candidate[:4, :4]
    error = candidate - reference
    viewer = reports.viewer_record(
        [{"reference": reference, "candidate": candidate, "stderr": 0 * reference, "error": error}],
        error_name="visibility_error",
        error_style="signed",
        error_range=(-1, 1),
    )
    return reports.make_case(
        name="checker",
        scene="plane",
        reference=reference,
        candidate=candidate,
        kind="visibility",
        metrics={"misclassified": 16 / (H * W)},
        viewer=viewer,
    )


def _hdr(frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    reference = np.stack([0.25 + 4 * x / W, 0.5 + 2 * y / H, 0.1 + 0 * x + frame], -1)
    candidate = reference * np.float32(1.25)
    stderr = np.full_like(reference, 0.03125)
    return reference.astype(np.float32), candidate.astype(np.float32), stderr


def _hdr_case() -> dict:
    """Colour: linear radiance up to 4.25, two frames (frame 2 brighter in blue)."""
    frames = []
    for k in range(2):
        reference, candidate, stderr = _hdr(k)
        error = np.abs(candidate - reference).mean(-1)
        metrics = {"flip_mean": 0.1 * (k + 1), "ssim": None}
        frames.append(
            {"reference": reference, "candidate": candidate, "stderr": stderr, "error": error}
        )
        frames[-1]["metrics"] = metrics
    viewer = reports.viewer_record(
        frames,
        error_name="flip",
        error_style="magma",
        error_range=(0, 1),
        exposure=EXPOSURE,
        tone_mapper="aces",
        srgb=True,
    )
    reference, candidate, _ = _hdr(0)
    return reports.make_case(
        name="hdr",
        scene="plane",
        reference=tonemap(reference, exposure=EXPOSURE),
        candidate=tonemap(candidate, exposure=EXPOSURE),
        kind="color",
        metrics={"flip_mean": 0.15},
        viewer=viewer,
    )


@pytest.fixture(scope="module")
def page_url(tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("viewer") / "report.html"
    report = reports.build_report([_checker_case(), _hdr_case()], title="Viewer", provenance={})
    reports.write_report(report, out)
    return out.as_uri()


@pytest.fixture
def page(browser, page_url):
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    page.problems = []
    page.on("console", lambda m: page.problems.append(m.text) if m.type == "error" else 0)
    page.on("pageerror", lambda e: page.problems.append(str(e)))
    page.goto(page_url)
    page.wait_for_selector('.pv[data-viewer="case-1"][data-ready="1"]')
    page.wait_for_selector('.pv[data-viewer="case-2"][data-ready="1"]')
    yield page
    assert page.problems == []
    context.close()


def _pixels(page, case: str, source: str) -> np.ndarray:
    """The RGB pixels of one view's canvas, (h, w, 3) uint8."""
    canvas = page.locator(
        f'.pv[data-viewer="{case}"] .pv-pane[data-source="{source}"] .pv-canvas-box canvas'
    )
    w, h, text = canvas.evaluate(
        "c => { const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        " let s = ''; for (let i = 0; i < d.length; i += 8192)"
        " s += String.fromCharCode.apply(null, d.subarray(i, i + 8192));"
        " return [c.width, c.height, btoa(s)]; }"
    )
    flat = np.frombuffer(base64.b64decode(text), dtype=np.uint8)
    return flat.reshape(h, w, 4)[..., :3]


def _colours(pixels: np.ndarray) -> set[tuple[int, ...]]:
    return {tuple(int(c) for c in p) for p in pixels.reshape(-1, 3)}


def _hover_pixel(page, case: str, source: str, x: int, y: int, width: int, height: int) -> None:
    canvas = page.locator(
        f'.pv[data-viewer="{case}"] .pv-pane[data-source="{source}"] .pv-canvas-box canvas'
    )
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    page.mouse.move(
        box["x"] + (x + 0.5) * box["width"] / width, box["y"] + (y + 0.5) * box["height"] / height
    )


def test_zoom_shows_unsmoothed_blocks_of_exactly_two_colours(page):
    viewer = page.locator('.pv[data-viewer="case-1"]')
    for _ in range(3):
        viewer.locator(".pv-zoom-in").click()
    zoom = float(viewer.get_attribute("data-zoom"))
    assert zoom > 7.5  # x8, or the deepest zoom (64 CSS px per data pixel) if that is less
    for source in ("reference", "compare"):
        pixels = _pixels(page, "case-1", source)
        # the wipe line of the compare view aside, a zoomed view holds only the two data
        # colours: nearest neighbour, no intermediate grey of a smoothing filter
        if source == "compare":
            pixels = pixels[:, : pixels.shape[1] // 2 - 2]
        assert _colours(pixels) == {(0, 0, 0), (255, 255, 255)}
        # every data pixel is a block of (canvas width / 48) x zoom canvas pixels
        row = pixels[pixels.shape[0] // 2, :, 0]
        runs = np.diff(np.flatnonzero(np.diff(row.astype(int)) != 0))
        block = _pixels(page, "case-1", "reference").shape[1] / W * zoom
        assert len(runs) >= 2 and np.abs(runs - block).max() <= 1.0
    rendering = viewer.locator("canvas").first.evaluate("c => getComputedStyle(c).imageRendering")
    assert rendering == "pixelated"
    ARTIFACTS.mkdir(exist_ok=True)
    viewer.screenshot(path=str(ARTIFACTS / "viewer-zoom.png"))


def test_fit_view_of_the_checker_has_no_smoothing_either(page):
    # Fit is 8 CSS px per pixel: nearest neighbour still gives only black and white (once the
    # worst tile's outline, yellow, is switched off).
    viewer = page.locator('.pv[data-viewer="case-1"]')
    assert (250, 204, 21) in _colours(_pixels(page, "case-1", "reference"))  # #facc15
    viewer.locator(".pv-tiles").uncheck()
    assert _colours(_pixels(page, "case-1", "reference")) == {(0, 0, 0), (255, 255, 255)}


def test_keyboard_zooms_pans_and_fits(page):
    viewer = page.locator('.pv[data-viewer="case-1"]')
    canvas = viewer.locator('.pv-pane[data-source="reference"] .pv-canvas-box canvas')
    canvas.focus()
    page.keyboard.press("+")
    page.keyboard.press("+")
    assert float(viewer.get_attribute("data-zoom")) == 4.0
    before = _pixels(page, "case-1", "reference")
    page.keyboard.press("ArrowLeft")
    assert not np.array_equal(_pixels(page, "case-1", "reference"), before)
    page.keyboard.press("-")
    assert float(viewer.get_attribute("data-zoom")) == 2.0
    page.keyboard.press("0")
    assert float(viewer.get_attribute("data-zoom")) == 1.0


def test_zoom_and_pan_are_shared_by_every_view(page):
    viewer = page.locator('.pv[data-viewer="case-1"]')
    viewer.locator(".pv-zoom-in").click()
    viewer.locator(".pv-zoom-in").click()
    reference = _pixels(page, "case-1", "reference")
    candidate = _pixels(page, "case-1", "candidate")
    assert np.array_equal(reference, candidate)  # the candidate differs only in a corner
    canvas = viewer.locator('.pv-pane[data-source="error"] .pv-canvas-box canvas')
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 3 * box["width"], cy + 3 * box["height"], steps=4)  # past the corner
    page.mouse.up()
    page.mouse.move(0, 0)
    # panned to the top-left corner, where the candidate is inverted: now they differ
    assert not np.array_equal(_pixels(page, "case-1", "reference"), reference)
    reference = _pixels(page, "case-1", "reference")
    candidate = _pixels(page, "case-1", "candidate")
    assert (reference[:20, :20] != candidate[:20, :20]).all()


def test_exposure_slider_applies_the_documented_tone_mapper(page):
    viewer = page.locator('.pv[data-viewer="case-2"]')
    x, y = 30, 10
    reference, _, _ = _hdr(0)
    value = reference[y, x].astype(np.float16).astype(np.float32)  # what the page holds

    def shown() -> np.ndarray:
        pixels = _pixels(page, "case-2", "reference")
        h, w = pixels.shape[:2]
        return pixels[int((y + 0.5) * h / H), int((x + 0.5) * w / W)].astype(int)

    def expected(exposure: float) -> np.ndarray:
        encoded = tonemap(value[None, None], exposure=exposure, method="aces")[0, 0]
        return np.round(encoded * 255).astype(int)

    before = shown()
    assert np.abs(before - expected(EXPOSURE)).max() <= 1
    viewer.locator(".pv-exposure").fill("1")
    assert viewer.locator(".pv-exposure-value").inner_text() == "+1.00"
    after = shown()
    assert np.abs(after - expected(1.0)).max() <= 1
    assert (after > before + 20).all()  # 2.5 stops brighter: visibly different pixels
    viewer.locator(".pv-exposure-reset").click()
    assert np.array_equal(shown(), before)


def test_readout_shows_the_linear_values_of_the_pixel_under_the_cursor(page):
    x, y = 30, 10
    reference, candidate, stderr = _hdr(0)
    _hover_pixel(page, "case-2", "candidate", x, y, W, H)
    viewer = page.locator('.pv[data-viewer="case-2"]')
    assert viewer.locator(".pv-xy").inner_text() == f"x {x}, y {y}"

    def cell(field: str) -> str:
        return viewer.locator(f'.pv-val[data-field="{field}"]').inner_text()

    def text(values) -> str:
        return ", ".join(f"{float(np.float16(v)):.4g}" for v in np.atleast_1d(values))

    assert cell("reference") == text(reference[y, x])
    assert cell("candidate") == text(candidate[y, x])
    assert cell("stderr") == text(stderr[y, x]) == "0.03125, 0.03125, 0.03125"
    error = np.abs(candidate - reference).mean(-1)[y, x]
    assert cell("error") == text(error)
    page.mouse.move(0, 0)
    assert cell("reference") == "—"


def test_ab_toggle_and_wipe_in_the_viewer(page):
    viewer = page.locator('.pv[data-viewer="case-1"]')
    for _ in range(2):
        viewer.locator(".pv-zoom-in").click()
    page.mouse.move(0, 0)
    viewer.locator(".pv-wipe").fill("100")
    reference = _pixels(page, "case-1", "reference")
    candidate = _pixels(page, "case-1", "candidate")
    main = viewer.locator(".pv-main")
    w = reference.shape[1]
    assert np.array_equal(_pixels(page, "case-1", "compare")[:, : w - 2], reference[:, : w - 2])
    viewer.locator(".pv-wipe").fill("0")
    assert np.array_equal(_pixels(page, "case-1", "compare")[:, 2:], candidate[:, 2:])
    viewer.locator(".pv-ab").click()
    assert main.get_attribute("data-showing") == "reference"
    assert np.array_equal(_pixels(page, "case-1", "compare"), reference)
    viewer.locator(".pv-ab").click()
    assert main.get_attribute("data-showing") == "candidate"
    page.evaluate("document.activeElement && document.activeElement.blur()")
    page.keyboard.down("Space")
    assert main.get_attribute("data-showing") == "reference"
    page.keyboard.up("Space")
    assert main.get_attribute("data-showing") == "candidate"


def test_frame_selector_shows_each_frame_and_its_metrics(page):
    viewer = page.locator('.pv[data-viewer="case-2"]')
    assert "flip_mean 0.1" in viewer.locator(".pv-frame-metrics").inner_text()
    x, y = 5, 5
    _hover_pixel(page, "case-2", "reference", x, y, W, H)
    blue = viewer.locator('.pv-val[data-field="reference"]').inner_text().split(", ")[2]
    assert blue == "0.09998"  # 0.1 as float16
    viewer.locator(".pv-frame").fill("1")
    page.wait_for_function(
        "() => document.querySelector('.pv[data-viewer=\"case-2\"] .pv-frame-metrics')"
        ".textContent.includes('frame 2')"
    )
    assert "flip_mean 0.2" in viewer.locator(".pv-frame-metrics").inner_text()
    _hover_pixel(page, "case-2", "reference", x, y, W, H)
    blue = viewer.locator('.pv-val[data-field="reference"]').inner_text().split(", ")[2]
    assert blue == "1.1"
    viewer.locator("details.pv-frames-table summary").click()
    rows = viewer.locator("table.pv-frames tbody tr")
    assert rows.count() == 2 and rows.nth(1).get_attribute("class") == "current"
    assert rows.nth(0).locator("td").nth(1).inner_text() == "0.1"  # flip_mean of frame 1
    assert rows.nth(0).locator("td").nth(2).inner_text() == "—"  # ssim: None, tolerated
    rows.nth(0).locator(".pv-link").click()
    assert viewer.locator(".pv-frame").input_value() == "0"
    page.wait_for_function(
        "() => document.querySelector('.pv[data-viewer=\"case-2\"] .pv-frame-metrics')"
        ".textContent.includes('frame 1')"
    )
