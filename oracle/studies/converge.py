"""Oracle convergence: how the reference's true error falls with samples per pixel.

``raster-oracle converge SCENE`` renders the visibility and coverage reference at 1, 2, 4, ...
``max_spp`` samples per pixel (and once with adaptive sampling) and compares each with a
``truth_spp`` reference of another seed: the true error (RMS and maximum over pixels), the
mean and RMS standard error the reference reports for itself, the rays cast and the wall time.
A least-squares power law ``error = a * spp^slope`` is fitted to the true RMS error, and the
spp needed for a target error is read off the measured ladder (the smallest spp from which
on every measured rendering meets it) and off the fit.

What to expect (closed form): the oracle's samples are stratified (one jittered sample per
cell of an ``m x n`` grid), so a pixel whose content is constant has no error at all and a
pixel crossed by one straight edge has variance ``O(N^-3/2)`` (Mitchell 1996): the true RMS
error of a scene whose error lives on straight shadow and silhouette edges (``plate``) falls
as ``spp^-3/4``, faster than the ``spp^-1/2`` of independent samples. The reported standard
error uses the sample variance as if samples were independent, so it falls as ``spp^-1/2``:
it bounds the true error from above, increasingly conservatively.

Under an area light the ``soft`` group is rendered and compared as well (``soft_visibility``
and ``light_fraction``: :mod:`oracle.reference.soft`): its cost per camera sample is 16 shadow
rays, and its error lives in penumbrae, smooth functions sampled by stratified light samples.

References
----------
.. [1] D. P. Mitchell, "Consequences of Stratified Sampling in Graphics", SIGGRAPH 1996,
   doi:10.1145/237170.237265 (variance of jittered sampling at an edge: O(N^-1.5)).
.. [2] A. B. Owen, *Monte Carlo theory, methods and examples*, 2013, ch. 10.3 (stratified
   sampling of discontinuous integrands).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from ...reports.sections import converge_section
from ..errors import InputError
from .output import write_study

__all__ = [
    "CONVERGE_CHANNELS",
    "ConvergeError",
    "JITTER_EDGE_SLOPE",
    "SOFT_CHANNELS",
    "fit_power_law",
    "run_converge",
    "spp_for_target",
    "spp_ladder",
]

#: Channels rendered and compared.
CONVERGE_CHANNELS = ("visibility", "coverage")
#: ... and, under an area light, these too (the ``soft`` group).
SOFT_CHANNELS = ("soft_visibility", "light_fraction")
#: Slope of the RMS error of jittered stratified sampling where the error lives on straight
#: edges: variance O(N^-1.5) (Mitchell 1996), so RMS error O(N^-0.75).
JITTER_EDGE_SLOPE = -0.75
#: Number of combined standard errors a difference from the truth is checked against.
Z_BOUND = 3.0
#: Seed offset of the truth (independent of every ladder rendering's seed).
TRUTH_SEED_OFFSET = 1000


class ConvergeError(InputError):
    """Bad convergence settings (spp ladder, target, truth)."""


def spp_ladder(max_spp: int) -> list[int]:
    """``1, 2, 4, ...`` up to and including ``max_spp`` (a power of two or not)."""
    if isinstance(max_spp, bool) or not isinstance(max_spp, int | np.integer) or max_spp < 1:
        raise ConvergeError(f"max_spp must be an integer >= 1, got {max_spp!r}")
    out, spp = [], 1
    while spp < max_spp:
        out.append(spp)
        spp *= 2
    out.append(int(max_spp))
    return out


def fit_power_law(spp, error) -> dict:
    """Least-squares fit of ``log error = log a + slope * log spp`` (positive errors only).

    Returns ``{"a", "slope", "points"}``; ``slope`` is None with fewer than two points.
    """
    s = np.asarray(spp, dtype=np.float64)
    e = np.asarray(error, dtype=np.float64)
    keep = (s > 0) & (e > 0) & np.isfinite(e)
    if keep.sum() < 2:
        return {"a": None, "slope": None, "points": int(keep.sum())}
    slope, intercept = np.polyfit(np.log(s[keep]), np.log(e[keep]), 1)
    return {"a": float(math.exp(intercept)), "slope": float(slope), "points": int(keep.sum())}


def spp_for_target(spp, error, target: float) -> int | None:
    """Smallest measured spp from which on every measured rendering has ``error <= target``.

    Monotone in ``target``: a larger target is met from the same spp or an earlier one.
    None when the last (largest) rendering misses it.
    """
    if not (isinstance(target, float | int) and math.isfinite(target) and target > 0):
        raise ConvergeError(f"target error must be a finite number > 0, got {target!r}")
    s = list(spp)
    e = list(error)
    best = None
    for k in range(len(s) - 1, -1, -1):
        if e[k] <= target:
            best = s[k]
        else:
            break
    return best


def _groups(loaded) -> tuple[str, ...]:
    """The channel groups rendered: :data:`CONVERGE_CHANNELS`, plus ``soft`` under an area
    light."""
    return CONVERGE_CHANNELS + (("soft",) if loaded.light.is_area else ())


def _errors(ch: dict, truth: dict) -> dict:
    out = {}
    for c in CONVERGE_CHANNELS + tuple(c for c in SOFT_CHANNELS if c in truth):
        d = ch[c].astype(np.float64) - truth[c].astype(np.float64)
        se = ch[f"{c}_stderr"].astype(np.float64)
        both = np.sqrt(se * se + truth[f"{c}_stderr"].astype(np.float64) ** 2)
        out[c] = {
            "rms": float(np.sqrt(np.mean(d * d))),
            "max": float(np.abs(d).max()),
            "stderr_mean": float(se.mean()),
            "stderr_rms": float(np.sqrt(np.mean(se * se))),
            # pixels whose difference from the truth exceeds 3 combined reported stderrs
            # (Chebyshev allows 1/9 for any distribution; a calibrated stderr far fewer)
            "beyond_3_stderr": float(np.mean(np.abs(d) > Z_BOUND * both)),
        }
    return out


def _check_settings(max_spp: int, truth_spp: int | None, targets) -> tuple[list[int], int]:
    """The spp ladder and the truth's spp; raises :class:`ConvergeError` on bad settings."""
    ladder_spp = spp_ladder(max_spp)
    truth_spp = int(truth_spp if truth_spp is not None else 4 * max_spp)
    if truth_spp <= max_spp:
        raise ConvergeError(f"truth spp ({truth_spp}) must be larger than max spp ({max_spp})")
    for t in targets:
        spp_for_target([1], [0.0], t)  # validates
    return ladder_spp, truth_spp


