"""Built-in scenes with moving objects (object paths, :mod:`scenes.object_paths`): the
temporal workloads where something is disoccluded.

- ``slide``: an axis-aligned orange panel slides right across a striped wall by
  :data:`SLIDE_PX_PER_FRAME` pixels a frame under an orthographic camera, so the band of wall
  it uncovers each frame is exactly that wide (the closed form the tests check); it casts a
  shadow on the wall that moves with it.
- ``spin``: a pinwheel of four blades turns by :data:`SPIN_DEGREES` a frame about the view
  axis in front of the same wall, seen by a perspective camera: the motion of its pixels
  grows with the distance from the hub.

Both keep their camera still (``LoadedScene.default_camera_path`` is ``static``); a camera
path can be added on top.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import meshes
from .aa_scenes import ortho_camera
from .factories import mesh, sensor, sun

__all__ = ["MOVING_SCENES", "SLIDE_HALF_WIDTH", "SLIDE_PX_PER_FRAME", "SPIN_DEGREES"]

#: Pixels the ``slide`` panel moves a frame (to the right).
SLIDE_PX_PER_FRAME = 2.0
#: Half width of the ``slide`` scene's orthographic view (world units).
SLIDE_HALF_WIDTH = 4.0
#: Degrees the ``spin`` pinwheel turns a frame.
SPIN_DEGREES = 3.0
_PANEL_Z = -1.0


def _rect(x0, x1, y0, y1, z):
    return meshes.quad([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])


def _wall() -> tuple[np.ndarray, np.ndarray]:
    """Slanted light stripes on the wall plane z = 0 (edges for the anti-aliasing to work on)."""
    parts = []
    for i in range(-10, 11):
        x = 0.55 * i
        z = -0.001
        corners = [[x, -6, z], [x + 0.18, -6, z], [x + 0.5, 6, z], [x + 0.32, 6, z]]
        parts.append(meshes.quad(np.array(corners, dtype=np.float64)))
    return meshes.merge(parts)


def slide(width: int, height: int) -> dict:
    """An orange panel sliding right across a striped wall, orthographic view."""
    pix = 2.0 * SLIDE_HALF_WIDTH / width
    # film x (pixels) -> world X: this camera looks down +Z and Mitsuba's camera +X is
    # image-left, so image right is world -X
    a = round(0.2 * width) + 0.25  # the panel's left edge, a quarter pixel into a pixel
    x_left, x_right = SLIDE_HALF_WIDTH - a * pix, SLIDE_HALF_WIDTH - (a + 0.25 * width) * pix
    y0 = 0.4 * SLIDE_HALF_WIDTH * height / width
    return {
        "type": "scene",
        "camera": ortho_camera(width, height, SLIDE_HALF_WIDTH),
        "sun": sun((-0.3, -0.35, 1.0)),
        "wall": mesh(_rect(-12, 12, -8, 8, 0.0), 0.25),
        "stripes": mesh(_wall(), 0.7),
        "panel": mesh(_rect(x_right, x_left, -y0, y0, _PANEL_Z), (0.9, 0.45, 0.1)),
        "ro_motion": {"panel": {"path": "slide", "velocity": (-SLIDE_PX_PER_FRAME * pix, 0, 0)}},
    }


def _pinwheel(radius: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    parts = []
    for i in range(4):
        a = math.radians(90.0 * i + 10.0)
        b = a + math.radians(35.0)
        tip_a = [radius * math.cos(a), radius * math.sin(a), z]
        tip_b = [radius * math.cos(b), radius * math.sin(b), z]
        v = np.array([[0, 0, z], tip_a, tip_b], dtype=np.float64)
        parts.append((v, np.array([[0, 1, 2]])))
    return meshes.merge(parts)


def spin(width: int, height: int) -> dict:
    """A pinwheel turning about the view axis before a striped wall, perspective view."""
    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 0, -10), target=(0, 0, 0), fov=40, near=0.1, far=100
        ),
        "sun": sun((-0.3, -0.35, 1.0)),
        "wall": mesh(_rect(-12, 12, -8, 8, 0.0), 0.25),
        "stripes": mesh(_wall(), 0.7),
        "pinwheel": mesh(_pinwheel(2.4, -1.5), (0.2, 0.6, 0.9)),
        "ro_motion": {
            "pinwheel": {
                "path": "spin",
                "pivot": (0.0, 0.0, -1.5),
                "axis": (0.0, 0.0, 1.0),
                "degrees": SPIN_DEGREES,
            }
        },
    }


#: name -> (factory, description, width, height), as :data:`scenes.catalogue.aa_scenes.AA_SCENES`.
MOVING_SCENES = {
    "slide": (
        slide,
        f"a panel sliding {SLIDE_PX_PER_FRAME:g} px a frame across a striped wall, "
        "orthographic (disocclusion band of closed-form width)",
        160,
        90,
    ),
    "spin": (
        spin,
        f"a pinwheel turning {SPIN_DEGREES:g} degrees a frame before a striped wall",
        160,
        90,
    ),
}
