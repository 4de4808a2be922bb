"""Deferred MSAA (``msaa`` ``shading=deferred``): the per-sample G-buffer's bytes as closed
forms, the same image as forward MSAA, Simple/Complex shading events."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa.msaa import DEFERRED_GBUFFER

from raster_oracle import raster_models, scenes


@pytest.fixture(scope="module")
def star():
    return scenes.load("star", width=32, height=18)


def test_gbuffer_layout_is_16_bytes_a_sample():
    assert sum(b for _, b in DEFERRED_GBUFFER.values()) == 16
    assert DEFERRED_GBUFFER["depth"] == ("D32F", 4)


@pytest.mark.parametrize("n", [4, 8])
def test_deferred_bytes_are_w_h_n_16(star, n):
    w, h = star.width, star.height
    d = raster_models.run("msaa", star, samples=n, shading="deferred")
    f = raster_models.run("msaa", star, samples=n)
    assert d.cost["framebuffer_bytes"] == w * h * n * 16
    by = d.cost["framebuffer_bytes_by_buffer"]
    assert by["depth"] == w * h * n * 4 and by["normal"] == w * h * n * 4
    assert by["color"] == w * h * n * 8 and by["aggregates"] == 0
    assert d.cost["resolve_target_bytes"] == w * h * 4
    assert f.cost["framebuffer_bytes"] == w * h * n * 8  # forward: RGBA8 + D32 a sample
    # the same image and coverage as forward MSAA
    np.testing.assert_array_equal(d.outputs["color"], f.outputs["color"])
    np.testing.assert_array_equal(d.outputs["coverage"], f.outputs["coverage"])
    # Simple/Complex: one shade where every sample holds one primitive, else one per
    # covered sample; none without geometry
    ev_f, ev_d = f.outputs["shading_events"], d.outputs["shading_events"]
    covered = np.rint(f.outputs["coverage"] * n)
    simple = (ev_f == 1) & (covered == n)
    assert simple.any() and (~simple & (ev_f > 0)).any()
    np.testing.assert_array_equal(ev_d[simple], 1)
    np.testing.assert_array_equal(ev_d[~simple], np.where(ev_f[~simple] == 0, 0, covered[~simple]))
    assert d.diagnostics["pipeline"] == "deferred"
    assert d.diagnostics["gbuffer"]["normal"] == {"format": "RGB10A2", "bytes_per_sample": 4}
