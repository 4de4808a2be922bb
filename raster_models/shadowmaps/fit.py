"""Fitting orthographic light boxes: light-frame hints, AABBs of point sets, the filter margin."""

from __future__ import annotations

import numpy as np

from ..light_frame import LightFrame, make_frame
from .frustum import frustum_slice

__all__ = ["aabb", "box_corners", "filter_kernel_texels", "light_box", "light_frame_for"]


def light_frame_for(light, camera, light_up: str, origin=(0.0, 0.0, 0.0)) -> LightFrame:
    """LookAt frame along the light's travel direction.

    ``light_up="world"``: up = world +Y (MJP, Falcor, Intel without alignment);
    ``"camera_right"``: up = the camera's right vector, which turns the camera's forward axis
    into the light frame's x axis (Intel's "align light to frustum"). A degenerate hint falls
    back to world Y, Z, X in that order (recorded as ``up_used``).
    """
    if light_up == "camera_right":
        hints = [("camera_right", camera.right)]
    else:
        hints = [("world_y", (0.0, 1.0, 0.0))]
    return make_frame(np.asarray(light.direction, dtype=np.float64), hints, origin)


def box_corners(lo, hi) -> np.ndarray:
    """The 8 corners of an axis-aligned box ``(8, 3)``."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def aabb(frame: LightFrame, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Light-frame (min, max) of world points."""
    lc = frame.to_light(points)
    return lc.min(axis=0), lc.max(axis=0)


def light_box(
    frame: LightFrame, scene, camera, *, whole_scene: bool, precision, inverse
) -> tuple[np.ndarray, np.ndarray]:
    """Light-frame (min, max) of what one light box must hold: the scene's bounding box
    (``whole_scene``) or the camera's view frustum from its near to its far plane (its
    corners at the matrices' ``precision``, through the view-projection ``inverse`` a model
    names; :func:`raster_models.shadowmaps.frustum.frustum_slice`)."""
    if whole_scene:
        lo, hi = scene.bounds()
        pts = box_corners(lo, hi)
    else:
        pts = frustum_slice(
            camera, camera.near, camera.far, precision=precision, inverse=inverse
        ).astype(np.float64)
    return aabb(frame, pts)


def filter_kernel_texels(params) -> float:
    """Width in texels a filter reads around its sample (for MJP's extent margin)."""
    f = params.filter
    if f == "point":
        return 1.0
    if f == "hw_pcf":
        return 2.0
    if f == "pcf":
        return float(params.pcf_size + 1)
    if f == "poisson":
        return float(np.ceil(params.filter_size) + 1)
    if f == "pcss":
        return 2.0  # the centre tap's 2x2 footprint; the disk's radius varies per pixel
    return float(params.blur_size + 1)
