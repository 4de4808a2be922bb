"""The pixel viewer's data (reports.viewer): budget, packing, reduction, checks, score folder."""

from __future__ import annotations

import base64
import json
import zlib

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.exr import read_exr, write_exr
from raster_oracle.reports import viewer as V

from raster_oracle import reports


def _frame(h=6, w=8, c=3, seed=0):
    rng = np.random.default_rng(seed)
    shape = (h, w, c) if c else (h, w)
    ref = rng.uniform(0, 5, shape).astype(np.float32)
    cand = (ref * 1.5).astype(np.float32)
    return {
        "reference": ref,
        "candidate": cand,
        "stderr": np.full(shape, 0.5, np.float32),
        "error": rng.uniform(-1, 1, (h, w)).astype(np.float32),
    }


def _record(frames, **kw):
    kw.setdefault("error_name", "e")
    kw.setdefault("error_style", "signed")
    kw.setdefault("error_range", (-1, 1))
    return V.viewer_record(frames, **kw)


@pytest.mark.parametrize(
    ("shape", "n_frames", "factor"),
    [
        ((360, 640), 1, 1),
        ((1080, 1920), 1, 3),  # exactly 640 x 360
        ((1081, 1920), 1, 4),  # one row more: 361 x 640 > budget
        ((1080, 1920), 4, 3),  # four frames: four budgets
        ((1080, 1920), 8, 5),  # eight frames share four budgets: 480 x 270 > 115,200
        ((27, 48), 100, 1),
        ((2, 2), 10**7, 2),  # a budget under one pixel a frame still ends: one pixel
    ],
)
def test_factor_is_the_smallest_that_fits_the_budget(shape, n_frames, factor):
    got = V.viewer_factor(*shape, max_pixels=640 * 360, n_frames=n_frames)
    assert got == factor
    budget = max(1, 640 * 360 * min(n_frames, V.MAX_FRAME_BUDGETS) / n_frames)
    assert -(-shape[0] // got) * -(-shape[1] // got) <= min(budget, 640 * 360)
    if got > 1:
        f = got - 1
        assert -(-shape[0] // f) * -(-shape[1] // f) > min(budget, 640 * 360)


def test_arrays_round_trip_as_float16_and_pack_deterministically():
    values = np.array([[0.1, 1.0, -2.5], [1e5, np.nan, 3.14159]], np.float32)
    text = V.encode_array(values)
    assert text == V.encode_array(values.copy())
    back = V.decode_array(text, (2, 3))
    expected = np.clip(values, -65504, 65504).astype(np.float16).astype(np.float32)
    np.testing.assert_array_equal(back, expected)  # NaN == NaN in assert_array_equal
    raw = zlib.decompress(base64.b64decode(text))
    pairs = expected.astype("<f2").reshape(-1).view(np.uint8).reshape(-1, 2)
    assert raw == pairs[:, 0].tobytes() + pairs[:, 1].tobytes()  # low bytes, then high
    with pytest.raises(ValueError, match="holds 6 values, expected 8"):
        V.decode_array(text, (2, 4))
    with pytest.raises(ValueError, match="not float16"):
        V.decode_array("bm90IHpsaWI=", (1,))


def test_reduction_box_mean_stderr_of_the_mean_and_largest_error():
    frame = _frame(h=4, w=4, c=0)
    frame["error"] = np.zeros((4, 4), np.float32)
    frame["error"][1, 2] = -0.75  # one pixel: must survive the reduction
    record = _record([frame], max_pixels=4)  # 4 x 4 into 4 pixels: factor 2
    assert (record["factor"], record["width"], record["height"]) == (2, 2, 2)
    ref = V.decode_array(record["frames"][0]["reference"], (2, 2))
    box = frame["reference"].reshape(2, 2, 2, 2).mean(axis=(1, 3))
    np.testing.assert_allclose(ref, box, rtol=1e-3)
    se = V.decode_array(record["frames"][0]["stderr"], (2, 2))
    np.testing.assert_array_equal(se, 0.25)  # 0.5 / sqrt(4)
    err = V.decode_array(record["frames"][0]["error"], (2, 2))
    np.testing.assert_array_equal(err, [[0, -0.75], [0, 0]])


def test_record_holds_frames_metrics_palette_and_display_settings():
    frames = [_frame(seed=k) for k in range(3)]
    frames[1]["metrics"] = {"flip": 0.25, "ssim": None, "nan": float("nan"), "n": 3}
    frames[2]["stderr"] = None
    record = _record(frames, exposure=-1.5, tone_mapper="aces", srgb=True, error_style="magma")
    assert record["channels"] == 3 and record["exposure"] == -1.5 and record["srgb"] is True
    assert [f["label"] for f in record["frames"]] == ["frame 1", "frame 2", "frame 3"]
    assert record["frames"][0]["metrics"] is None
    assert record["frames"][1]["metrics"] == {"flip": 0.25, "ssim": None, "nan": None, "n": 3.0}
    assert record["frames"][2]["stderr"] is None
    lut = np.frombuffer(base64.b64decode(record["palette"]), np.uint8).reshape(-1, 3)
    np.testing.assert_array_equal(lut, reports.images.palette("magma"))
    json.dumps(record, allow_nan=False)
    assert V.check_viewer("v", record) == record


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f[1].update(candidate=np.zeros((6, 7, 3))), r"frame 1\['candidate'\]"),
        (lambda f: f[0].update(error=np.zeros((6, 8, 3))), r"frame 0\['error'\]"),
        (lambda f: f[0].update(reference=np.zeros((6, 8, 4))), "must be \\(H, W\\) or"),
    ],
)
def test_bad_frames_are_named(change, message):
    frames = [_frame(), _frame()]
    change(frames)
    with pytest.raises(ValueError, match=message):
        _record(frames)


