"""Light paths for moving-light work: frame 0 is the scene's own light.

- ``orbit-sun``: a directional light whose direction turns about the world up axis (+Y) by
  :data:`SUN_STEP_DEG` degrees a frame; its elevation (the angle below the horizon) stays
  that of the scene's own sun. Needs a directional light that is not vertical (a vertical
  sun has no azimuth to turn).
- ``moving-point``: a point (or spot) light that travels on a horizontal circle through its
  own position, :data:`POINT_STEP_DEG` degrees of arc a frame, of radius a quarter of the
  light's height above the scene's lowest point (so shadows move by a similar fraction in any
  scene; at least 1e-3 of the scene's diagonal); a spot light keeps its axis. Frame ``k`` is
  at ``p0 + r (1 - cos a, 0, sin a)``, ``a = k`` steps: the circle's centre is
  ``p0 + (r, 0, 0)`` and the light first moves towards +Z.

Like camera paths (:mod:`scenes.paths`), a path is a pure function of the base light, the
frame and the scene's bounds, so the same frame gives the same light bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .lights import Light

__all__ = [
    "LIGHT_PATHS",
    "LIGHT_PATH_KINDS",
    "POINT_STEP_DEG",
    "SUN_STEP_DEG",
    "VERTICAL_TOLERANCE",
    "check_light_path",
    "path_light",
]

#: Degrees of azimuth the ``orbit-sun`` direction turns per frame.
SUN_STEP_DEG = 10.0

#: Degrees of arc the ``moving-point`` light travels per frame.
POINT_STEP_DEG = 15.0

#: Fraction of the light's height above the scene's lowest point used as the
#: ``moving-point`` circle's radius.
POINT_RADIUS_FRACTION = 0.25

#: A sun whose direction is within this angle (degrees) of vertical has no usable azimuth.
VERTICAL_TOLERANCE = 1.0

LIGHT_PATHS = {
    "orbit-sun": f"directional light turning {SUN_STEP_DEG:g} degrees of azimuth a frame about "
    "+Y at the scene sun's elevation",
    "moving-point": f"point/spot light moving {POINT_STEP_DEG:g} degrees a frame on a horizontal "
    f"circle through its position, radius {POINT_RADIUS_FRACTION:g} x its height above the scene",
}

#: Light kinds each path applies to.
LIGHT_PATH_KINDS = {"orbit-sun": ("directional",), "moving-point": ("point", "spot")}


def _rotate_y(v: np.ndarray, angle: float) -> np.ndarray:
    """Rotate ``v`` about +Y by ``angle`` radians (right-handed: +Z towards +X)."""
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = (float(t) for t in v)
    return np.array([c * x + s * z, y, -s * x + c * z])


def check_light_path(path: str, light: Light) -> None:
    """Raise ``ValueError`` when ``path`` is unknown or does not fit ``light``."""
    if path not in LIGHT_PATHS:
        raise ValueError(f"unknown light path {path!r}; choose one of {', '.join(LIGHT_PATHS)}")
    kinds = LIGHT_PATH_KINDS[path]
    if light.is_area:  # its emitter shape is part of the scene's geometry and cannot move
        raise ValueError(
            f"light path {path} moves punctual lights; the scene's light is a {light.area} "
            "area light"
        )
    if light.kind not in kinds:
        raise ValueError(
            f"light path {path} needs a {' or '.join(kinds)} light; the scene's light is a "
            f"{light.kind} light"
        )
    if path == "orbit-sun":
        d = np.asarray(light.direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        if abs(d[1]) >= math.cos(math.radians(VERTICAL_TOLERANCE)):
            raise ValueError(
                f"light path orbit-sun needs a sun that is not vertical (within "
                f"{VERTICAL_TOLERANCE:g} degrees of +-Y); the scene's sun travels along "
                f"{tuple(round(float(c), 6) for c in d)}"
            )


def path_light(base: Light, path: str, frame: int, *, scene=None) -> Light:
    """The light of ``frame`` (0-based) along ``path``; frame 0 is ``base`` itself.

    Parameters
    ----------
    base : the scene's own light (world space, see :class:`scenes.Light`).
    path : a name of :data:`LIGHT_PATHS`.
    frame : frame index >= 0.
    scene : the loaded scene, for its bounds (``moving-point``); without it the bounds are
        ``[-1, 1]^3``.

    Raises
    ------
    ValueError
        Unknown path, or a path that does not fit the light's kind (see
        :data:`LIGHT_PATH_KINDS`).
    """
    check_light_path(path, base)
    k = int(frame)
    if k == 0:
        return base
    if path == "orbit-sun":
        d = np.asarray(base.direction, dtype=np.float64)
        d = _rotate_y(d, math.radians(SUN_STEP_DEG * k))
        return replace(base, direction=tuple(float(c) for c in d))
    lo, hi = scene.bounds() if scene is not None else (np.full(3, -1.0), np.full(3, 1.0))
    p0 = np.asarray(base.position, dtype=np.float64)
    height = abs(float(p0[1] - lo[1]))
    radius = POINT_RADIUS_FRACTION * max(height, 1e-3 * float(np.linalg.norm(hi - lo)))
    a = math.radians(POINT_STEP_DEG * k)
    p = p0 + radius * np.array([1.0 - math.cos(a), 0.0, math.sin(a)])
    return replace(base, position=tuple(float(c) for c in p))
