"""Temporal AA metrics (metrics.ghosting) and motion-vector errors (metrics.motion) on
sequences whose answers are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.metrics import MetricError
from raster_oracle.metrics.ghosting import FLICKER_FLOOR

from raster_oracle import metrics as M


def test_convergence_is_the_first_frame_from_which_the_error_stays_near_its_level():
    e = [1.0, 0.5, 0.3, 0.21, 0.2, 0.2, 0.19, 0.2]
    c = M.convergence(e, judged=4)
    assert c["steady_error"] == pytest.approx(0.1975)
    # 0.21 <= 1.1 * 0.1975 = 0.217, 0.3 is not
    assert c["convergence_frames"] == 3
    assert M.convergence([0.2] * 5)["convergence_frames"] == 0
    # a periodic error: converged only once averaged over its period
    wobble = [0.2 + 0.05 * (-1) ** k for k in range(12)]
    assert M.convergence(wobble, judged=4)["convergence_frames"] == 11
    assert M.convergence(wobble, judged=4, window=2)["convergence_frames"] == 1
    with pytest.raises(MetricError, match="judged must be in"):
        M.convergence(e, judged=9)


def test_disocclusion_age_follows_points_along_their_motion():
    t, h, w = 4, 1, 6
    motion = np.zeros((t, h, w, 2))
    motion[..., 0] = -1.0  # everything moves one pixel right a frame
    dis = np.zeros((t, h, w))
    dis[2, 0, 3] = 1.0
    age = M.disocclusion_age(motion, dis)
    assert age[0].tolist() == [[0] * 6]
    # pixel 0 comes from outside the image every frame: disoccluded
    assert age[1].tolist() == [[0, 1, 1, 1, 1, 1]]
    assert age[2].tolist() == [[0, 1, 2, 0, 2, 2]]
    assert age[3].tolist() == [[0, 1, 2, 3, 1, 3]]


def test_ghosting_is_the_error_on_recently_disoccluded_pixels():
    t, h, w = 3, 2, 4
    ref = np.zeros((t, h, w))
    cand = np.zeros((t, h, w))
    age = np.full((t, h, w), 9)
    age[1:, 0, 0] = 0
    cand[1:, 0, 0] = 0.5  # a ghost where the point is new
    cand[1:, 1, :] = 0.1  # settled error elsewhere on one row
    g = M.ghosting(ref, cand, age, window=4)
    assert g["ghosting_error"] == pytest.approx(0.5)
    assert g["settled_error"] == pytest.approx(0.1 * 4 / 7)
    assert g["error_by_age"][0] == pytest.approx(0.5) and g["error_by_age"][1] is None
    assert g["lag_frames"] == 4  # never reaches the settled level within the window


def test_history_error_and_flicker_ratio_and_map():
    ref = np.zeros((3, 1, 4))
    ref[1:, 0, 2] = 1.0  # the truth changes at pixel 2 in frame 1
    cand = ref.copy()
    cand[1, 0, 2] = 0.25  # the candidate lags behind
    motion = np.zeros((3, 1, 4, 2))
    assert M.history_error(ref, cand, motion) == pytest.approx(0.75)
    # changes: truth 1 (one pixel once), candidate 0.25 + 0.75
    assert M.flicker_ratio(ref, cand) == pytest.approx(1.0)
    still = np.zeros((3, 1, 4))
    noisy = still.copy()
    noisy[1, 0, 0] = 0.01
    assert M.flicker_ratio(still, noisy) == pytest.approx((0.02 / 8) / FLICKER_FLOOR)
    fmap = M.flicker_map(still, noisy)
    assert fmap.shape == (1, 4) and fmap[0, 0] == pytest.approx(0.01) and fmap[0, 1] == 0


def test_motion_errors_on_kept_pixels_and_disocclusion_recall_precision():
    ref = np.zeros((2, 3, 2))
    cand = ref.copy()
    cand[0, 0] = [0.3, 0.4]  # 0.5 px off: not over the threshold
    cand[0, 1] = [3.0, 4.0]  # 5 px off
    cand[1, 2] = [9.0, 9.0]  # off, but disoccluded: not counted
    dis = np.zeros((2, 3))
    dis[1, 2] = 1
    mine = np.zeros((2, 3))
    mine[1, 2] = mine[0, 0] = 1
    e = M.motion_errors(ref, cand, disocclusion=dis, candidate_disocclusion=mine)
    assert e["motion_epe_mean"] == pytest.approx(5.5 / 5)
    assert e["motion_epe_over_half"] == pytest.approx(1 / 5)
    assert e["disocclusion_recall"] == 1.0 and e["disocclusion_precision"] == 0.5
    assert e["epe"][1, 2] == 0
    with pytest.raises(MetricError, match="same"):
        M.motion_errors(ref, cand[:1], disocclusion=dis)
