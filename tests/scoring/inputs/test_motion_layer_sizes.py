"""Issue 48: an engine motion layer whose ``.X`` is full size and ``.Y`` sub-sampled by 2
was a ``ValueError: all input arrays must have the same shape`` traceback; now one line
naming the size, exit 2 from the command line."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.scoring.inputs import candidates


def _fake(monkeypatch, channels):
    monkeypatch.setattr(candidates, "read_exr", lambda path: channels)


@pytest.mark.parametrize(
    "channels",
    [
        {"mv.X": np.zeros((12, 16)), "mv.Y": np.zeros((6, 8))},
        {"mv.X": np.zeros((6, 8)), "mv.Y": np.zeros((12, 16))},
        {"mv.X": np.zeros((12, 16)), "mv.Y": np.zeros((12, 16)), "d": np.zeros((6, 8))},
    ],
)
def test_a_sub_sampled_motion_channel_is_one_line(tmp_path, monkeypatch, channels):
    _fake(monkeypatch, channels)
    disocclusion = "d" if "d" in channels else None
    with pytest.raises(
        candidates.CandidateError, match=r"candidate is 8x6, the reference is 16x12"
    ):
        candidates.load_motion(
            tmp_path / "c.exr",
            layer="mv",
            convention="pixels",
            expected_shape=(12, 16),
            disocclusion=disocclusion,
        )


def test_matching_channels_are_read(tmp_path, monkeypatch):
    _fake(monkeypatch, {"mv.X": np.ones((12, 16)), "mv.Y": np.zeros((12, 16))})
    mv, mask = candidates.load_motion(
        tmp_path / "c.exr", layer="mv", convention="pixels", expected_shape=(12, 16)
    )
    assert mv.shape == (12, 16, 2) and mask is None