def _render_ladder(loaded, ladder_spp: list[int], truth: dict, *, seed: int, say) -> list[dict]:
    """One rendering per spp of the ladder, compared with the truth."""
    from ..reference.render import ReferenceSettings, render_reference

    ladder = []
    for spp in ladder_spp:
        settings = ReferenceSettings(spp=spp, seed=seed, channels=_groups(loaded))
        ch, st = render_reference(loaded, settings, quiet=True)
        rec = {
            "spp": spp,
            "rays": st["rays_cast"],
            "seconds": st["wall_seconds"],
            **_errors(ch, truth),
        }
        ladder.append(rec)
        say(
            f"  {spp:>6} spp: visibility RMS {rec['visibility']['rms']:.2e} "
            f"max {rec['visibility']['max']:.3f}, reported stderr "
            f"{rec['visibility']['stderr_rms']:.2e} ({st['wall_seconds']:.2f} s)"
        )
    return ladder


def _render_adaptive(loaded, truth: dict, *, target: float, max_spp: int, seed: int) -> dict:
    """One adaptive rendering (16 spp first pass, up to ``max_spp``) against the truth."""
    from ..reference.render import ReferenceSettings, render_reference

    settings = ReferenceSettings(
        adaptive=True,
        adaptive_spp=16,
        target_stderr=target,
        max_spp=max_spp,
        seed=seed,
        channels=_groups(loaded),
    )
    ch, st = render_reference(loaded, settings, quiet=True)
    npix = loaded.width * loaded.height
    return {
        "target_stderr": target,
        "mean_spp": st["adaptive"]["samples"] / npix,
        "max_spp_used": st["adaptive"]["max_spp_used"],
        "rays": st["rays_cast"],
        "seconds": st["wall_seconds"],
        **_errors(ch, truth),
    }


def _fit_ladder(ladder: list[dict], truth_spp: int) -> dict:
    """Power laws of the true RMS error and the reported stderr RMS, per channel.

    The fit leaves out spp < 4 (1 and 2 samples are one and two strata: the stratified
    asymptote starts with a 2x2 grid) and spp above a quarter of the truth's, whose error is
    the closest to the truth's own noise.
    """
    use = [r for r in ladder if 4 <= r["spp"] and r["spp"] * 4 <= truth_spp]
    spp = [r["spp"] for r in use]
    return {
        c: {
            "true_rms": fit_power_law(spp, [r[c]["rms"] for r in use]),
            "reported_stderr_rms": fit_power_law(spp, [r[c]["stderr_rms"] for r in use]),
            "spp_range": [use[0]["spp"], use[-1]["spp"]] if use else None,
        }
        for c in CONVERGE_CHANNELS + SOFT_CHANNELS
        if c in ladder[0]
    }


def _spp_on_fit(fit: dict, error: float) -> float | None:
    """The spp at which the fitted power law reaches ``error`` (None: no falling fit)."""
    if fit["slope"] is None or not fit["slope"] < 0 or not error > 0:
        return None
    return float((error / fit["a"]) ** (1.0 / fit["slope"]))


