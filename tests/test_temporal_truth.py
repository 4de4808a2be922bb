"""Temporal truth: the reference's ``motion`` group against closed forms, object paths and
camera files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.catalogue.moving_scenes import SLIDE_PX_PER_FRAME
from raster_oracle.scenes.object_paths import object_transform

from raster_oracle import scenes

#: Motion vectors must equal the projection of the reference position with the previous
#: frame's camera to this many pixels (the issue's bound; float32 positions and float64
#: projection leave about 1e-5 px).
MOTION_TOL_PX = 1e-3
W, H = 48, 27


def _channels(loaded, groups=("id", "position", "motion")):
    ch, _ = render_reference(loaded, ReferenceSettings(spp=1, channels=groups), quiet=True)
    return ch


def _opengl_film(camera, points):
    """Film positions of world points through the camera's OpenGL matrices (column vectors):
    clip = P @ V @ p, NDC = clip / w, film x = (ndc_x + 1) / 2 W, y = (1 - ndc_y) / 2 H."""
    p = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    clip = p @ (camera.projection("opengl") @ camera.world_to_view("opengl")).T
    ndc = clip[:, :2] / clip[:, 3:4]
    return np.stack(
        [(ndc[:, 0] + 1) / 2 * camera.width, (1 - ndc[:, 1]) / 2 * camera.height], axis=-1
    )


@pytest.mark.parametrize("path", ["subpixel-pan", "rotate", "dolly"])
@pytest.mark.parametrize("frame", [0, 3])
def test_motion_is_the_reference_position_projected_by_the_previous_camera(path, frame):
    loaded = scenes.load("plate", width=W, height=H, camera_path=path, frame=frame, n_frames=8)
    ch = _channels(loaded)
    valid = ch["id"] >= 0
    pos = np.stack([ch[f"position.{c}"] for c in "XYZ"], -1)[valid].astype(np.float64)
    prev = loaded.previous()
    assert prev.frame == frame - 1
    film = _opengl_film(prev.camera, pos)
    y, x = np.nonzero(valid)
    mx, my = film[:, 0] - (x + 0.5), film[:, 1] - (y + 0.5)
    assert np.max(np.abs(ch["motion.X"][valid] - mx)) < MOTION_TOL_PX
    assert np.max(np.abs(ch["motion.Y"][valid] - my)) < MOTION_TOL_PX
    # the camera moved: the vectors are not all zero (else the check above is empty)
    assert np.max(np.hypot(mx, my)) > 0.2


def test_subpixel_pan_moves_the_image_a_quarter_pixel():
    loaded = scenes.load("plate", width=W, height=H, camera_path="subpixel-pan", frame=2)
    ch = _channels(loaded)
    centre = ch["motion.X"][H // 2 - 1 : H // 2 + 1, W // 2 - 1 : W // 2 + 1]
    # yawing right by a quarter pixel moves content left: it was 0.25 px to the right before
    np.testing.assert_allclose(centre, 0.25, atol=2e-3)


def test_a_still_scene_has_no_motion_and_no_disocclusion():
    ch = _channels(scenes.load("plate", width=W, height=H))
    assert not np.any(ch["motion.X"]) and not np.any(ch["motion.Y"])
    assert not np.any(ch["disocclusion"])


@pytest.mark.parametrize("frame", [0, 4])
def test_sliding_panel_uncovers_a_band_of_closed_form_width(frame):
    loaded = scenes.load("slide", width=64, height=36, frame=frame)
    ch = _channels(loaded)
    panel = ch["id"] == loaded.shape_names.index("panel")
    rows = np.flatnonzero(panel.any(axis=1))
    dis = ch["disocclusion"] > 0.5
    # on every row the panel covers, the band it uncovered is SLIDE_PX_PER_FRAME pixels wide:
    # the centres in [left_k - v, left_k), left_k = left_0 + k v (a quarter pixel past a
    # pixel boundary, so no centre lies on an edge)
    assert len(rows) > 5
    np.testing.assert_array_equal(dis.sum(axis=1)[rows], SLIDE_PX_PER_FRAME)
    assert dis.sum() == SLIDE_PX_PER_FRAME * len(rows)
    left = panel[rows[0]].argmax()
    band = np.zeros(64, bool)
    band[left - int(SLIDE_PX_PER_FRAME) : left] = True
    assert np.all(dis[rows] == band)
    # panel pixels moved by v to the right: they were v px to the left in frame k - 1
    np.testing.assert_allclose(ch["motion.X"][panel], -SLIDE_PX_PER_FRAME, atol=1e-4)
    np.testing.assert_allclose(ch["motion.X"][~panel & ~dis], 0.0, atol=1e-4)


def test_spinning_object_moves_along_its_rotation():
    loaded = scenes.load("spin", width=64, height=36, frame=1)
    ch = _channels(loaded)
    wheel = ch["id"] == loaded.shape_names.index("pinwheel")
    pos = np.stack([ch[f"position.{c}"] for c in "XYZ"], -1)[wheel].astype(np.float64)
    spec = loaded.object_motion["pinwheel"]
    back = object_transform(spec, 0) @ np.linalg.inv(object_transform(spec, 1))
    before = pos @ back[:3, :3].T + back[:3, 3]
    film = loaded.camera.project(before)
    y, x = np.nonzero(wheel)
    np.testing.assert_allclose(ch["motion.X"][wheel], film[:, 0] - x - 0.5, atol=MOTION_TOL_PX)
    np.testing.assert_allclose(ch["motion.Y"][wheel], film[:, 1] - y - 0.5, atol=MOTION_TOL_PX)
    assert ch["disocclusion"].sum() > 0


def test_camera_file_frames_follow_the_file(tmp_path):
    base = scenes.load("plate", width=W, height=H)
    cams = [
        scenes.load("plate", width=W, height=H, camera_path="rotate", frame=k) for k in (0, 1, 2)
    ]
    frames = [
        {"world_to_view": c.camera.world_to_view("opengl").tolist(), "fov_y_deg": c.camera.fov_y}
        for c in cams
    ]
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"frames": frames}))
    seq = scenes.load("plate", width=W, height=H, camera_file=path, frame=2)
    assert seq.camera_path == "file" and seq.frame == 2
    np.testing.assert_allclose(seq.camera.to_world, cams[2].camera.to_world, atol=1e-9)
    assert seq.camera.fov_x == pytest.approx(base.camera.fov_x)
    a, b = _channels(seq, ("motion",)), _channels(cams[2], ("motion",))
    np.testing.assert_allclose(a["motion.X"], b["motion.X"], atol=MOTION_TOL_PX)
    first = _channels(seq.with_frame(0), ("motion",))
    assert not np.any(first["motion.X"])  # frame -1 of a file is its frame 0


def test_bad_camera_file_is_one_line(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"frames": [{"to_world": [[1, 0], [0, 1]]}]}))
    with pytest.raises(scenes.SceneError, match="frame 0 to_world: expected a 4x4 matrix"):
        scenes.load("plate", width=W, height=H, camera_file=path)
    with pytest.raises(scenes.SceneError, match="camera file not found"):
        scenes.load("plate", width=W, height=H, camera_file=tmp_path / "none.json")


def test_export_records_the_frame_of_its_sequence(tmp_path):
    from raster_oracle.scenes.formats.export import export

    loaded = scenes.load("slide", width=64, height=36, frame=3, n_frames=8)
    export(loaded, tmp_path / "e")
    seq = json.loads((tmp_path / "e" / "camera.json").read_text())["sequence"]
    assert seq["frame"] == 3 and seq["n_frames"] == 8 and seq["camera_path"] == "static"
    assert seq["object_paths"]["panel"]["path"] == "slide"
    moved = np.asarray(seq["object_transforms"]["panel"])
    np.testing.assert_allclose(moved, object_transform(loaded.object_motion["panel"], 3))


def test_score_follows_a_camera_file(tmp_path):
    from raster_oracle.oracle.cli import main

    cams = [
        scenes.load("plate", width=32, height=18, camera_path="rotate", frame=k) for k in (0, 1, 2)
    ]
    frames = [{"to_world": c.camera.to_world.tolist(), "fov_x_deg": c.camera.fov_x} for c in cams]
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps({"frames": frames}))
    out = tmp_path / "score"
    argv = ["score", "plate", "--width", "32", "--height", "18", "--camera-file", str(path)]
    argv += ["--frames", "3", "--technique", "noaa", "--spp", "2", "--no-cache", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    rec = json.loads((out / "metrics.json").read_text())
    assert rec["camera_path"] == "file" and len(rec["frames"]) == 3
    assert rec["reference"]["scene"]["name"] == "plate"
