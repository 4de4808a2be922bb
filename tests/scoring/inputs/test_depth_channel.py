"""A depth layer is never read as a shadow mask (issue 43, item 8): ``--channel depth`` (or
a file holding only depth) is read as the ``depth`` kind, scored by its relative error, not
"visibility must be in [0, 1]"; the engines' usual depth channels are found."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.exr import write_exr
from raster_oracle.oracle.scoring.inputs.candidates import MissingChannelError
from raster_oracle.oracle.scoring.inputs.layout import candidate_layout, read_candidate


@pytest.mark.parametrize("channel", ["depth", None])
def test_depth_is_read_as_depth_not_as_visibility(tmp_path, channel):
    path = tmp_path / "frame.exr"
    write_exr(path, {"depth": np.full((6, 8), 5.0, np.float32)})
    layout = candidate_layout(str(path), channel=channel)
    assert (layout.kind, layout.names) == ("depth", ("depth",))
    assert float(read_candidate(path, layout, expected_shape=(6, 8)).max()) == 5.0
    write_exr(path, {"shadow.Y": np.ones((6, 8), np.float32), "depth": np.ones((6, 8), np.float32)})
    assert candidate_layout(str(path), channel="shadow").kind == "visibility"


@pytest.mark.parametrize("name", ["Z", "depth.Z", "depth.Y", "view_depth"])
def test_channel_depth_finds_the_engines_depth_names(tmp_path, name):
    path = tmp_path / "frame.exr"
    grey = np.ones((6, 8), np.float32)
    write_exr(path, {name: grey * 3, "shadow.Y": grey, "R": grey, "G": grey, "B": grey})
    layout = candidate_layout(str(path), channel="depth")
    assert (layout.kind, layout.names) == ("depth", (name,))


def test_channel_depth_without_depth_names_what_it_looked_for(tmp_path):
    path = tmp_path / "frame.exr"
    write_exr(path, {"shadow.Y": np.ones((6, 8), np.float32)})
    with pytest.raises(MissingChannelError, match="no depth channel .depth, Z, depth.Z"):
        candidate_layout(str(path), channel="depth")
