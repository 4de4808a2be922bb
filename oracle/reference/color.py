"""The ``color`` channel group: the box-filtered shaded image (linear radiance) and its
per-channel sample standard error.

The samples' radiance comes from the shading of :func:`scenes.backend.raycast.trace_film_dr`
(punctual lights) or from the area light's samples (:mod:`oracle.reference.soft`). The
standard error is the sample one, unfloored: a colour floor depends on the radiance a missed
feature could have, which the score's Z-test applies.
"""

from __future__ import annotations

import numpy as np

from .group import SampledGroup, sample_stderr

__all__ = ["ColorGroup"]


class ColorGroup(SampledGroup):
    """Planar ``(3, npix)`` sums of the samples' RGB and of its square (the layout Dr.Jit
    hands over: the sums add rows, not a transpose)."""

    name = "color"

    def __init__(self, npix: int, *, output: bool = True):
        super().__init__(npix, output=output)
        self.rgb = np.zeros((3, npix))
        self.rgb2 = np.zeros((3, npix))

    def sample_values(self, res, chunk, block):
        import drjit as dr

        c = res["color"]
        return {"rgb": (c, dr.ReduceOp.Add), "rgb2": (c * c, dr.ReduceOp.Add)}

    def add(self, host, at):
        self.rgb[:, at] += host["rgb"]
        self.rgb2[:, at] += host["rgb2"]

    def rgb_stderr(self, n):
        """``(3, npix)``."""
        return sample_stderr(self.rgb, self.rgb2, n)

    def finish(self, n, img):
        mean = self.rgb / n
        se = self.rgb_stderr(n)
        channels = {f"color.{c}": img(mean[i]) for i, c in enumerate("RGB")}
        channels.update({f"color_stderr.{c}": img(se[i]) for i, c in enumerate("RGB")})
        return channels

    def summary(self, channels):
        cs = np.stack([channels[f"color_stderr.{c}"] for c in "RGB"])
        return {"color_stderr_mean": float(cs.mean()), "color_stderr_max": float(cs.max())}

    def refine_anywhere(self, n, target):
        return self.rgb_stderr(n).max(axis=0) > target

    def stderr(self, n):
        return self.rgb_stderr(n).max(axis=0)

    def variance(self, n):
        return [np.max((self.rgb2 - self.rgb**2 / n) / (n - 1), 0)]
