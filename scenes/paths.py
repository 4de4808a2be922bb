"""Camera paths for temporal work: N frames each, frame 0 is the scene's own camera.

- ``subpixel-pan``: the camera yaws by a quarter of a pixel's angle per frame (image content
  moves 0.25 px a frame at the image centre); orthographic cameras translate 0.25 px.
- ``subtexel-pan``: the camera translates along its right axis by a quarter of a shadow-map
  texel per frame, the texel being the scene's horizontal extent / 2048 (a 2048^2 map fit
  to the scene): the workload that stable cascades must not shimmer under.
- ``fast-pan``: the camera yaws by :data:`FAST_PAN_PX` pixels' angle per frame (orthographic:
  translates as many pixels): the fast pan under which temporal denoisers ghost.
- ``rotate``: slow yaw of 0.5 degree per frame about the camera position.
- ``static``: the scene's own camera every frame (scenes whose objects move,
  :mod:`scenes.object_paths`; a static-camera TAA's convergence).
- ``dolly``: the camera moves forward by 4 % of the distance to what the image centre sees
  (the scene's extent / 4 when that is sky) a frame;
  geometry newly enters the view, the workload for SDSM's readback latency.
"""

from __future__ import annotations

import math

import numpy as np

from .camera import Camera

__all__ = ["CAMERA_PATHS", "FAST_PAN_PX", "path_camera"]

#: Image motion (pixels a frame at the image centre) of the ``fast-pan`` path.
FAST_PAN_PX = 4.0

CAMERA_PATHS = {
    "static": "the scene's own camera every frame (objects may move)",
    "subpixel-pan": "yaw by 1/4 pixel a frame (0.25 px image motion)",
    "subtexel-pan": "translate right by 1/4 shadow-map texel (scene extent / 2048) a frame",
    "fast-pan": f"yaw by {FAST_PAN_PX:g} pixels a frame ({FAST_PAN_PX:g} px image motion)",
    "rotate": "yaw by 0.5 degree a frame",
    "dolly": "move forward by 4% of the distance to the geometry at the image centre a frame",
}


def _yaw(to_world: np.ndarray, angle: float) -> np.ndarray:
    """Rotate the camera frame about its own up axis by ``angle`` radians."""
    m = to_world.copy()
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0, -up[2], up[1]], [up[2], 0, -up[0]], [-up[1], up[0], 0]])
    rot = np.eye(3) + s * k + (1 - c) * (k @ k)
    m[:3, :3] = rot @ m[:3, :3]
    return m


def path_camera(base: Camera, path: str, frame: int, n_frames: int, *, scene=None) -> Camera:
    """The camera of ``frame`` (0-based) along ``path``."""
    if path not in CAMERA_PATHS:
        raise ValueError(f"unknown camera path {path!r}; choose one of {', '.join(CAMERA_PATHS)}")
    if path == "static":
        return base
    m = np.asarray(base.to_world, dtype=np.float64)
    k = float(frame)
    if path in ("subpixel-pan", "fast-pan"):
        px = 0.25 if path == "subpixel-pan" else FAST_PAN_PX
        if base.kind == "perspective":
            return base.with_to_world(_yaw(m, -px * k * base.pixel_angle))
        hw, _ = base.half_extent()
        m = m.copy()
        m[:3, 3] += base.right * (px * k * 2 * hw / base.width)
        return base.with_to_world(m)
    if path == "rotate":
        return base.with_to_world(_yaw(m, math.radians(-0.5 * k)))
    lo, hi = scene.bounds() if scene is not None else (np.zeros(3) - 1, np.zeros(3) + 1)
    m = m.copy()
    if path == "subtexel-pan":
        extent = float(np.max((hi - lo)[[0, 2]]))
        m[:3, 3] += base.right * (0.25 * k * extent / 2048.0)
        return base.with_to_world(m)
    # dolly: 4 % of the distance to what the centre of the view sees, per frame
    dist = _centre_distance(base, scene) if scene is not None else None
    if dist is None:
        dist = float(np.linalg.norm(hi - lo)) / 4
    m[:3, 3] += base.forward * (0.04 * k * dist)
    return base.with_to_world(m)


def _centre_distance(base: Camera, scene) -> float | None:
    """Distance along the view axis to the geometry at the image centre (None: sky)."""
    from .backend.raycast import intersect

    o, d, tmax = base.rays(np.array([base.width / 2]), np.array([base.height / 2]))
    hit = intersect(scene, o, d, tmax=tmax)
    if not bool(hit["valid"][0]):
        return None
    return float(hit["t"][0] * (d[0] @ base.forward))
