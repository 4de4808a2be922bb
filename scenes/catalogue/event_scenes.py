"""Built-in event scenes for temporal shadow denoisers: each event with a sun of angular size
(``*-sun``) and with a rectangle light (``*-rect``).

- ``flicker-*``: a post and a raised plate on a ground; a shutter closes in front of the light
  at frame :data:`FLICKER_OFF` and opens at :data:`FLICKER_ON` (object path ``step``): to
  every receiver the light goes off and comes back on (the lag after a light change).
- ``occluder-*``: a plate :data:`OCCLUDER_HEIGHT` m above a still ground slides
  :data:`OCCLUDER_STEP` m a frame along +X (its penumbra moves over a static receiver).
- ``pan-*``: posts, a plate and a sphere; scored along the ``fast-pan`` camera path
  (:data:`scenes.paths.FAST_PAN_PX` px a frame: disocclusion at the image's edge and behind the
  casters).

The sun is a disk area light :data:`SUN_DISTANCE` m away whose apex angle is
:data:`SUN_APEX_DEG` degrees (the area-light truth integrates over it; an engine treats it as
a directional light with that angular size, :mod:`raster_models.rtshadows.rays`). The
rectangle light is :data:`RECT_SIZE` m square, :data:`RECT_HEIGHT` m up, facing down.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import meshes
from .factories import diffuse, ground, look_at, mesh, sensor
from .soft_scenes import rectangle_light

__all__ = [
    "EVENT_SCENES",
    "FLICKER_OFF",
    "FLICKER_ON",
    "OCCLUDER_HEIGHT",
    "OCCLUDER_STEP",
    "RECT_HEIGHT",
    "RECT_SIZE",
    "SUN_APEX_DEG",
    "SUN_DIRECTION",
    "SUN_DISTANCE",
]

#: Frame at which the ``flicker`` shutter closes (light off) and opens again (light on).
FLICKER_OFF = 8
FLICKER_ON = 12
#: The ``occluder`` plate's height (m) and its motion a frame (m, along +X).
OCCLUDER_HEIGHT = 1.5
OCCLUDER_STEP = 0.04
#: The sun: direction of travel, distance (m) and apex angle (degrees; the real sun's is 0.53,
#: this one is wider so that penumbrae span pixels at 160 x 90).
SUN_DIRECTION = (0.35, -1.0, 0.25)
SUN_DISTANCE = 1.0e4
SUN_APEX_DEG = 8.0
#: The rectangle light's side and height (m).
RECT_SIZE = 1.0
RECT_HEIGHT = 4.0


def disk_light(centre, normal, radius, radiance) -> dict:
    """A Mitsuba ``disk`` of ``radius`` m centred at ``centre``, emitting towards ``normal``."""
    c = np.asarray(centre, dtype=np.float64)
    m = look_at(c, c + np.asarray(normal, dtype=np.float64), (0.0, 0.0, 1.0))
    m[:3, 0] *= float(radius)
    m[:3, 1] *= float(radius)
    return {
        "type": "disk",
        "to_world": m,
        "bsdf": diffuse(0.0),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [float(radiance)] * 3}},
    }


def _sun_axis() -> np.ndarray:
    d = np.asarray(SUN_DIRECTION, dtype=np.float64)
    return d / np.linalg.norm(d)


def _light(kind: str) -> dict:
    if kind == "sun":
        d = _sun_axis()
        r = SUN_DISTANCE * math.tan(math.radians(0.5 * SUN_APEX_DEG))
        return disk_light(-d * SUN_DISTANCE, d, r, 1.0)
    return rectangle_light((0.0, RECT_HEIGHT, 0.0), (0.0, -1.0, 0.0), (RECT_SIZE, RECT_SIZE), 30.0)


def _shutter(kind: str) -> tuple[dict, dict]:
    """The shutter's shape, parked where it occludes nothing, and its ``step`` path to just in
    front of the light for frames ``FLICKER_OFF <= k < FLICKER_ON``."""
    if kind == "sun":
        d = _sun_axis()
        half = 0.5 * SUN_DISTANCE * math.tan(math.radians(0.5 * SUN_APEX_DEG)) * 1.5 + 20.0
        closed, parked = -d * 0.5 * SUN_DISTANCE, -d * 1.5 * SUN_DISTANCE
        m = look_at(parked, parked + d, (0.0, 0.0, 1.0))
    else:
        half = 0.6 * RECT_SIZE + 0.05
        closed = np.array([0.0, RECT_HEIGHT - 0.05, 0.0])
        parked = closed + np.array([0.0, 2.0, 0.0])  # above the light: no ray meets it
        m = look_at(parked, parked + np.array([0.0, -1.0, 0.0]), (0.0, 0.0, 1.0))
    corners = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]])
    verts = corners @ m[:3, :3].T + m[:3, 3]
    spec = {"path": "step", "offset": tuple(closed - parked), "start": FLICKER_OFF}
    spec["stop"] = FLICKER_ON
    return mesh(meshes.quad(verts), 0.2), spec


def _base(width: int, height: int, kind: str) -> dict:
    return {
        "type": "scene",
        "camera": sensor(
            width,
            height,
            origin=(0.3, 4.2, 4.2),
            target=(-0.2, 0.0, -0.4),
            fov=55,
            near=0.1,
            far=1.0e5,
        ),
        "light": _light(kind),
        "ground": ground(40.0, 0.6),
        "post": mesh(meshes.box((-1.6, 0.0, -0.1), (-1.4, 2.0, 0.1)), (0.75, 0.7, 0.6)),
    }


def _plate(x0: float, y: float) -> dict:
    q = [[x0, y, -1.2], [x0, y, -0.2], [x0 + 1.0, y, -0.2], [x0 + 1.0, y, -1.2]]
    return mesh(meshes.quad(q), (0.5, 0.7, 0.4))


def flicker(width: int, height: int, kind: str) -> dict:
    """A post and a raised plate; a shutter switches the light off and on."""
    scene = _base(width, height, kind)
    scene["plate"] = _plate(0.2, 1.2)
    scene["shutter"], spec = _shutter(kind)
    scene["ro_motion"] = {"shutter": spec}
    return scene


def occluder(width: int, height: int, kind: str) -> dict:
    """A plate sliding along +X over a still ground, beside a still post."""
    scene = _base(width, height, kind)
    scene["plate"] = _plate(-0.8, OCCLUDER_HEIGHT)
    scene["ro_motion"] = {"plate": {"path": "slide", "velocity": (OCCLUDER_STEP, 0.0, 0.0)}}
    return scene


def pan(width: int, height: int, kind: str) -> dict:
    """Posts, a plate and a sphere on a ground (scored along the ``fast-pan`` path)."""
    scene = _base(width, height, kind)
    scene["plate"] = _plate(0.2, 1.2)
    scene["post_2"] = mesh(meshes.box((1.6, 0.0, 0.6), (1.8, 1.6, 0.8)), (0.3, 0.5, 0.8))
    scene["ball"] = {
        "type": "sphere",
        "center": [-0.4, 0.5, 1.2],
        "radius": 0.5,
        "bsdf": diffuse((0.8, 0.3, 0.3)),
    }
    return scene


def _factory(fn, kind):
    def make(width: int, height: int) -> dict:
        return fn(width, height, kind)

    make.__name__ = f"{fn.__name__}_{kind}"
    return make


_LIGHTS = {
    "sun": f"a sun {SUN_APEX_DEG:g} degrees wide",
    "rect": f"a {RECT_SIZE:g} m square light {RECT_HEIGHT:g} m up",
}
_EVENTS = {
    "flicker": (flicker, f"light off at frame {FLICKER_OFF}, on again at {FLICKER_ON}"),
    "occluder": (occluder, f"a plate sliding {OCCLUDER_STEP:g} m a frame over the ground"),
    "pan": (pan, "posts, a plate and a sphere (score along --camera-path fast-pan)"),
}

#: name -> (factory, description, width, height), as the other catalogue modules.
EVENT_SCENES = {
    f"{event}-{kind}": (_factory(fn, kind), f"{text}; {_LIGHTS[kind]}", 160, 90)
    for event, (fn, text) in _EVENTS.items()
    for kind in _LIGHTS
}
