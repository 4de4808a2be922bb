"""The event scenes' motions in closed form: the ``step`` object path and the ``fast-pan``
camera path."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.scenes.catalogue.event_scenes import EVENT_SCENES
from raster_oracle.scenes.geometry.motion import film_motion
from raster_oracle.scenes.loader import load
from raster_oracle.scenes.object_paths import check_motion, object_transform
from raster_oracle.scenes.paths import FAST_PAN_PX


def test_step_path_translates_only_inside_its_frames():
    spec = {"path": "step", "offset": (1.0, 2.0, 3.0), "start": 2, "stop": 4}
    for k, moved in ((1, False), (2, True), (3, True), (4, False), (-1, False)):
        want = np.array([1.0, 2.0, 3.0]) if moved else np.zeros(3)
        assert np.array_equal(object_transform(spec, k)[:3, 3], want)
    with pytest.raises(ValueError, match="needs 'stop'"):
        check_motion({"shutter": {"path": "step", "offset": (0, 0, 0), "start": 1}})


def test_fast_pan_moves_the_image_centre_by_its_pixels():
    sc = load("pan-rect", width=80, height=45, n_frames=3)
    s1 = sc.with_frame(1, path="fast-pan", n_frames=3)
    mo = film_motion(s1, np.array([40.0]), np.array([22.5]))
    assert abs(abs(mo["motion_x"][0]) - FAST_PAN_PX) < 0.05 and abs(mo["motion_y"][0]) < 0.05


def test_six_event_scenes_with_a_sun_and_a_rectangle():
    assert sorted(EVENT_SCENES) == sorted(
        f"{e}-{k}" for e in ("flicker", "occluder", "pan") for k in ("sun", "rect")
    )
    assert load("flicker-sun", width=32, height=18).light.area == "disk"
    assert load("flicker-rect", width=32, height=18).light.area == "rectangle"