def test_make_case_checks_the_viewer_size_and_read_cases_checks_its_data(tmp_path):
    frame = _frame(c=0)
    kwargs = dict(name="n", scene="s", kind="visibility", metrics={"m": 1.0})
    clip = np.clip(frame["reference"], 0, 1)
    with pytest.raises(ValueError, match="viewer images are 8x6, the case's 8x5"):
        reports.make_case(reference=clip[:5], candidate=clip[:5], viewer=_record([frame]), **kwargs)
    case = reports.make_case(reference=clip, candidate=clip, viewer=_record([frame]), **kwargs)
    plain = reports.make_case(reference=clip, candidate=clip, **kwargs)
    assert plain["viewer"] is None
    report = reports.build_report([case, plain], title="t", provenance={})
    reports.write_report(report, tmp_path / "report.html")
    back = reports.read_cases(tmp_path / "report.json", relative_to=tmp_path)
    assert back[0]["viewer"] == case["viewer"] and back[1]["viewer"] is None
    data = json.loads((tmp_path / "report.json").read_text())
    del data["cases"][1]["viewer"]  # a record from before the viewer: still readable
    data["cases"][0]["viewer"]["frames"][0]["stderr"] = V.encode_array(np.zeros((2, 2)))
    (tmp_path / "report.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"cases\[0\]\['viewer'\]\['frames'\]\[0\]\['stderr'\]"):
        reports.read_cases(tmp_path / "report.json", relative_to=tmp_path)
    html = (tmp_path / "report.html").read_text()
    assert html.count('class="pv"') == 1 and html.count('class="viewer frame"') == 1


def test_score_report_views_every_frame_with_the_reference_stderr(tmp_path, capsys):
    size = ["--width", "24", "--height", "14", "--spp", "4", "--quiet"]
    camera = ["--camera-path", "subpixel-pan", "--frames", "2"]
    for k in range(2):
        out = tmp_path / f"r{k}"
        args = ["reference", "plate", *size, *camera, "--frame", str(k), "--out", str(out)]
        assert main([*args, "--channels", "visibility"]) == 0
        ch = read_exr(out / "reference.exr")
        write_exr(tmp_path / f"c{k}.exr", {"visibility": 1.0 - ch["visibility"]})
    out = tmp_path / "s"
    args = ["score", "plate", *size, *camera, "--candidate", str(tmp_path / "c{frame}.exr")]
    assert main([*args, "--channel", "visibility", "--out", str(out)]) == 0
    viewer = json.loads((out / "report.json").read_text())["cases"][0]["viewer"]
    assert (viewer["factor"], viewer["channels"], len(viewer["frames"])) == (1, 1, 2)
    assert viewer["error"] == {"name": "visibility_error", "style": "signed", "range": [-1, 1]}
    metrics = json.loads((out / "metrics.json").read_text())
    for k, frame in enumerate(viewer["frames"]):
        ch = read_exr(tmp_path / f"r{k}" / "reference.exr")
        half = {key: ch[key].astype(np.float16).astype(np.float32) for key in ch}
        got = {key: V.decode_array(frame[key], (14, 24)) for key in frame if key in V_KEYS}
        np.testing.assert_array_equal(got["reference"], half["visibility"])
        np.testing.assert_array_equal(got["stderr"], half["visibility_stderr"])
        flipped = (1.0 - ch["visibility"]).astype(np.float16).astype(np.float32)
        np.testing.assert_array_equal(got["candidate"], flipped)
        assert frame["metrics"]["misclassified_fraction"] == pytest.approx(
            metrics["frames"][k]["misclassified_fraction"]
        )
    # combining score folders keeps the viewer; a tampered one is exit 2, nothing written
    assert main(["report", str(out), "--out", str(tmp_path / "all" / "r.html")]) == 0
    combined = json.loads((tmp_path / "all" / "r.json").read_text())
    assert combined["cases"][0]["viewer"] == viewer
    data = json.loads((out / "report.json").read_text())
    data["cases"][0]["viewer"]["frames"][1]["error"] = "not base64!"
    (out / "report.json").write_text(json.dumps(data))
    rc = main(["report", str(out), "--out", str(tmp_path / "bad" / "r.html")])
    assert rc == 2 and not (tmp_path / "bad" / "r.html").exists()
    err = capsys.readouterr().err.strip()
    assert "['viewer']['frames'][1]['error']" in err and "\n" not in err


V_KEYS = ("reference", "candidate", "stderr", "error")


def test_shrinking_a_viewer_is_reducing_its_arrays_once_more():
    frame = _frame(h=8, w=12, c=3)
    frame["error"][5, 7] = 0.99
    full = _record([frame])
    direct = _record([frame], max_pixels=24)  # factor 2: 4 x 6
    shrunk = V.shrink_viewer(full, 2)
    assert (shrunk["factor"], shrunk["width"], shrunk["height"]) == (2, 6, 4)
    assert direct["factor"] == 2
    for key, shape in (("reference", (4, 6, 3)), ("stderr", (4, 6, 3)), ("error", (4, 6))):
        a = V.decode_array(shrunk["frames"][0][key], shape)
        b = V.decode_array(direct["frames"][0][key], shape)
        np.testing.assert_allclose(a, b, rtol=2e-3)  # float16 rounding, once more
    assert V.decode_array(shrunk["frames"][0]["error"], (4, 6))[2, 3] == np.float16(0.99)


def test_viewers_of_one_page_share_a_budget():
    viewers = [_record([_frame(h=40, w=60, seed=k)]) for k in range(3)]
    total = sum(map(V.viewer_bytes, viewers))
    assert V.fit_viewers(viewers + [None], max_bytes=total) == viewers + [None]
    fitted = V.fit_viewers(viewers + [None], max_bytes=total // 3)
    assert sum(map(V.viewer_bytes, fitted)) <= total // 3 and fitted[3] is None
    assert {v["factor"] for v in fitted[:3]} == {2}  # about a quarter of the pixels


def test_ten_noisy_colour_cases_with_viewers_stay_under_15_mb(tmp_path):
    rng = np.random.default_rng(1)
    h, w = 540, 960
    cases = []
    for k in range(10):
        ref = rng.gamma(2.0, 0.5, (h, w, 3)).astype(np.float32)
        cand = (ref * rng.uniform(0.8, 1.2, ref.shape)).astype(np.float32)
        frame = {"reference": ref, "candidate": cand, "stderr": 0.1 * ref}
        frame["error"] = np.abs(cand - ref).mean(-1)
        viewer = _record([frame], error_style="magma", error_range=(0, 1), srgb=True)
        shown = np.clip(ref, 0, 1)
        cases.append(
            reports.make_case(
                name=f"c{k}",
                scene="s",
                reference=shown,
                candidate=np.clip(cand, 0, 1),
                kind="color",
                metrics={"m": 1.0},
                viewer=viewer,
            )
        )
    report = reports.build_report(cases, title="size", provenance={})
    assert sum(V.viewer_bytes(c["viewer"]) for c in report["cases"]) <= V.MAX_VIEWER_PAGE_BYTES
    assert report["cases"][0]["viewer"]["factor"] > cases[0]["viewer"]["factor"]
    out = tmp_path / "report.html"
    reports.write_report(report, out)
    assert out.stat().st_size < 15_000_000
    assert f"Reduced 1/{report['cases'][0]['viewer']['factor']}" in out.read_text()


def test_viewer_section_for_pages_without_report_js():
    from raster_oracle.reports._env import environment

    frame = _frame(c=0)
    cases = V.viewer_cases([("row-3", "<b>pcf</b>", _record([frame]))])
    assert [c["id"] for c in cases] == ["row-3"]
    template = environment().get_template("viewer_section.html")
    html = template.render(viewer_cases=cases)
    assert html.count('class="pv"') == 1 and 'data-viewer="row-3"' in html
    assert "&lt;b&gt;pcf&lt;/b&gt;" in html and "DecompressionStream" in html
    assert template.render(viewer_cases=[]).strip() == ""
    with pytest.raises(ValueError, match="unique"):
        V.viewer_cases([("a", "x", _record([frame])), ("a", "y", _record([frame]))])


def test_same_inputs_write_the_same_bytes(tmp_path):
    def write(name: str) -> bytes:
        frames = [_frame(seed=3), _frame(seed=4)]
        frames[0]["metrics"] = {"flip": 0.5}
        viewer = _record(frames, exposure=0.5, tone_mapper="aces", srgb=True)
        clip = np.clip(frames[0]["reference"], 0, 1)
        case = reports.make_case(
            name="n", scene="s", reference=clip, candidate=clip, kind="color",
            metrics={"m": 1.0}, viewer=viewer,
        )  # fmt: skip
        report = reports.build_report([case], title="t", provenance={})
        reports.write_report(report, tmp_path / name)
        return (tmp_path / name).read_bytes() + (tmp_path / name).with_suffix(".json").read_bytes()

    assert write("a.html") == write("b.html")


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("error", "range"), [1, 0], "two increasing numbers"),
        (("error", "range"), "<script>", "a name and a range"),
        (("exposure",), "1", "exposure must be a number"),
        (("palette",), "AAA=", "RGB byte triples"),  # two bytes
        (("frames", 0, "metrics"), {"m": "x"}, "numbers or null"),
        (("frames", 0, "label"), 3, "with a label"),
        (("channels",), 2, "channels must be 1 or 3"),
    ],
)
def test_hostile_viewer_records_are_refused(path, value, message):
    record = json.loads(json.dumps(_record([_frame()])))
    target = record
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    with pytest.raises(ValueError, match=message):
        V.check_viewer("v", record)
