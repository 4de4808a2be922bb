"""The reference's ``front_coverage``: the coverage of each pixel's front-most primitive.

``coverage`` counts the samples that hit any geometry: 1 everywhere on a scene with a
backdrop, so its metrics say nothing about the anti-aliasing of the silhouettes in front of
it. ``front_coverage`` counts the samples whose nearest surface is the shape seen through the
pixel centre (the sky counting as one): every silhouette, against the sky or another surface,
is an edge of it. The models compute it with the same rule
(:func:`raster_models.aa.common.front_coverage`), so the two compare directly; on silhouettes
against the sky it is the geometry coverage where the centre sees geometry and one minus it
where the centre sees the sky, with the same absolute errors.

The centre's shape is traced once per pixel (exact, no noise), so each sample is a Bernoulli
trial: the estimate's standard error is the binomial one, floored as ``coverage``'s is.

The ``coverage_exact`` group holds the same two quantities without noise for triangle scenes
(:mod:`scenes.geometry.exact_coverage`), and :func:`exact_channels` cross-checks the sampled ones
against it in every reference's provenance.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ...scenes import backend
from ...scenes.backend.raycast import trace_film_dr
from .group import SampledGroup, binary_stderr, floored_stderr, mean_variance, stderr_summary
from .settings import ExactBudget

__all__ = ["CROSS_CHECK_Z", "CoverageGroup", "centre_shapes", "exact_channels", "front_hits"]

#: Pixel centres per Dr.Jit launch.
CENTRE_CHUNK = 1 << 22


def centre_shapes(loaded) -> np.ndarray:
    """``(H*W,)`` int32 shape index seen through each pixel centre (-1: sky)."""
    mi = backend.mitsuba()
    import drjit as dr

    w, h = loaded.width, loaded.height
    out = np.empty(w * h, dtype=np.int32)
    for start in range(0, w * h, CENTRE_CHUNK):
        idx = dr.arange(mi.UInt32, start, min(w * h, start + CENTRE_CHUNK))
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(loaded, x, y, color=False, albedo=False)
        out[start : start + dr.width(idx)] = np.array(res["shape"], dtype=np.int32)
    return out


def front_hits(shape, centre: np.ndarray, block: int):
    """Dr.Jit ``1.0`` where a sample's shape (``shape``, Int32, ``block`` consecutive samples
    per pixel) is its pixel's centre shape (``centre``: per pixel of the launch), else 0."""
    mi = backend.mitsuba()
    import drjit as dr

    pixel = dr.arange(mi.UInt32, dr.width(shape)) // block
    same = dr.gather(mi.Int32, mi.Int32(centre), pixel) == shape
    return dr.select(same, 1.0, 0.0)


class CoverageGroup(SampledGroup):
    """Sums of the samples that hit any geometry (``coverage``) and, with output, of those
    whose nearest surface is the pixel centre's shape (``front_coverage``; the centres are
    traced when the group is made). Without output (an adaptive render that did not ask
    for coverage) only the first is kept, for the refinement."""

    name = "coverage"

    def __init__(self, npix: int, *, loaded=None, output: bool = True):
        super().__init__(npix, output=output)
        self.cov = np.zeros(npix)
        #: shape seen through each pixel centre (None: ``front_coverage`` not asked for)
        self.centre = centre_shapes(loaded) if output else None
        self.front = np.zeros(npix if output else 0)

    def sample_values(self, res, chunk, block):
        import drjit as dr

        out = {"cov": (dr.select(res["valid"], 1.0, 0.0), dr.ReduceOp.Add)}
        if self.centre is not None:
            out["front"] = (front_hits(res["shape"], self.centre[chunk], block), dr.ReduceOp.Add)
        return out

    def add(self, host, at):
        self.cov[at] += host["cov"]
        if self.centre is not None:
            self.front[at] += host["front"]

    def finish(self, n, img):
        return {
            "coverage": img(self.cov / n),
            "coverage_stderr": img(floored_stderr(self.cov, n)),
            "front_coverage": img(self.front / n),
            "front_coverage_stderr": img(floored_stderr(self.front, n)),
        }

    def summary(self, channels):
        return stderr_summary(channels, "coverage_stderr")

    def refine_stderr(self, n):
        se = binary_stderr(self.cov, n)
        if self.centre is not None:
            se = np.maximum(se, binary_stderr(self.front, n))
        return se

    def feature(self, n):
        return (self.cov > 0) & (self.cov < n), [self.cov > 0]

    def stderr(self, n):
        return floored_stderr(self.cov, n)

    def variance(self, n):
        return [mean_variance(self.cov, self.cov, n)]


#: Pixels of the cross-check whose |z| exceeds this count as disagreements (a 4-sigma
#: event has probability 6e-5 per pixel under the null: a few per 1080p image).
CROSS_CHECK_Z = 4.0


def _say_once(loaded, exc, line: str) -> None:
    """Print ``line`` on stderr once per view (the noise floor's reference of the same view
    is refused for the same reason without a second line)."""
    said = loaded.memo.setdefault("exact_coverage_said", set())
    view = getattr(exc, "view", None)
    if view is None or (view, line) not in said:
        print(line, file=sys.stderr)
        said.add((view, line))


def _no_exact(loaded, record: dict) -> tuple[dict, dict]:
    """The ``coverage_exact`` group claiming nothing exact (``valid`` 0 everywhere: coverage
    is then scored against the Monte Carlo truth, see ``coverage_truth``) and its record."""
    zero = np.zeros((loaded.height, loaded.width), np.float32)
    channels = {"coverage_exact": zero, "front_coverage_exact": zero}
    channels["coverage_exact_valid"] = zero
    return channels, {"valid_fraction": 0.0, **record}


