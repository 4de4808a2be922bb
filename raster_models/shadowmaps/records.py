"""The records a shadow-map technique and the shared engine exchange: partitions (where a
map goes), set-ups (how a pixel picks a map) and rendered maps."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..light_frame import Projection

__all__ = ["MapData", "Partition", "Setup"]


@dataclass
class Partition:
    """One shadow map: its projection (``None`` for an empty partition, Intel's sentinel
    that no geometry overlaps) and the view-depth interval ``[z_begin, z_end)`` it serves."""

    projection: Projection | None
    z_begin: float = -math.inf
    z_end: float = math.inf
    info: dict = field(default_factory=dict)


@dataclass
class Setup:
    """Where a technique puts its maps and how a pixel picks one.

    ``selection``: ``single`` (one map), ``depth`` (by split depth: partition = number of
    interior ``z_end`` a pixel's view depth is at or beyond), ``projection`` (first map whose
    texture contains the pixel), ``cube`` (point light: face of the major axis).
    ``outside``: what depth selection does with a pixel outside ``[z_begin_0, z_end_last)``:
    ``clamp`` to the first/last partition (MJP), or ``discard`` (Intel: no light).
    ``depth_extent_reference``: light-space depth extent the EVSM exponents refer to when
    ``evsm_light_space`` is on.
    """

    partitions: list[Partition]
    selection: str = "single"
    outside: str = "clamp"
    blend_band: float = 0.0
    diagnostics: dict = field(default_factory=dict)
    compute_passes: int = 0
    readback_latency: int = 0
    depth_extent_reference: float = 1.0
    skip_rendering: bool = False


@dataclass
class MapData:
    """A rendered map: stored depth ``(R, R)`` float32 and, for VSM/EVSM, its moments.

    ``texels``: the same stored depths as a flat Dr.Jit ``Float`` array (row-major), which
    the compare filters read; for a map finished in the ray-casting kernel ``depth`` is a
    NumPy view of this array's memory, so the two never disagree. ``None`` for VSM/EVSM
    maps (their lookups read ``moments``).
    """

    depth: np.ndarray
    moments: np.ndarray | None
    exponents: tuple
    texels_covered: int
    z_start: float
    texels: object = None
