"""A depth layer is never read as a shadow mask (issue 43, item 8): ``--channel depth`` (or
a file holding only depth) is one line naming the channel, not "visibility must be in
[0, 1]"."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.exr import write_exr
from raster_oracle.oracle.scoring.inputs.candidates import CandidateError
from raster_oracle.oracle.scoring.inputs.layout import candidate_layout


@pytest.mark.parametrize("channel", ["depth", None])
def test_depth_is_named_not_read_as_visibility(tmp_path, channel):
    path = tmp_path / "frame.exr"
    write_exr(path, {"depth": np.full((6, 8), 5.0, np.float32)})
    with pytest.raises(CandidateError, match="channel 'depth' holds depth, not a shadow mask"):
        candidate_layout(str(path), channel=channel)
    write_exr(path, {"shadow.Y": np.ones((6, 8), np.float32), "depth": np.ones((6, 8), np.float32)})
    assert candidate_layout(str(path), channel="shadow").kind == "visibility"
