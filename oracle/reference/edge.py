"""The ``edge`` channel group: 1 where a pixel's samples disagree on the shape they hit or on
its visibility (a silhouette or a shadow edge crosses the pixel), else 0.

The shape range of the samples (smallest and largest Mitsuba shape index, -1 for the sky) is
also what the adaptive passes compare between neighbours (:mod:`oracle.reference.adaptive`).
"""

from __future__ import annotations

import numpy as np

from .group import SampledGroup

__all__ = ["EdgeGroup"]


class EdgeGroup(SampledGroup):
    """Per-pixel smallest and largest shape index of the samples; the edge reads the
    visibility group's sums (``visibility``, kept without output when not asked for)."""

    name = "edge"

    def __init__(self, npix: int, *, visibility, output: bool = True):
        super().__init__(npix, output=output)
        self.visibility = visibility
        self.smin = np.full(npix, np.iinfo(np.int32).max, dtype=np.int64)
        self.smax = np.full(npix, np.iinfo(np.int32).min, dtype=np.int64)

    def sample_values(self, res, chunk, block):
        import drjit as dr

        return {"smin": (res["shape"], dr.ReduceOp.Min), "smax": (res["shape"], dr.ReduceOp.Max)}

    def add(self, host, at):
        self.smin[at] = np.minimum(self.smin[at], host["smin"])
        self.smax[at] = np.maximum(self.smax[at], host["smax"])

    def finish(self, n, img):
        return {"edge": img((self.smin != self.smax) | self.visibility.mixed(n))}

    def feature(self, n):
        return self.smin != self.smax, [self.smin, self.smax]
