"""A score folder's report.json is untrusted: the combined report embeds only ``data:`` images
and relative links to files inside the score folder; anything else is exit 2, nothing written.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main

from raster_oracle import reports

H, W = 12, 16


def _score_folder(folder):
    """A real score folder's report (report.html + report.json) of a small visibility case."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    reference = (x > W / 2).astype(np.float32)
    candidate = (x > W / 2 - 1).astype(np.float32)
    case = reports.make_case(
        name="case",
        scene="plate",
        reference=reference,
        candidate=candidate,
        kind="visibility",
        metrics={"mae": float(np.mean(np.abs(candidate - reference)))},
        error_maps={"visibility_error": {"data": candidate - reference, "style": "signed"}},
        exr_links={"candidate": "candidate.exr", "maps": "sub/error maps.exr"},
        tile_size=4,
    )
    report = reports.build_report([case], title="t", provenance={"scene": "plate"})
    reports.write_report(report, folder / "report.html")
    return folder / "report.json"


REMOTE = ("https://example.com/x.png", "//example.com/x.png", "javascript:alert(1)")


def _set(path, value):
    def edit(case):
        target = case
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value

    return edit


def _link(path, href=None):
    def edit(case):
        case["exr_links"][0] = {"label": "x", "path": path, "href": href or path}

    return edit


TAMPER = {
    **{f"img src {u}": _set(["images", "reference"], u) for u in REMOTE},
    **{f"candidate {u}": _set(["images", "candidate"], u) for u in REMOTE},
    **{f"error map {u}": _set(["error_maps", 0, "image"], u) for u in REMOTE},
    **{f"worst tile {u}": _set(["worst_tiles", "tiles", 0, "reference"], u) for u in REMOTE},
    "worst tile error crop": _set(["worst_tiles", "tiles", 0, "error"], REMOTE[0]),
    "data URI of html": _set(["images", "reference"], "data:text/html;base64,PHNjcmlwdD4="),
    "data URI with markup": _set(["images", "reference"], 'data:image/png;base64,"><script>'),
    "exr link https": _link("https://example.com/x.exr"),
    "exr link //host": _link("//example.com/x.exr"),
    "exr link javascript": _link("javascript:alert(1)"),
    "exr link javascript quoted": _link("javascript:alert(1)", "javascript%3Aalert%281%29"),
    "exr link href differs from path": _link("candidate.exr", "https://example.com/"),
    "exr link absolute": _link("/etc/passwd"),
    "exr link escapes the folder": _link("../../etc/passwd"),
    "exr link escapes after a folder": _link("sub/../../x.exr"),
    "exr link backslash": _link("..\\x.exr", "..%5Cx.exr"),
}


def _tampered(tmp_path, edit):
    js = _score_folder(tmp_path / "score")
    data = json.loads(js.read_text())
    edit(data["cases"][0])
    js.write_text(json.dumps(data))
    return tmp_path / "score"


@pytest.mark.parametrize("name", list(TAMPER), ids=list(TAMPER))
def test_unsafe_url_in_a_score_folder_is_exit_2(tmp_path, capsys, name):
    folder = _tampered(tmp_path, TAMPER[name])
    out = tmp_path / "all" / "report.html"
    rc = main(["report", str(folder), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.splitlines()) == 1 and err.startswith("raster-oracle: error: "), err
    assert re.search(r"data:image|relative|inside|URL-quoted", err), err
    assert not (tmp_path / "all").exists()


def test_safe_score_folder_combines_with_local_links_only(tmp_path, capsys):
    folder = tmp_path / "score"
    folder.mkdir()
    _score_folder(folder)
    out = tmp_path / "all" / "report.html"
    assert main(["report", str(folder), str(folder), "--out", str(out)]) == 0
    html = out.read_text()
    srcs = re.findall(r'\bsrc="([^"]*)"', html)
    assert srcs and all(s.startswith("data:image/") for s in srcs)
    hrefs = re.findall(r'\bhref="([^"]*)"', html)
    links = [h for h in hrefs if not h.startswith(("#", "data:"))]
    assert sorted(set(links)) == ["../score/candidate.exr", "../score/sub/error%20maps.exr"]


@pytest.mark.parametrize("uri", REMOTE)
def test_render_html_refuses_remote_images(uri):
    y = np.linspace(0, 1, H * W, dtype=np.float32).reshape(H, W)
    case = reports.make_case(
        name="c",
        scene="s",
        reference=y,
        candidate=y,
        kind="visibility",
        metrics={"mae": 0.0},
        error_maps={"e": {"data": y * 0, "style": "signed"}},
        tile_size=4,
    )
    report = reports.build_report([case], title="t", provenance={})
    assert "<html" in reports.render_html(report).lower()
    report["cases"][0]["images"]["candidate"] = uri
    with pytest.raises(ValueError, match="must be a data:image"):
        reports.render_html(report)
    report["cases"][0]["images"]["candidate"] = report["cases"][0]["images"]["reference"]
    report["colorbars"]["signed"] = uri
    with pytest.raises(ValueError, match="must be a data:image"):
        reports.render_html(report)


def test_absolute_exr_link_is_refused_when_rendered():
    y = np.zeros((H, W), dtype=np.float32)
    case = reports.make_case(
        name="c",
        scene="s",
        reference=y,
        candidate=y,
        kind="visibility",
        metrics={"mae": 0.0},
        error_maps={"e": {"data": y, "style": "signed"}},
        exr_links={"x": "//example.com/x.exr"},
        tile_size=4,
    )
    with pytest.raises(ValueError, match="relative link"):
        reports.render_html(reports.build_report([case], title="t", provenance={}))
