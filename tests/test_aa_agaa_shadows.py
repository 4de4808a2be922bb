"""AGAA shades an aggregate with its filtered visibility: the mean over its samples of the
light visibility at each sample's own surface point (issue 18, "AGAA shadows").

One exact shadow ray from the aggregate's mean position tested a point on no surface:
behind ``stripes``' zigzag, so every K = 1 pixel was black (0 on all 57,600 px at the
scene's size, 320 x 180, and at 160 x 90) and K = 2 had a mean of (0.005, 0.010, 0.040)
against the reference's (0.368, 0.078, 0.086). (At 80 x 45 the strips are wide enough in
world units for the mean position to clear them.)
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa import samples
from raster_oracle.raster_models.aa.agaa import kernels
from raster_oracle.scenes import backend
from raster_oracle.scenes.catalogue.builtin import BuiltinScene

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests.test_aa_shading_point import _tilted_wall

#: Relative tolerance of a frame's mean colour against 16x supersampling of the same frame
#: (one surface an aggregate: only the shading position differs, pixel centre vs samples).
MEAN_RTOL = 0.02


def _reference(scene):
    """Box-filtered per-sample shading (the oracle's shading and shadow ray at each of 16
    standard samples): the reference of the same frame."""
    return rm.run("ssaa", scene, samples=16).outputs["color"]


@pytest.fixture(scope="module")
def stripes():
    return scenes.load("stripes", width=160, height=90)


def test_stripes_two_aggregates_match_the_reference(stripes):
    ref = _reference(stripes)
    got = rm.run("agaa", stripes, aggregates=2).outputs["color"]
    assert np.allclose(got.mean((0, 1)), ref.mean((0, 1)), rtol=MEAN_RTOL)
    lit = ref.sum(-1) > 0.05
    assert lit.mean() > 0.9
    # no pixel darker than the reference beyond its float noise where the reference is lit
    assert (got.sum(-1)[lit] > 0.98 * ref.sum(-1)[lit]).all()


def test_stripes_one_aggregate_is_lit_as_its_samples_see_it(stripes):
    """Nothing shadows the strips: every sample sees the light, so one aggregate's colour is
    its filtered shading with visibility 1 (the correlation loss of K = 1, no shadow)."""
    res = rm.run("agaa", stripes, aggregates=1)
    got = res.outputs["color"]
    unshadowed = kernels.render(
        stripes,
        samples.positions(8),
        k=1,
        threshold=0.1,
        depth_weight=1.0,
        fmt="rgb10a2",
        visibility=lambda attrs: np.ones(len(attrs["valid"])),
    )["color"].reshape(got.shape)
    assert np.array_equal(got, unshadowed)
    assert (got.sum(-1) > 0.1).all()
    # one shadow ray per covered sample (the samples' own points), none per aggregate
    assert res.cost["shadow_rays"] == 160 * 90 * 8


@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("degrees", [20.0, 63.0])
def test_tilted_wall_matches_the_reference(k, degrees):
    def factory(w, h):
        return _tilted_wall(w, h, degrees=degrees, offset_x=30.0)

    wall = scenes.load(BuiltinScene("tilted-wall", factory, "a lit tilted wall", 64, 40))
    ref = _reference(wall)
    got = rm.run("agaa", wall, aggregates=k).outputs["color"]
    assert np.allclose(got.mean((0, 1)), ref.mean((0, 1)), rtol=MEAN_RTOL)
    lit = ref.sum(-1) > 0.05
    assert (got.sum(-1)[lit] > 0.9 * ref.sum(-1)[lit]).all()


def test_filtered_visibility_by_hand():
    """The mean of the sample visibilities over each aggregate's samples (sky: -1)."""
    mi = backend.mitsuba()
    import drjit as dr

    vis = np.array([[1, 0, 1, 1], [0, 0, 1, 0], [1, 1, 1, 1]], np.float32)  # 3 px, N = 4
    agg = np.array([[0, 0, 1, -1], [0, 1, 1, 1], [-1, -1, -1, -1]], np.int32)
    f = kernels.filtered_visibility(
        mi, dr, mi.Float(vis.ravel()), [mi.Int32(agg[:, j]) for j in range(4)], 2
    )
    assert np.allclose(f[0].numpy(), [0.5, 0.0, 0.0])
    assert np.allclose(f[1].numpy(), [1.0, 1.0 / 3.0, 0.0])