def _adaptive_saving(adaptive: dict, fit: dict) -> dict:
    """``adaptive`` with the uniform spp of equal fitted true RMS and the samples saved."""
    equiv = _spp_on_fit(fit["visibility"]["true_rms"], adaptive["visibility"]["rms"])
    saving = equiv / adaptive["mean_spp"] if equiv is not None else None
    return {**adaptive, "uniform_spp_same_rms_fit": equiv, "uniform_over_adaptive_samples": saving}


def _target_spp(targets, ladder: list[dict], fit: dict) -> list[dict]:
    """The spp each target true RMS error needs: on the measured ladder and on the fit."""
    spps = [r["spp"] for r in ladder]
    rms = [r["visibility"]["rms"] for r in ladder]
    return [
        {
            "target_rms": float(t),
            "spp_measured": spp_for_target(spps, rms, float(t)),
            "spp_fitted": _spp_on_fit(fit["visibility"]["true_rms"], float(t)),
        }
        for t in targets
    ]


def run_converge(
    scene: str,
    *,
    out: Path | None = None,
    max_spp: int = 4096,
    truth_spp: int | None = None,
    targets: tuple[float, ...] = (0.01,),
    adaptive: bool = True,
    adaptive_target: float = 0.01,
    width: int | None = None,
    height: int | None = None,
    seed: int = 0,
    quiet: bool = True,
    echo=None,
) -> dict:
    """Measure the oracle's convergence on ``scene``; write ``out/converge.json`` and
    ``out/converge.html`` if ``out`` is given.

    Parameters
    ----------
    scene : built-in name or Mitsuba XML path (or a loaded scene).
    max_spp : largest spp of the ladder ``1, 2, 4, ..., max_spp``.
    truth_spp : spp of the truth (default ``4 * max_spp``), seed ``seed + 1000``.
    targets : true RMS visibility errors (in [0, 1] visibility units) to find the spp for.
    adaptive : also render once with adaptive sampling (16 spp first pass, target
        ``adaptive_target``, at most ``max_spp``).

    Returns
    -------
    dict (JSON-serialisable): ``ladder`` (one record per spp: true RMS/max error, reported
    stderr mean/RMS per channel, rays, seconds), ``adaptive``, ``fit`` (power law per
    channel), ``targets`` (spp needed per target, measured and fitted), ``truth``.
    """
    from ... import scenes
    from ..reference.render import ReferenceSettings, render_reference

    ladder_spp, truth_spp = _check_settings(max_spp, truth_spp, targets)
    loaded = scene if hasattr(scene, "mi_scene") else scenes.load(scene, width=width, height=height)
    say = echo or (lambda *_: None)
    t0 = time.perf_counter()
    truth_settings = ReferenceSettings(
        spp=truth_spp, seed=seed + TRUTH_SEED_OFFSET, channels=_groups(loaded)
    )
    truth, tstats = render_reference(loaded, truth_settings, quiet=quiet)
    say(f"converge {loaded.name}: truth {truth_spp} spp ({tstats['wall_seconds']:.1f} s)")
    ladder = _render_ladder(loaded, ladder_spp, truth, seed=seed, say=say)
    fit = _fit_ladder(ladder, truth_spp)
    adaptive_rec = None
    if adaptive and max_spp >= 16:
        adaptive_rec = _render_adaptive(
            loaded, truth, target=adaptive_target, max_spp=max_spp, seed=seed
        )
        adaptive_rec = _adaptive_saving(adaptive_rec, fit)
    data = {
        "schema": "raster-oracle.studies.converge/1",
        "scene": loaded.provenance(),
        "resolution": [loaded.width, loaded.height],
        "channels": list(CONVERGE_CHANNELS) + [c for c in SOFT_CHANNELS if loaded.light.is_area],
        "seed": seed,
        "truth": {
            "spp": truth_spp,
            "seed": seed + TRUTH_SEED_OFFSET,
            "rays": tstats["rays_cast"],
            "seconds": tstats["wall_seconds"],
            "visibility_stderr_mean": tstats["visibility_stderr_mean"],
            "coverage_stderr_mean": tstats["coverage_stderr_mean"],
        },
        "ladder": ladder,
        "adaptive": adaptive_rec,
        "fit": fit,
        "expected_slope": {
            "true_rms": JITTER_EDGE_SLOPE,
            "reported_stderr_rms": -0.5,
            "why": "jittered stratified samples: O(N^-1.5) variance at straight edges "
            "(Mitchell 1996); the reported stderr treats samples as independent",
        },
        "targets": _target_spp(targets, ladder, fit),
        "wall_seconds": time.perf_counter() - t0,
    }
    if out is not None:
        section = converge_section(data)
        title = f"raster-oracle converge {data['scene'].get('name', '')}"
        write_study(out, name="converge", data=data, section=section, title=title)
    return data
