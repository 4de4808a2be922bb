"""The display transform in scenes: its own error class, and metrics.tonemap's re-export."""

import numpy as np
import pytest
from raster_oracle.metrics import MetricError
from raster_oracle.metrics import tonemap as metric_tonemap
from raster_oracle.scenes.base import display


def test_display_error_is_a_value_error_naming_the_parameter():
    with pytest.raises(display.DisplayError, match="exposure must be a finite number"):
        display.tonemap(np.ones((2, 2, 3)), exposure=float("inf"))
    assert issubclass(display.DisplayError, ValueError)


def test_metrics_reexport_raises_metric_error_with_the_same_text():
    with pytest.raises(MetricError, match=r"image must be finite, got 1 NaN and 0 inf"):
        metric_tonemap(np.array([[np.nan, 1.0]]), exposure=0.0)


def test_metrics_and_scenes_give_the_same_bytes():
    rng = np.random.default_rng(3)
    img = rng.lognormal(0.0, 1.0, (8, 8, 3)).astype(np.float32)
    e = display.exposure_from_reference(img)
    a = display.tonemap(img, exposure=e)
    b = metric_tonemap(img, exposure=e)
    assert a.tobytes() == b.tobytes()
