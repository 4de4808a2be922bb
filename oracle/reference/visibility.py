"""The ``visibility`` channel group: the lit fraction of each pixel's camera samples (hard
shadows of the scene's light, or of an area light's punctual proxy), with its standard error
floored at the binomial floor (a pixel whose samples all agree is not known exactly)."""

from __future__ import annotations

import numpy as np

from .group import SampledGroup, binary_stderr, floored_stderr, mean_variance, stderr_summary

__all__ = ["VisibilityGroup"]


class VisibilityGroup(SampledGroup):
    """Sums of the samples' shadow-ray visibility (1 = lit; sky samples are lit)."""

    name = "visibility"

    def __init__(self, npix: int, *, output: bool = True):
        super().__init__(npix, output=output)
        self.vis = np.zeros(npix)

    def sample_values(self, res, chunk, block):
        import drjit as dr

        return {"vis": (dr.select(res["lit"], 1.0, 0.0), dr.ReduceOp.Add)}

    def add(self, host, at):
        self.vis[at] += host["vis"]

    def mixed(self, n):
        """Pixels whose samples disagree (some lit, some not)."""
        return (self.vis > 0) & (self.vis < n)

    def finish(self, n, img):
        return {"visibility": img(self.vis / n), "visibility_stderr": img(self.stderr(n))}

    def summary(self, channels):
        return stderr_summary(channels, "visibility_stderr")

    def refine_stderr(self, n):
        return binary_stderr(self.vis, n)

    def feature(self, n):
        return self.mixed(n), [self.vis > 0]

    def stderr(self, n):
        return floored_stderr(self.vis, n)

    def variance(self, n):
        return [mean_variance(self.vis, self.vis, n)]