def _spent(loaded, clock: ExactBudget) -> tuple[dict, dict]:
    """A view of a command whose exact budget is spent: skipped (one line for the scene,
    none after a line of an earlier view already told the budget's story)."""
    said = loaded.memo.setdefault("exact_coverage_said", set())
    if not said:
        said.add(("spent", clock.seconds))
        print(
            f"raster-oracle: coverage_exact skipped for {loaded.name!r} from frame "
            f"{loaded.frame} on: the command's exact budget ({clock.seconds:g} s, "
            "--exact-budget) is spent; coverage is scored against the Monte Carlo truth",
            file=sys.stderr,
        )
    record = {"decision": "skipped: over budget", "budget_seconds": clock.seconds}
    return _no_exact(loaded, {**record, "budget_left_seconds": 0.0})


def _budget_record(clock: ExactBudget, spent_before: float) -> dict:
    """The budget in a view's record: the command's seconds and, when earlier views had
    spent some, what was left for this one."""
    out = {"budget_seconds": clock.seconds}
    if spent_before > 0:
        out["budget_left_seconds"] = max(0.0, clock.seconds - spent_before)
    return out


def exact_channels(
    loaded, centre: np.ndarray | None, sampled: dict, *, budget: float | None = None
) -> tuple[dict, dict]:
    """The ``coverage_exact`` group of ``loaded`` (:mod:`scenes.geometry.exact_coverage`) and its
    provenance record; with the Monte Carlo channels in ``sampled`` (``coverage`` and
    ``front_coverage`` with their standard errors), the record holds the z-scores of their
    difference from the exact channels on the valid pixels (mean, RMS, largest, fraction
    beyond :data:`CROSS_CHECK_Z`): a sampling bug shows up in every reference."""
    import shapely

    from ...scenes.geometry.exact_coverage import NotExact, OutOfTime, OverBudget, exact_coverage

    if centre is None:
        centre = centre_shapes(loaded)
    clock = budget if isinstance(budget, ExactBudget) or budget is None else ExactBudget(budget)
    kw, spent_before, t0 = {}, 0.0, time.perf_counter()
    if clock is not None:
        spent_before = clock.spent
        kw = {"budget": clock.left(), "deadline": t0 + clock.left()}
        if clock.spent > 0.0 and clock.left() <= 0.0:  # earlier views spent it all
            return _spent(loaded, clock)
    try:
        ex = exact_coverage(loaded, centre, **kw)
    except OverBudget as exc:
        # too costly for what is left: skipped with one line, Monte Carlo truth instead
        _say_once(
            loaded,
            exc,
            f"raster-oracle: coverage_exact skipped for {loaded.name!r} frame {loaded.frame}: "
            f"{exc} (--exact-budget); coverage is scored against the Monte Carlo truth",
        )
        decision = {"decision": "skipped: over budget", **_budget_record(clock, spent_before)}
        return _no_exact(loaded, {**decision, "estimate": exc.estimate})
    except OutOfTime as exc:
        # the deadline: the estimate was wrong for this content; stopped, said, Monte Carlo
        if not hasattr(exc, "used"):  # the view's first stop (its noise floor re-raises it)
            exc.used = spent_before + (time.perf_counter() - t0)
        used = exc.used
        _say_once(
            loaded,
            exc,
            f"raster-oracle: coverage_exact stopped for {loaded.name!r} frame {loaded.frame}: "
            f"over budget after {used:.1f} s of exact work (--exact-budget "
            f"{clock.seconds:g}); coverage is scored against the Monte Carlo truth",
        )
        record = {"decision": f"over budget after {used:.1f} s"}
        record["seconds"] = time.perf_counter() - t0
        if getattr(exc, "estimate", None) is not None:
            record["estimate"] = exc.estimate
        return _no_exact(loaded, {**record, **_budget_record(clock, spent_before)})
    except NotExact as exc:
        # geometry float64 cannot clip exactly (coordinates of 1e30): said, not passed off
        _say_once(
            loaded,
            exc,
            f"raster-oracle: coverage_exact not exact for {loaded.name!r} frame "
            f"{loaded.frame}: {exc}; coverage is scored against the Monte Carlo truth",
        )
        return _no_exact(loaded, {"decision": f"not exact: {exc}"})
    except shapely.errors.GEOSException as exc:
        # a polygon operation that failed on degenerate input: nothing is claimed exact
        return _no_exact(loaded, {"error": f"polygon operation failed: {exc}"})
    finally:
        if clock is not None:
            clock.charge(time.perf_counter() - t0)
    f32 = np.float32
    channels = {
        "coverage_exact": ex.coverage.astype(f32),
        "front_coverage_exact": ex.front_coverage.astype(f32),
        "coverage_exact_valid": ex.valid.astype(f32),
    }
    record = {**ex.stats, "valid_fraction": float(ex.valid.mean())}
    if clock is not None:
        record.update(decision="computed", **_budget_record(clock, spent_before))
    checks = {}
    for name, exact in (("coverage", ex.coverage), ("front_coverage", ex.front_coverage)):
        if name not in sampled:
            continue
        se = np.asarray(sampled[f"{name}_stderr"], np.float64)[ex.valid]
        z = (np.asarray(sampled[name], np.float64)[ex.valid] - exact[ex.valid]) / se
        checks[name] = {
            "pixels": int(z.size),
            "z_mean": float(z.mean()) if z.size else None,
            "z_rms": float(np.sqrt(np.mean(z * z))) if z.size else None,
            "z_max_abs": float(np.abs(z).max()) if z.size else None,
            f"fraction_abs_z_over_{CROSS_CHECK_Z:g}": float(np.mean(np.abs(z) > CROSS_CHECK_Z))
            if z.size
            else None,
        }
    if checks:
        record["monte_carlo_vs_exact"] = checks
    return channels, record
