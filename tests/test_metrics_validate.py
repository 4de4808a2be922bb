"""NaN / inf / empty / shape sweep over every public metric: one clear MetricError each."""

import numpy as np
import pytest
from raster_oracle.metrics import MetricError
from raster_oracle.metrics.validate import check_images

from raster_oracle import metrics

H, W = 16, 16
REC = np.ones((H, W), bool)


def _frames(image):
    """A 2-frame sequence: ``image`` then a clean copy (so bad values are counted once)."""
    return np.stack([image, np.full_like(image, 0.5)])


def _pair_metrics():
    """(name, call(reference, candidate)) for every metric of two same-shaped images."""
    return [
        ("flip", lambda a, b: metrics.flip(a, b)),
        ("flip_hdr", lambda a, b: metrics.flip(a, b, mode="HDR")),
        ("ssim", lambda a, b: metrics.ssim(a, b)),
        ("psnr_db", lambda a, b: metrics.psnr_db(a, b)),
        ("delta_e2000", lambda a, b: metrics.delta_e2000(a, b)),
        ("shadow", lambda a, b: metrics.shadow_metrics(a, b, receivers=REC)),
        ("edge_interior", lambda a, b: metrics.edge_interior_error(a, b, edge_mask=REC)),
        ("coverage", lambda a, b: metrics.coverage_error(a, b)),
        ("z_test", lambda a, b: metrics.z_test(a, np.full(a.shape, 0.1), b)),
        ("flicker", lambda a, b: metrics.flicker(_frames(a), _frames(b))),
        ("temporal", lambda a, b: metrics.temporal_error(_frames(a), _frames(b))),
    ]


PAIR_METRICS = _pair_metrics()
IDS = [name for name, _ in PAIR_METRICS]


def _image():
    return np.full((H, W), 0.5, np.float32)


@pytest.mark.parametrize("call", [c for _, c in PAIR_METRICS], ids=IDS)
@pytest.mark.parametrize(
    ("bad", "what"), [(np.nan, "1 NaN and 0 inf"), (np.inf, "0 NaN and 1 inf")]
)
def test_non_finite_candidate(call, bad, what):
    cand = _image()
    cand[3, 4] = bad
    with pytest.raises(MetricError, match=f"candidate\\w* must be finite, got {what}"):
        call(_image(), cand)


@pytest.mark.parametrize("call", [c for _, c in PAIR_METRICS], ids=IDS)
def test_non_finite_reference(call):
    ref = _image()
    ref[0, 0] = -np.inf
    ref[1, 1] = np.nan
    with pytest.raises(MetricError, match=r"reference\w* must be finite, got 1 NaN and 1 inf"):
        call(ref, _image())


@pytest.mark.parametrize("call", [c for _, c in PAIR_METRICS], ids=IDS)
def test_shape_mismatch(call):
    ref = _image()
    with pytest.raises(MetricError, match=r"must have the same shape, got \(.*16\) and \(.*15\)"):
        call(ref, ref[:, :15])


@pytest.mark.parametrize("call", [c for _, c in PAIR_METRICS], ids=IDS)
def test_empty(call):
    empty = np.zeros((0, W), np.float32)
    with pytest.raises(MetricError, match=r"must (not be empty|have shape)"):
        call(empty, empty)


def test_message_format_is_exact():
    with pytest.raises(MetricError) as info:
        check_images("reference", np.zeros((64, 96)), "candidate", np.zeros((64, 95)))
    assert str(info.value) == (
        "reference and candidate must have the same shape, got (64, 96) and (64, 95)"
    )


def test_non_numeric_and_wrong_ndim():
    with pytest.raises(MetricError, match="candidate must be a real numeric array, got dtype"):
        metrics.ssim(np.zeros((16, 16)), np.full((16, 16), "x"))
    with pytest.raises(
        MetricError, match=r"reference must be a 2-D or 3-D array, got shape \(4,\)"
    ):
        metrics.psnr_db(np.zeros(4), np.zeros(4))


def test_metric_error_is_a_value_error():
    assert issubclass(MetricError, ValueError)
    assert set(metrics.__all__) <= set(dir(metrics))
