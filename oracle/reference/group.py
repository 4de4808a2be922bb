"""The contract between the reference's sampling loop and its channel groups.

As in Mitsuba 3's integrators, where a base class owns the loop and each integrator overrides
one method, :mod:`oracle.reference.render` owns the loop (launches, tracing, per-pixel
reductions, adaptive passes) and each sampled channel group owns, in its own module, the
per-sample values it sums, its running sums, its standard errors and its output images:

- ``visibility`` (:mod:`.visibility`), ``coverage`` and ``front_coverage``
  (:mod:`.coverage`), ``color`` (:mod:`.color`), ``soft`` (:mod:`.soft`), ``edge``
  (:mod:`.edge`): subclasses of :class:`SampledGroup`;
- the pixel-centre groups (``id``, ``depth``, ``position``, ``normal``, ``albedo``,
  ``tangent32``: :mod:`.gbuffer`; ``motion``: :mod:`.motion`) and ``coverage_exact``
  (:mod:`.coverage`) take no samples and are plain functions of the scene.

A group may be kept without output (``output=False``): the adaptive passes read visibility,
coverage and the shape range of every pixel whatever was asked for, and ``edge`` reads the
visibility sums. The sample count of each pixel is the loop's (:class:`Accumulators`).
"""

from __future__ import annotations

import numpy as np

from ...metrics.stats import binomial_stderr_floor

__all__ = [
    "Accumulators",
    "SampledGroup",
    "binary_stderr",
    "floored_stderr",
    "mean_variance",
    "sample_stderr",
    "stderr_summary",
]


def sample_stderr(s: np.ndarray, s2: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``sqrt(s^2 / N)`` of a pixel mean from the sums ``s``, ``s2`` of its ``n`` samples,
    with the unbiased sample variance (0 where n <= 1); computed in place (a 1080p colour
    reference spent 2 % of its time here). ``s`` may be ``(..., npix)``, ``n`` ``(npix,)``."""
    n = np.broadcast_to(n, s.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        var = s * s
        var /= n
        np.subtract(s2, var, out=var)
        var /= n - 1
        var /= n
        np.maximum(var, 0.0, out=var)
        np.sqrt(var, out=var)
    var[n <= 1] = 0.0
    return var


def floored_stderr(hits: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Standard error of a binary quantity's pixel mean from its ``hits`` (0/1 samples, so
    ``s2 == s``): the sample one, floored at the binomial floor
    (:func:`metrics.stats.binomial_stderr_floor`)."""
    return np.maximum(sample_stderr(hits, hits, n), binomial_stderr_floor(n))


def binary_stderr(hits: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Standard error of a binary pixel quantity from ``hits`` of ``n`` samples (Jeffreys).

    ``sqrt(p (1 - p) / n)`` with ``p = (min(hits, n - hits) + 1/2) / (n + 1)``, the
    posterior mean of the rarer outcome: the binomial floor when all samples agree, and
    never below it when a feature was seen only a few times (the plain sample variance
    of 1 hit in 128 samples claims 0.008 where a feature covering 6 % of the pixel is still
    likely).
    """
    p = (np.minimum(hits, n - hits) + 0.5) / (n + 1.0)
    return np.sqrt(p * (1.0 - p) / n)


def mean_variance(s: np.ndarray, s2: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Per-pixel sample variance from the sums (``n`` at least 2)."""
    return (s2 - s**2 / n) / (n - 1)


def stderr_summary(channels: dict, name: str) -> dict:
    """``{name}_mean`` and ``{name}_max`` of a standard-error channel."""
    return {
        f"{name}_mean": float(channels[name].mean()),
        f"{name}_max": float(channels[name].max()),
    }


class SampledGroup:
    """One channel group's share of the sampled passes.

    Per launch the loop asks :meth:`sample_values` for the Dr.Jit per-sample values to
    reduce per pixel (``name -> (values, dr.ReduceOp)``; sums are float64, a ``Min``/``Max``
    keeps its type) and hands the host results to :meth:`add`. At the end :meth:`finish`
    makes the output images and :meth:`summary` the record's figures. The adaptive passes
    ask :meth:`refine_stderr` (the standard error a pixel near a feature refines on),
    :meth:`refine_anywhere` (pixels to refine wherever they are), :meth:`feature` (what the
    samples show of an edge), :meth:`stderr` (what the record reports as achieved) and
    :meth:`variance` (for the uniform spp of the same error). The defaults contribute nothing.
    """

    #: The name of the group (a key of ``CHANNEL_GROUPS``).
    name = ""

    def __init__(self, npix: int, *, output: bool = True):
        self.npix = npix
        self.output = output

    def sample_values(self, res: dict, chunk: np.ndarray, block: int) -> dict:
        return {}

    def add(self, host: dict, at) -> None:
        """Add the reduced sums ``host`` of the pixels ``at`` (a slice or an index array)."""

    def finish(self, n: np.ndarray, img) -> dict:
        """Output channels (``img`` makes an ``(H, W)`` float32 image of a per-pixel array)."""
        return {}

    def summary(self, channels: dict) -> dict:
        return {}

    def refine_stderr(self, n: np.ndarray) -> np.ndarray | None:
        return None

    def refine_anywhere(self, n: np.ndarray, target: float) -> np.ndarray | None:
        return None

    def feature(self, n: np.ndarray) -> tuple[np.ndarray | None, list]:
        """``(own, parts)``: where the pixel's own samples disagree (None: no opinion), and
        per-pixel arrays of what they agree on (compared with the neighbours')."""
        return None, []

    def stderr(self, n: np.ndarray) -> np.ndarray | None:
        return None

    def variance(self, n: np.ndarray) -> list:
        return []


class Accumulators:
    """The loop's per-pixel state: the sample count ``n`` (float64) and the groups in the
    order their channels are written, by name."""

    def __init__(self, npix: int, groups: dict[str, SampledGroup], *, color: bool, phases=None):
        self.npix = npix
        self.n = np.zeros(npix)
        self.groups = groups
        #: whether the samples are shaded (the colour group is kept)
        self.color = color
        #: :class:`oracle.phases.Phases` of a profiled render (None: no profiling, no syncs)
        self.phases = phases
        #: rays that stopped at the alpha layer bound (alpha-tested scenes; reference.json)
        self.alpha_bound_rays = 0

    def sample_values(self, res: dict, chunk: np.ndarray, block: int) -> dict:
        out = {}
        for g in self.groups.values():
            out.update(g.sample_values(res, chunk, block))
        return out

    def add(self, host: dict, at, block: int) -> None:
        self.n[at] += block
        for g in self.groups.values():
            g.add(host, at)

    def finish(self, width: int, height: int) -> dict:
        def img(a):
            return np.asarray(a, dtype=np.float32).reshape(height, width)

        channels: dict[str, np.ndarray] = {}
        for g in self.groups.values():
            if g.output:
                channels.update(g.finish(self.n, img))
        return channels
