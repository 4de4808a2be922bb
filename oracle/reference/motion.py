"""The reference's temporal truth: the ``motion`` channel group.

``motion.X``, ``motion.Y`` (pixels, float32): at each pixel centre of frame ``k``, the film
position in frame ``k - 1``'s image of the surface point seen through the centre, minus the
centre (x right, y down; object paths and camera/light paths are defined for frame -1, so
frame 0 has motion too); ``disocclusion`` (0 or 1): 1 where that point was hidden from frame
``k - 1``'s camera or outside its image. A scene without camera path, light path or moving
objects has zero motion and no disocclusion. The geometry is
:func:`scenes.geometry.motion.film_motion`;
docs/conventions.md converts it to Unreal's, Unity's and a UV-space convention.
"""

from __future__ import annotations

import numpy as np

from ...scenes.geometry.motion import film_motion

__all__ = ["motion_channels"]


def motion_channels(loaded) -> dict[str, np.ndarray]:
    """``motion.X``, ``motion.Y`` and ``disocclusion``, ``(H, W)`` float32 each, at the pixel
    centres of ``loaded``'s frame."""
    h, w = loaded.height, loaded.width
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    m = film_motion(loaded, x, y)
    return {
        "motion.X": m["motion_x"].astype(np.float32).reshape(h, w),
        "motion.Y": m["motion_y"].astype(np.float32).reshape(h, w),
        "disocclusion": m["disoccluded"].astype(np.float32).reshape(h, w),
    }
