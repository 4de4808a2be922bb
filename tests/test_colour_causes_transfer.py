"""A transfer-curve cause names what fixes it (issue 43 item 8): ``--transfer`` for an 8-bit
file, "write linear radiance" for a linear file such as an EXR (which takes no --transfer,
so following the old advice exited 2)."""

from __future__ import annotations

import numpy as np
from raster_oracle.metrics.colour_causes import colour_causes
from raster_oracle.metrics.tonemap import srgb_decode

RNG = np.random.default_rng(43)


def _scene():
    ref = RNG.uniform(0.05, 0.9, (24, 32, 3))
    ids = np.zeros((24, 32), dtype=np.int32)
    return ref, ids


def test_gamma22_in_an_8bit_file_advises_the_transfer():
    ref, ids = _scene()
    # written with a 2.2 power, decoded with the sRGB curve
    cand = srgb_decode(np.power(ref, 1 / 2.2))
    got = colour_causes(ref, cand, ids)
    assert got["causes"][0]["cause"] == "gamma 2.2 read as sRGB"
    assert "--transfer gamma2.2" in got["causes"][0]["message"]


def test_display_encoded_colour_in_an_exr_says_write_linear():
    ref, ids = _scene()
    cand = np.power(ref, 1 / 2.2)  # display-encoded values in a linear file
    got = colour_causes(ref, srgb_decode(cand), ids, linear_file=True)
    message = got["causes"][0]["message"]
    assert "write linear radiance" in message and "--transfer gamma2.2" not in message
