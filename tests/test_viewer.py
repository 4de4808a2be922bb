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
    ],
)
def test_factor_is_the_smallest_that_fits_the_budget(shape, n_frames, factor):
    got = V.viewer_factor(*shape, max_pixels=640 * 360, n_frames=n_frames)
    assert got == factor
    budget = 640 * 360 * min(n_frames, V.MAX_FRAME_BUDGETS) / n_frames
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
    assert raw[:2] == np.float16(0.1).astype("<f2").tobytes()  # little-endian, row-major
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


def test_score_report_views_every_frame_with_the_reference_stderr(tmp_path):
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


V_KEYS = ("reference", "candidate", "stderr", "error")
