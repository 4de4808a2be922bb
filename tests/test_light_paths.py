"""Light paths: the frame's light is where the path says, the oracle and the models follow it,
the reference cache key changes with it, and bad paths are refused (one line, exit 2)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.cache import reference_key
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.light_paths import (
    POINT_RADIUS_FRACTION,
    POINT_STEP_DEG,
    SUN_STEP_DEG,
    path_light,
)

from raster_oracle import raster_models as rm
from raster_oracle import scenes

W, H = 48, 27
SMALL = ["--width", str(W), "--height", str(H), "--quiet", "--no-cache", "--spp", "4"]

#: Directions and positions are float64 rotations of the base: a few ulps of rounding.
GEOMETRY_TOL = 1e-12


def _settings():
    return ReferenceSettings(spp=4, channels=("visibility",))


def _direct(loaded, light):
    """The base scene with ``light`` put in directly (no light path involved)."""
    base = scenes.load(loaded.name, width=W, height=H)
    lights = list(base.lights)
    lights[base.light_index] = light
    return replace(base, lights=lights)


@pytest.mark.parametrize("frame", [1, 3, 7])
def test_orbit_sun_turns_about_up_at_fixed_elevation(frame):
    s0 = scenes.load("plate", width=W, height=H)
    sk = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=frame)
    d0 = np.asarray(s0.light.direction)
    dk = np.asarray(sk.light.direction)
    assert np.linalg.norm(dk) == pytest.approx(np.linalg.norm(d0), abs=GEOMETRY_TOL)
    assert dk[1] == pytest.approx(d0[1], abs=GEOMETRY_TOL)  # same elevation
    h0, hk = d0[[0, 2]], dk[[0, 2]]
    cos_a = float(h0 @ hk) / (np.linalg.norm(h0) * np.linalg.norm(hk))
    assert math.degrees(math.acos(min(cos_a, 1.0))) == pytest.approx(SUN_STEP_DEG * frame)
    # Right-handed about +Y: +Z turns towards +X, i.e. (x, z) rotates clockwise seen from +Y.
    cross_y = h0[1] * hk[0] - h0[0] * hk[1]
    assert cross_y > 0
    assert sk.camera.to_world.tolist() == s0.camera.to_world.tolist()  # camera stays


def test_moving_point_travels_on_its_circle():
    s0 = scenes.load("point", width=W, height=H)
    lo, _ = s0.bounds()
    p0 = np.asarray(s0.light.position)
    radius = POINT_RADIUS_FRACTION * (p0[1] - lo[1])
    centre = p0 + np.array([radius, 0.0, 0.0])
    for frame in (0, 1, 2, 5):
        pk = np.asarray(
            scenes.load(
                "point", width=W, height=H, light_path="moving-point", frame=frame
            ).light.position
        )
        assert pk[1] == p0[1]
        assert np.linalg.norm(pk - centre) == pytest.approx(radius, abs=GEOMETRY_TOL)
        chord = 2 * radius * math.sin(math.radians(POINT_STEP_DEG * frame) / 2)
        assert np.linalg.norm(pk - p0) == pytest.approx(chord, abs=GEOMETRY_TOL)


def test_frame_zero_is_the_scenes_own_light():
    s0 = scenes.load("plate", width=W, height=H)
    assert path_light(s0.light, "orbit-sun", 0) == s0.light


def test_reference_follows_the_light_and_equals_a_directly_built_scene():
    frames = [
        scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=k) for k in (0, 4)
    ]
    vis = []
    for sk in frames:
        ch, _ = render_reference(sk, _settings(), quiet=True)
        direct, _ = render_reference(_direct(sk, sk.light), _settings(), quiet=True)
        assert np.array_equal(ch["visibility"], direct["visibility"])
        vis.append(ch["visibility"])
    # A 40-degree turn of the sun moves the plate's shadow: many pixels change.
    assert float(np.mean(vis[0] != vis[1])) > 0.02


def test_model_follows_the_light():
    sk = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=5)
    s0 = scenes.load("plate", width=W, height=H)
    a = rm.run("shadow-map", sk, resolution=256).outputs["visibility"]
    b = rm.run("shadow-map", _direct(sk, sk.light), resolution=256).outputs["visibility"]
    c = rm.run("shadow-map", s0, resolution=256).outputs["visibility"]
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_cache_keys_differ_between_frames():
    keys = [
        reference_key(
            scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=k),
            _settings(),
            "v",
        )
        for k in (0, 1, 2)
    ]
    again = reference_key(
        scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=1), _settings(), "v"
    )
    assert len(set(keys)) == 3
    assert again == keys[1]
    # The light actually used is in the key: the same light index, another light, another key.
    s0 = scenes.load("plate", width=W, height=H)
    s1 = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=1)
    assert reference_key(_direct(s1, s1.light), _settings(), "v") != reference_key(
        s0, _settings(), "v"
    )


def test_with_frame_moves_the_light_and_keeps_the_camera():
    s = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=0)
    s3 = s.with_frame(3)
    direct = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=3)
    assert s3.light == direct.light
    assert s3.camera_path is None
    assert s3.camera.to_world.tolist() == s.camera.to_world.tolist()
    assert s3.provenance()["light_path"] == "orbit-sun"


def test_vertical_sun_is_refused():
    sun = scenes.Light(kind="directional", color=(1.0, 1.0, 1.0), direction=(0.0, -1.0, 0.0))
    with pytest.raises(ValueError, match="not vertical"):
        path_light(sun, "orbit-sun", 1)


def test_cli_reference_records_the_frame_light(tmp_path):
    out = tmp_path / "ref"
    args = ["reference", "plate", "--light-path", "orbit-sun", "--frame", "2", *SMALL]
    assert main([*args, "--out", str(out)]) == 0
    meta = json.loads((out / "reference.json").read_text())
    expected = scenes.load("plate", width=W, height=H, light_path="orbit-sun", frame=2).light
    assert meta["light"]["direction"] == list(expected.direction)
    assert meta["scene"]["light_path"] == "orbit-sun"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["reference", "plate", "--light-path", "spin"], "unknown light path 'spin'"),
        (["reference", "point", "--light-path", "orbit-sun"], "needs a directional light"),
        (["model", "shadow-map", "plate", "--light-path", "moving-point"], "point or spot"),
        (["reference", "plate", "--light-path", "orbit-sun", "--frame", "8"], "frame must be"),
    ],
)
def test_cli_bad_light_path_is_one_line_exit_2(tmp_path, capfd, argv, message):
    out = tmp_path / "out"
    extra = SMALL if argv[0] == "reference" else SMALL[:4]
    assert main([*argv, *extra, "--out", str(out)]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert message in err[0]
    assert not out.exists()


def test_score_along_a_light_path_keeps_the_camera(tmp_path):
    out = tmp_path / "score"
    argv = ["score", "plate", "--technique", "shadow-map", "--light-path", "orbit-sun"]
    assert main([*argv, "--frames", "2", *SMALL, "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["light_path"] == "orbit-sun"
    assert metrics["camera_path"] is None
    assert len(metrics["frames"]) == 2
