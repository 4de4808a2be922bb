"""The alpha coverage study (oracle.studies.alpha_coverage) on a small alpha-foliage view."""

from __future__ import annotations

import pytest
from raster_oracle.oracle.studies.alpha_coverage import PRESETS, coverage_by_band


@pytest.mark.slow
def test_coverage_kept_per_band(mi):
    res = coverage_by_band(n=300, width=96, height=54, samples=4, spp_side=3)
    assert len(res["bands"]) == 5 and res["bands"][0][0] == 2.0
    assert all(p > 50 for p in res["pixels"]) and all(0.2 < t < 0.9 for t in res["truth"])
    kept = res["kept"]
    assert set(kept) == set(PRESETS)
    # hashed alpha is unbiased at every distance (its threshold is uniform)
    assert all(abs(k - 1) < 0.1 for k in kept["hashed/box"])
    # at 96 x 54 a pixel holds 30-80 texels at 2-5 m: box-filtered mips have lost the
    # foliage there already, NVTT's scaled mips keep it (and lose it beyond, at levels of
    # 2 x 2 and 1 x 1 texels that scaling cannot hold)
    assert kept["test/box"][0] < 0.05 and kept["test/coverage"][0] > 0.9
    assert all(c >= b for c, b in zip(kept["test/coverage"], kept["test/box"], strict=True))
    assert kept["test/coverage"][-1] < 0.05


@pytest.mark.slow
def test_silhouette_shift_of_the_rules(mi):
    from raster_oracle.oracle.studies.alpha_coverage import silhouette_shift

    plain = silhouette_shift("test/box", size=96, samples=4)
    a2c = silhouette_shift("threejs-a2c/box", size=96, samples=4)
    assert plain["contour_px"] > 100
    # the plain test's contour is the truth's (alpha at the pixel centre, no bias)
    assert abs(plain["shift_px"]) < 0.1
    # three.js's smoothstep(t, t + fwidth, a) puts half coverage half a ramp inside
    assert -0.8 < a2c["shift_px"] < -0.4


@pytest.mark.slow
def test_flicker_over_a_subpixel_pan(mi):
    from raster_oracle.oracle.studies.alpha_coverage import flicker

    res = flicker(n=300, width=64, height=36, frames=4)
    assert res["truth_change"] > 0  # sub-pixel leaves change coverage as they move
    values = res["flicker"]
    assert set(values) == set(PRESETS) and all(v >= 0 for v in values.values())
    # a hashed threshold per pixel-sized object-space cell: a new threshold at every step
    assert values["hashed/box"] > 1.5 * values["test/box"]
