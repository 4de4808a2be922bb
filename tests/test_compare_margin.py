"""The compare margin a shadow model reports per receiver (raster_models/shadowmaps/
margins.py): closed form on a flat map, and every pixel whose verdict a coarser depth format
flips lies within that format's rounding of the map (issue 43, item 5)."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.shadowmaps import margins

from raster_oracle import raster_models, scenes

#: D16's quantum (normalized depth) plus the half-quantum of the reference's own rounding.
D16_ROUNDING = 1.5 / (2**16 - 1)


def test_flat_map_margin_is_the_depth_distance():
    depth = np.full((8, 8), 0.5)
    u = np.array([0.1, 0.5, 0.93])
    ref = np.array([0.5003, 0.49, 0.7])
    zero = np.zeros((1, 3))
    got = margins.compare_margin(depth, u, u, ref, zero, zero, point=False)
    np.testing.assert_allclose(got, [3e-4, 0.01, 0.2], atol=1e-12)
    # a step inside the 2x2 footprint: the nearer texel decides
    depth[:, 4:] = 0.6
    got = margins.compare_margin(
        depth,
        np.array([0.5]),
        np.array([0.5]),
        np.array([0.59]),
        zero[:, :1],
        zero[:, :1],
        point=False,
    )
    assert got[0] == pytest.approx(0.01)


@pytest.mark.parametrize("filt", ["point", "pcf", "three_pcf"])
def test_format_flips_lie_within_the_formats_rounding(_backend, filt):
    scene = scenes.load("city", width=160, height=90)
    kw = {"resolution": 512, "filter": filt, "bias": 1e-5}
    fine = raster_models.run("shadow-map", scene, format="D32F", **kw).outputs
    coarse = raster_models.run("shadow-map", scene, format="D16", **kw).outputs
    flips = (fine["visibility"] >= 0.5) != (coarse["visibility"] >= 0.5)
    assert flips.sum() > 0  # D16 against a 1e-5 bias: acne somewhere
    assert fine["compare_margin"][flips].max() <= D16_ROUNDING
    assert (
        "compare_margin"
        not in raster_models.run("shadow-map", scene, **{**kw, "filter": "vsm"}).outputs
    )
