"""Sub-sample positions of a pixel: the standard multisample patterns and ordered grids.

Positions are in ``[0, 1)^2`` from the pixel's upper-left corner, y down (the project's
frame, README "Conventions"). The standard patterns are the Vulkan standard sample locations
(``VkPhysicalDeviceLimits::standardSampleLocations``), which Direct3D 11/12 use too: Vulkan's
framebuffer frame is y down like ours, so the table is used as published. (OpenGL's
``GL_SAMPLE_POSITION`` values are y up from the lower-left corner; they would be flipped,
``y_down = 1 - y_gl``.)

References
----------
Khronos, Vulkan 1.3 specification, "Multisampling", table "Standard sample locations".
Microsoft, D3D11_STANDARD_MULTISAMPLE_PATTERN (the same points in 1/16-pixel units).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ModelError

__all__ = ["PATTERNS", "STANDARD_COUNTS", "STANDARD_POSITIONS", "ordered_grid", "positions"]

#: Vulkan/D3D standard sample locations, y down, in pixels from the upper-left corner.
STANDARD_POSITIONS: dict[int, tuple[tuple[float, float], ...]] = {
    1: ((0.5, 0.5),),
    2: ((0.75, 0.75), (0.25, 0.25)),
    4: ((0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)),
    8: (
        (0.5625, 0.3125),
        (0.4375, 0.6875),
        (0.8125, 0.5625),
        (0.3125, 0.1875),
        (0.1875, 0.8125),
        (0.0625, 0.4375),
        (0.6875, 0.9375),
        (0.9375, 0.0625),
    ),
    16: (
        (0.5625, 0.5625),
        (0.4375, 0.3125),
        (0.3125, 0.625),
        (0.75, 0.4375),
        (0.1875, 0.375),
        (0.625, 0.8125),
        (0.8125, 0.6875),
        (0.6875, 0.1875),
        (0.375, 0.875),
        (0.5, 0.0625),
        (0.25, 0.125),
        (0.125, 0.75),
        (0.0, 0.5),
        (0.9375, 0.25),
        (0.875, 0.9375),
        (0.0625, 0.0),
    ),
}

#: Sample counts with a standard pattern.
STANDARD_COUNTS = tuple(STANDARD_POSITIONS)


def check_standard_count(technique: str, samples: int, *, why: str = "(standard patterns)"):
    """Refuse a sample count with no standard pattern (message names the valid counts)."""
    if samples not in STANDARD_COUNTS:
        raise ModelError(
            f"{technique}: parameter samples must be one of "
            f"{', '.join(map(str, STANDARD_COUNTS))} {why}, got {samples}"
        )


#: Sample patterns by name.
PATTERNS = ("standard", "ordered-grid")


def ordered_grid(n: int) -> np.ndarray:
    """``(n, 2)`` cell centres of an ``m x k`` grid (``m * k = n``, ``m >= k``, as square as
    possible; ``m`` columns), row by row from the top left."""
    k = int(math.isqrt(n))
    while n % k:
        k -= 1
    m = n // k
    ix, iy = np.meshgrid(np.arange(m), np.arange(k))
    return np.column_stack([(ix.ravel() + 0.5) / m, (iy.ravel() + 0.5) / k])


def positions(n: int, pattern: str = "standard") -> np.ndarray:
    """``(n, 2)`` float64 sample positions of ``pattern`` with ``n`` samples.

    Raises
    ------
    ModelError
        Unknown pattern, or a count without a standard pattern (1, 2, 4, 8, 16).
    """
    if pattern == "standard":
        if n not in STANDARD_POSITIONS:
            raise ModelError(
                f"the standard pattern has {', '.join(map(str, STANDARD_COUNTS))} samples, got {n}"
            )
        return np.asarray(STANDARD_POSITIONS[n], dtype=np.float64)
    if pattern == "ordered-grid":
        if not 1 <= n <= 64:
            raise ModelError(f"ordered-grid samples must be in [1, 64], got {n}")
        return ordered_grid(n)
    raise ModelError(f"unknown sample pattern {pattern!r}; choose one of {', '.join(PATTERNS)}")
