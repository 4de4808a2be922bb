"""The extremes matrix: every registered model x every extreme, each cell as documented."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.oracle.studies.extremes import run as X
from raster_oracle.reports.sections import extremes_section, render_section

from raster_oracle import raster_models

#: Huge-map size of the test matrix: 1024^2 keeps the module under half a minute on 2 cores
#: (the main job's quick mode runs 4096^2, the CLI's default 16384^2).
TEST_HUGE = 1024

#: Cells that fail for a reason outside this module, each with the reason (strict xfail:
#: the test fails once the cause is fixed, so the entry must then be removed).
#: (msaa x all_sky raised IndexError until raster_models/aa/_trace.py masked the shape
#: gather of missed samples.)
KNOWN_FAILURES: dict[tuple[str, str], str] = {}


@pytest.fixture(scope="module")
def matrix(tmp_path_factory):
    out = tmp_path_factory.mktemp("extremes")
    data = X.run_extremes(out, quick=True, huge=TEST_HUGE)
    return out, data


#: The techniques the study covers: those of families with an extremes scene (not TAA).
STUDIED = [t for t in raster_models.TECHNIQUES if raster_models.family(t).extremes_scene]


def _cells():
    out = []
    for ext in X.EXTREMES:
        for tech in STUDIED:
            marks = ()
            if (tech, ext) in KNOWN_FAILURES:
                marks = pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[(tech, ext)])
            out.append(pytest.param(ext, tech, marks=marks, id=f"{ext}-{tech}"))
    return out


@pytest.mark.parametrize(("extreme", "technique"), _cells())
def test_every_cell_is_as_documented(matrix, extreme, technique):
    _, data = matrix
    cell = next(c for c in data["cells"] if (c["extreme"], c["technique"]) == (extreme, technique))
    assert cell["status"] in ("ok", "n/a", "refused"), cell["message"]
    if cell["status"] == "ok":
        assert cell["finite"] is True
        exp = X.expectation(technique, extreme, cell["family"])
        assert exp.min_error <= cell["error"] <= exp.max_error, (cell["error"], cell["reason"])
    assert cell["outcome_met"], cell
    assert cell["expected"] and cell["reason"]


def test_matrix_files_and_json(matrix):
    out, data = matrix
    assert json.loads((out / "extremes.json").read_text())["cells"] == json.loads(
        json.dumps(data["cells"], allow_nan=False)
    )
    html = (out / "extremes.html").read_text()
    assert "Numerical extremes" in html and html.count("<tr>") == len(X.EXTREMES) + 1
    assert set(data["techniques"]) == set(STUDIED)
    assert len(data["cells"]) == len(X.EXTREMES) * len(STUDIED)


def test_documented_failures_show(matrix):
    """The failures the table documents are measured, not just allowed."""
    _, data = matrix
    cell = {(c["technique"], c["extreme"]): c for c in data["cells"]}
    acne = cell[("csm", "grazing_light")]
    assert acne["detail"]["false_shadow_fraction"] > 0.1  # acne is false shadow
    tiny, base = cell[("shadow-map", "tiny_map")], cell[("shadow-map", "baseline")]
    assert tiny["error"] > 20 * base["error"]
    f32, f64 = cell[("sdsm", "float32_matrices")], cell[("sdsm", "far_1e4")]
    assert f32["error"] > 5 * f64["error"]  # float32 matrices, not the distance
    assert cell[("coherent-shadow-map", "huge_map")]["status"] == "refused"
    for c in data["cells"]:
        if c["extreme"] == "all_sky" and c["status"] == "ok":
            assert c["error"] == 0.0
    # anti-aliasing models on the star: coverage error falls with the sample count
    noaa, ssaa, msaa = (cell[(t, "baseline")]["error"] for t in ("noaa", "ssaa", "msaa"))
    assert noaa > ssaa > msaa > 0
    assert cell[("msaa", "baseline")]["scene"] == "star"


def _raw(name, w=32, h=18):
    import copy

    from raster_oracle.scenes.catalogue.builtin import BUILTIN_SCENES

    return X.EXTREMES[name].transform(copy.deepcopy(BUILTIN_SCENES["plate"].factory(w, h)), w, h)


def test_transformations_closed_form():
    from raster_oracle.scenes.catalogue.builtin import BUILTIN_SCENES

    base = BUILTIN_SCENES["plate"].factory(32, 18)
    far = _raw("far_1e5")
    np.testing.assert_array_equal(
        far["plate"]["vertices"], np.asarray(base["plate"]["vertices"]) + [1e5, 0, 1e5]
    )
    np.testing.assert_array_equal(
        far["camera"]["to_world"][:3, 3], base["camera"]["to_world"][:3, 3] + [1e5, 0, 1e5]
    )
    cam = _raw("far_near_1e6")["camera"]
    assert cam["far_clip"] / cam["near_clip"] == pytest.approx(1e6)
    d = np.asarray(_raw("grazing_light")["sun"]["direction"])
    assert math.degrees(math.asin(-d[1] / np.linalg.norm(d))) == pytest.approx(X.GRAZING_DEG)
    view = _raw("light_parallel_view")
    fwd = view["camera"]["to_world"][:3, 2]
    np.testing.assert_allclose(view["sun"]["direction"], fwd / np.linalg.norm(fwd))
    assert _raw("light_parallel_up")["sun"]["direction"] == [0.0, -1.0, 0.0]
    wall = _raw("camera_in_wall")
    p = wall["camera"]["to_world"][:3, 3]
    v = np.asarray(wall["wall"]["vertices"])
    assert (v.min(axis=0) < p).all() and (p < v.max(axis=0)).all()
    deg = _raw("degenerate_triangles")["plate"]
    verts, faces = np.asarray(deg["vertices"]), np.asarray(deg["faces"])
    assert len(faces) == len(base["plate"]["faces"]) + 4
    extra = verts[faces[-4:]]
    area = np.linalg.norm(np.cross(extra[:, 1] - extra[:, 0], extra[:, 2] - extra[:, 0]), axis=1)
    np.testing.assert_array_equal(area, 0.0)


def test_all_sky_oracle_sees_no_geometry():
    loaded = X.load_extreme(X.EXTREMES["all_sky"], width=16, height=9)
    ref = X.reference_channels(loaded, spp=4, cache=None, quiet=True)
    assert (ref["id"] == -1).all() and (ref["coverage"] == 0).all()
    assert (ref["visibility"] == 1).all()  # sky counts as lit


def test_expectation_lookup_and_default():
    assert X.expectation("csm", "grazing_light").min_error == 0.1
    assert X.expectation("izb", "all_sky").max_error == 0.0  # all_sky comes first
    assert X.expectation("some-future-model", "far_1e5") is X.DEFAULT_EXPECTATION
    assert X.expectation("future-aa", "far_1e5", "aa") is X.DEFAULT_AA_EXPECTATION
    assert X.DEFAULT_EXPECTATION.text("m") == "finite, m <= 0.05"


def test_a_model_registered_later_enters_the_matrix(monkeypatch):
    later = dataclasses.replace(raster_models.TECHNIQUES["shadow-map"], name="later-model")
    monkeypatch.setitem(raster_models.TECHNIQUES, "later-model", later)
    data = X.run_extremes(None, quick=True, extremes=["baseline"], techniques=["later-model"])
    (cell,) = data["cells"]
    assert cell["technique"] == "later-model" and cell["outcome_met"]
    assert cell["reason"] == X.DEFAULT_EXPECTATION.reason


def test_huge_map_refused_when_memory_is_short(monkeypatch):
    monkeypatch.setattr(X, "memory_budget", lambda: 2**28)  # below a 4096^2 map's 0.5 GiB
    data = X.run_extremes(None, quick=True, extremes=["huge_map"], techniques=["shadow-map"])
    (cell,) = data["cells"]
    assert cell["status"] == "refused" and "GiB" in cell["message"] and cell["outcome_met"]


def test_page_escapes_text(matrix):
    _, data = matrix
    evil = dict(data, techniques=[*data["techniques"], "<b>x</b>"], unexpected=["<i>y</i>"])
    html = render_section(extremes_section(evil))
    assert "<b>x</b>" not in html and "&lt;b&gt;x&lt;/b&gt;" in html and "<i>y" not in html


def test_cli_bad_huge(tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["extremes", "--huge", "20000", "--out", str(out)]) == 2
    assert "--huge" in capsys.readouterr().err
    assert not out.exists()


def test_cached_references_give_the_same_cells(tmp_path):
    """The main job passes its reference cache: a second run reads the references back."""
    from raster_oracle.oracle.reference.cache import ReferenceCache

    cache = ReferenceCache(tmp_path / "cache")
    kw = {"quick": True, "extremes": ["far_1e5"], "techniques": ["shadow-map", "msaa"]}
    first = X.run_extremes(None, cache=cache, **kw)
    again = X.run_extremes(None, cache=cache, **kw)
    direct = X.run_extremes(None, cache=None, **kw)
    for a, b, c in zip(first["cells"], again["cells"], direct["cells"], strict=True):
        assert a["error"] == b["error"] == c["error"]
    assert len(list((tmp_path / "cache").rglob("reference.json"))) == 2  # plate and star


def test_same_inputs_same_cells():
    kw = {"quick": True, "extremes": ["tiny_map", "grazing_light"], "techniques": ["sdsm", "ssaa"]}
    a, b = X.run_extremes(None, **kw), X.run_extremes(None, **kw)
    for ca, cb in zip(a["cells"], b["cells"], strict=True):
        assert {k: v for k, v in ca.items() if k != "seconds"} == {
            k: v for k, v in cb.items() if k != "seconds"
        }


def test_cells_are_coloured_by_error_and_a_failed_expectation_is_marked():
    from raster_oracle.reports.sections.extremes import cell_class, cell_mark, cell_style

    def lum(style):
        hexes = style.split("background:#")[1][:6]
        r, g, b = (int(hexes[i : i + 2], 16) for i in (0, 2, 4))
        return 0.2126 * r + 0.7152 * g + 0.0722 * b

    cell = {"status": "ok", "outcome_met": True, "expected_short": "<= 0.05"}
    small, large = {**cell, "error": 0.001}, {**cell, "error": 0.4}
    assert lum(cell_style(small)) > lum(cell_style(large))  # darker is worse, expected or not
    assert cell_class(large) == "met" and cell_mark(large) == "≤ 0.05"
    failed = {**large, "outcome_met": False}
    assert cell_class(failed) == "failed" and cell_mark(failed).startswith("✗")
    assert cell_style(failed) == cell_style(large)  # the colour is the error, not the verdict
    band = {**cell, "error": 0.3, "expected_short": "0.1..0.6"}
    assert cell_mark(band) == "◆ 0.1–0.6"
    assert cell_style({"status": "refused", "error": None}) == ""
