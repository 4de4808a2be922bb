"""Ground-truth rendering: supersampled visibility, coverage and a box-filtered shaded image.

This module owns the sampling loop (launches, tracing, per-pixel reductions, the adaptive
passes); each channel group owns its sums, standard errors and images
(:mod:`oracle.reference.group`), the settings are :mod:`oracle.reference.settings`'s and the
sample positions :mod:`oracle.reference.sampling`'s.

Sub-pixel samples are stratified: ``spp = m * n`` with ``m >= n`` as close as possible, one
jittered sample per cell of an ``m x n`` grid over the pixel, jitter from a 6-round 32-bit TEA
hash of (pixel, sample, seed) (:func:`sample_jitter`), so results do not depend on chunking.
Every cell is used, so the estimate is unbiased for any ``spp`` (a prime ``spp`` stratifies
along x only).

Standard errors are ``sqrt(s^2 / N)`` with the unbiased sample variance ``s^2`` of the pixel's
``N`` samples (conservative for stratified samples), floored for the binary quantities
(visibility, coverage) at the binomial floor of :func:`metrics.stats.binomial_stderr_floor`
(Jeffreys: ``p = 0.5 / (N + 1)``, ``sqrt(p (1 - p) / N)``): a pixel whose samples all agree is
not known exactly, a feature smaller than the sample spacing may have been missed. The colour
standard error is the sample one (its floor depends on the radiance a missed feature could
have; the score's Z-test applies it).

With ``adaptive``, a first pass at ``adaptive_spp`` samples covers every pixel; then a pixel
refines (a further pass of as many samples again, doubling up to ``max_spp``) while it lies
near a feature and its standard error exceeds ``target_stderr``. Near a feature: the pixel or
one of its 3x3 neighbours shows an edge (its samples disagree on shape id, visibility or
coverage, or what they agree on differs from a neighbour's), dilated by one pixel; the
standard error is the Jeffreys binomial one (:func:`binary_stderr`: the floor when all samples
agree) and, with colour, the colour's sample one. A pixel's own standard error cannot see a
thin feature that all its samples missed, its neighbours' samples can: refinement spreads
along a feature from the pixels that caught it (stopped pixels rejoin when a neighbour shows
one), and pixels far from every feature stop after the first pass, reporting their floor.
Adaptive passes take points of a per-pixel scrambled Sobol (0, 2)-sequence
(:func:`sobol_sample`), so each doubling is a stratified net and so is the union.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ...raster_models.drjit import numpy_view
from ...scenes import backend
from ...scenes.backend.alpha_hit import MAX_ALPHA_LAYERS
from ...scenes.backend.raycast import trace_film_dr
from ..phases import maybe_phase
from .adaptive import adaptive_stats, binary_stderr, feature_mask, refine_mask
from .color import ColorGroup
from .coverage import CoverageGroup, exact_channels
from .edge import EdgeGroup
from .gbuffer import centre_channels, tangent32_channel
from .group import Accumulators
from .motion import motion_channels
from .sampling import jitter_key, sample_jitter, sobol_sample
from .settings import (
    ALL_CHANNELS,
    CENTRE_GROUPS,
    CHANNEL_GROUPS,
    EXACT_BUDGET_S,
    MAX_SEED,
    SAMPLED_GROUPS,
    ReferenceSettings,
    ReferenceSettingsError,
    available_memory,
    channel_names,
    check_memory,
    estimate_memory,
    grid_shape,
    samples_per_chunk,
)
from .soft import SoftGroup, light_samples, soft_samples
from .visibility import VisibilityGroup

# The settings and the sampling helpers are part of what a caller of render_reference uses.
__all__ = [
    "ALL_CHANNELS",
    "CHANNEL_GROUPS",
    "EXACT_BUDGET_S",
    "MAX_SEED",
    "ReferenceSettings",
    "ReferenceSettingsError",
    "available_memory",
    "binary_stderr",
    "block_sum",
    "channel_names",
    "estimate_memory",
    "feature_mask",
    "grid_shape",
    "make_accumulators",
    "render_reference",
    "sample_jitter",
    "sample_pass",
    "samples_per_chunk",
    "sobol_sample",
]

#: The record lists the groups' standard-error summaries in this order (that of every
#: reference since oracle version 6; the channels follow the groups' order).
SUMMARY_ORDER = ("visibility", "coverage", "soft", "color")


def make_accumulators(loaded, groups, *, adaptive: bool = False, phases=None) -> Accumulators:
    """The sampled groups a render of ``groups`` (channel group names) keeps, in the order
    their channels are written: those asked for, ``visibility`` for ``edge``, and for the
    adaptive passes ``visibility``, ``coverage`` and the shape range (``edge``) whatever was
    asked for (kept without output)."""
    groups = set(groups)
    npix = loaded.width * loaded.height
    keep = groups | ({"visibility", "coverage", "edge"} if adaptive else set())
    if "edge" in keep:
        keep.add("visibility")
    out: dict = {}
    if "visibility" in keep:
        out["visibility"] = VisibilityGroup(npix, output="visibility" in groups)
    if "coverage" in keep:
        out["coverage"] = CoverageGroup(npix, loaded=loaded, output="coverage" in groups)
    if "color" in keep:
        out["color"] = ColorGroup(npix)
    if "soft" in keep:
        out["soft"] = SoftGroup(npix)
    if "edge" in keep:
        out["edge"] = EdgeGroup(npix, visibility=out["visibility"], output="edge" in groups)
    return Accumulators(npix, out, color="color" in out, phases=phases)


def sample_pass(
    loaded,
    acc: Accumulators,
    pixels: np.ndarray,
    spp: int,
    offset: int,
    seed: int,
    progress,
    progressive: bool = False,
    launch: int | None = None,
) -> tuple[int, int]:
    """Trace ``spp`` stratified samples in each of ``pixels``; returns (primary, shadow) rays.

    With ``progressive`` the samples are points ``offset .. offset + spp - 1`` of each
    pixel's scrambled Sobol sequence (:func:`sobol_sample`), else a jittered ``m x n`` grid.

    A launch holds at most ``launch`` (default :data:`SAMPLES_PER_CHUNK`) samples: several
    pixels' samples, or, when one pixel has more, a block of one pixel's samples at a time,
    so memory is bounded for any ``spp``. Under an area light (colour or soft channels) each
    camera sample casts :func:`oracle.reference.soft.light_samples` shadow rays and a launch
    holds that many times fewer camera samples.
    """
    mi = backend.mitsuba()
    import drjit as dr

    width = loaded.width
    m, n = grid_shape(spp)
    launch = launch or samples_per_chunk()
    if _area_sampled(loaded, acc):
        launch = max(1, launch // light_samples(loaded.light))
    block = min(spp, launch)
    per_chunk = max(1, launch // block)
    bits = max(1, int(offset + spp - 1).bit_length())
    primary = shadow = 0
    for start in range(0, len(pixels), per_chunk):
        chunk = pixels[start : start + per_chunk]
        for s0 in range(0, spp, block):
            bsz = min(block, spp - s0)
            count = len(chunk) * bsz
            idx = dr.arange(mi.UInt32, count)
            local = idx // bsz
            s = idx - local * bsz + s0
            if int(chunk[-1]) - int(chunk[0]) == len(chunk) - 1:
                # a run of pixels: no upload of their indices; the first is opaque, so every
                # chunk reuses one compiled kernel
                pix = local + dr.opaque(mi.UInt32, int(chunk[0]))
            else:
                pix = dr.gather(mi.UInt32, mi.UInt32(chunk), local)
            if progressive:
                u, v = sobol_sample(pix, s + offset, seed, bits=bits)
            else:
                u, v = sample_jitter(pix, s + offset, seed)
                u = (mi.Float(s % m) + u) * (1.0 / m)
                v = (mi.Float(s // m) + v) * (1.0 / n)
            x = mi.Float(pix % width) + u
            y = mi.Float(pix // width) + v
            primary += count
            shadow += _accumulate(loaded, acc, chunk, x, y, bsz, keys=(pix, s + offset, seed))
            if progress is not None:
                progress.update(count)
    return primary, shadow


def _area_sampled(loaded, acc: Accumulators) -> bool:
    """Whether the samples integrate over an area light (its colour or soft channels)."""
    return loaded.light.is_area and (acc.color or "soft" in acc.groups)


def _accumulate(loaded, acc: Accumulators, chunk: np.ndarray, x, y, block: int, keys=None) -> int:
    """Trace the samples ``(x, y)`` (``block`` consecutive ones per pixel of ``chunk``) and
    add their sums to ``acc``; returns the shadow rays cast. ``keys``: the samples' ``(pixel,
    sample index, seed)``, which seed an area light's samples (:mod:`.soft`)."""
    import drjit as dr

    with maybe_phase(acc.phases, "record"):  # Python: recording the kernel's operations
        if _area_sampled(loaded, acc):
            res = _area_trace(loaded, acc, x, y, keys)
        else:
            res = trace_film_dr(loaded, x, y, color=acc.color, albedo=False)
        sums = acc.sample_values(res, chunk, block)
        for key in ("light_rays", "alpha_bound"):
            if key in res:
                sums[key] = (res[key], dr.ReduceOp.Add)
    return _reduce_and_add(acc, res, sums, chunk, block)


def _area_trace(loaded, acc: Accumulators, x, y, keys) -> dict:
    """:func:`trace_film_dr` with the area light's samples (:func:`.soft.soft_samples`):
    its soft values and area-lit colour replace the punctual proxy's colour."""
    import drjit as dr

    res = trace_film_dr(loaded, x, y, color=False, albedo=acc.color, keep_si=True)
    # the light samples gather the primary hits: trace them in a kernel of their own
    dr.eval(res["si"], res["valid"], res["normal"], res["to_eye"], res.get("albedo"))
    pix, sample, seed = keys
    res.update(soft_samples(loaded, res, pix, sample, jitter_key(pix, seed), color=acc.color))
    return res


def _reduce_and_add(acc: Accumulators, res: dict, sums: dict, chunk, block: int) -> int:
    """Evaluate the samples' values, reduce them per pixel and add them to ``acc``."""
    import drjit as dr

    # one kernel traces every sample; reductions then read the evaluated arrays. A profiled
    # render (acc.phases) waits at the end of each phase so its launches count there.
    ph = acc.phases
    with maybe_phase(ph, "trace+shade", sync=True):
        dr.eval(*[v for v, _ in sums.values()], res["shadow_tested"])
    with maybe_phase(ph, "reductions", sync=True):
        shadow_count = dr.count(res["shadow_tested"])
        outs = {k: block_sum(dr, op, v, block) for k, (v, op) in sums.items()}
        dr.eval(*outs.values(), shadow_count)
    with maybe_phase(ph, "transfer"):
        # numpy_view: a colour vector component by component (Dr.Jit's own conversion
        # compiles a packing kernel for every array length: the last, shorter chunk); sums
        # in float64, a Min/Max in its own type
        host = {
            k: np.asarray(
                numpy_view(v), dtype=np.float64 if sums[k][1] == dr.ReduceOp.Add else None
            )
            for k, v in outs.items()
        }
        shadow_tested = int(shadow_count[0])
        if "light_rays" in host:  # an area light's shadow rays, not its proxy's
            shadow_tested += int(round(float(host.pop("light_rays").sum())))
        if "alpha_bound" in host:  # rays stopped at the alpha layer bound
            acc.alpha_bound_rays += int(round(float(host.pop("alpha_bound").sum())))
    with maybe_phase(ph, "accumulate"):
        if len(chunk) and int(chunk[-1]) - int(chunk[0]) == len(chunk) - 1:
            chunk = slice(int(chunk[0]), int(chunk[-1]) + 1)  # a run of pixels: no fancy indexing
        acc.add(host, chunk, block)
    return shadow_tested


def block_sum(dr, op, values, block: int):
    """``dr.block_reduce`` of per-sample ``values``; float sums in float64. A float32 block
    sum rounds in an order set by the block size and the backend (CUDA reduces in a tree):
    a pixel's samples split over launches gave other bytes on an H200, and the standard
    error of a constant pixel, ``sqrt(s2 - s^2 / n)``, came out as that rounding (4e-6 or
    1.4e-6 instead of 0). In float64 the sums of float32 samples are exact up to 2^29 of
    them and rounded at 2^-53 beyond, whatever the order."""
    if op == dr.ReduceOp.Add and dr.type_v(values) == dr.VarType.Float32:
        return dr.block_reduce(op, dr.float64_array_t(type(values))(values), block, mode="symbolic")
    return dr.block_reduce(op, values, block, mode="evaluated")


def _refine(loaded, acc: Accumulators, settings: ReferenceSettings, passes: list, progress, launch):
    """Adaptive passes after the first: each doubles the samples of the pixels of
    :func:`oracle.reference.adaptive.refine_mask` (grouped by their current count, which
    differs once stopped pixels rejoin), until none is left; returns (primary, shadow) rays."""
    primary = shadow = 0
    while True:
        active = np.nonzero(refine_mask(acc, settings, loaded.width, loaded.height))[0]
        if len(active) == 0:
            return primary, shadow
        counts = acc.n[active]
        for n_k in np.unique(counts):
            group = active[counts == n_k].astype(np.uint32)
            spp_k = int(min(n_k, settings.max_spp - n_k))
            if progress is not None:
                progress.total += len(group) * spp_k
            p, s = sample_pass(
                loaded,
                acc,
                group,
                spp_k,
                int(n_k),
                settings.seed,
                progress,
                progressive=True,
                launch=launch,
            )
            primary, shadow = primary + p, shadow + s
            passes.append({"pixels": int(len(group)), "spp": spp_k})


def _progress(loaded, settings: ReferenceSettings, quiet: bool):
    """A progress bar, only on a terminal (in a CI log its carriage-return redraws are
    noise); None otherwise."""
    if quiet or not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    npix = loaded.width * loaded.height
    total = npix * (settings.adaptive_spp if settings.adaptive else settings.spp)
    return tqdm(
        total=total,
        unit="spl",
        unit_scale=True,
        desc=f"reference {loaded.name}",
        leave=False,
        mininterval=0.5,
    )


def render_reference(
    loaded,
    settings: ReferenceSettings,
    *,
    quiet: bool = False,
    samples_per_launch: int | None = None,
    phases=None,
):
    """Render the reference channels of ``loaded`` (its current camera frame), at most
    ``samples_per_launch`` samples a Dr.Jit launch (default :func:`samples_per_chunk`; the
    result does not depend on it, which ``doctor --check`` verifies).

    ``phases``: an :class:`oracle.phases.Phases` to profile the render into (``trace+shade``,
    ``reductions``, ``transfer``, ``accumulate``, ``centre``, ``finish``); each phase then
    waits for its Dr.Jit work, which the normal path (None) never does.

    Returns
    -------
    channels : dict of ``(H, W)`` float32 arrays named as in the README's table.
    stats : dict with rays cast, wall seconds, M rays/s, mean/max standard errors and, for
        adaptive sampling, the rays uniform sampling would need for the same maximum error.
    """
    settings = settings.validate()
    w, h = loaded.width, loaded.height
    check_memory(w, h, settings)
    groups = set(settings.channels)
    sampled = groups & set(SAMPLED_GROUPS)
    acc = make_accumulators(
        loaded, sampled, adaptive=settings.adaptive and bool(sampled), phases=phases
    )
    t0 = time.perf_counter()
    progress = _progress(loaded, settings, quiet)
    primary = shadow = 0
    passes = []
    try:
        if sampled:
            spp0 = settings.adaptive_spp if settings.adaptive else settings.spp
            p, s = sample_pass(
                loaded,
                acc,
                np.arange(w * h, dtype=np.uint32),
                spp0,
                0,
                settings.seed,
                progress,
                progressive=settings.adaptive,
                launch=samples_per_launch,
            )
            primary, shadow = primary + p, shadow + s
            passes.append({"pixels": int(w * h), "spp": spp0})
            if settings.adaptive:
                p, s = _refine(loaded, acc, settings, passes, progress, samples_per_launch)
                primary, shadow = primary + p, shadow + s
        with maybe_phase(phases, "centre", sync=True):
            centre = (
                centre_channels(loaded, groups, progress) if groups & set(CENTRE_GROUPS) else {}
            )
            if "tangent32" in groups:
                centre["visibility_tangent32"] = tangent32_channel(loaded)
            if "motion" in groups:
                centre.update(motion_channels(loaded))
    finally:
        if progress is not None:
            progress.close()
    wall = time.perf_counter() - t0  # rendering only: the images below are not counted
    with maybe_phase(phases, "finish"):
        channels = acc.finish(w, h)
        channels.update(centre)
    stats = _stats(settings, acc, channels, (primary, shadow), wall, passes, (w, h))
    stats.update(_area_stats(loaded, acc))
    if getattr(loaded, "alpha", None) is not None:  # glTF MASK: what every ray cut out
        stats["alpha_tested"] = _alpha_record(loaded, acc.alpha_bound_rays)
    if "coverage_exact" in groups:
        cov = acc.groups.get("coverage")
        with maybe_phase(phases, "coverage_exact"):
            exact, stats["coverage_exact"] = exact_channels(
                loaded,
                None if cov is None else cov.centre,
                channels,
                budget=settings.exact_budget,
            )
        channels.update(exact)
    return channels, stats


def _alpha_record(loaded, bound_rays: int) -> dict:
    """The alpha-tested shapes of ``loaded`` (reference.json): the rule, each mask and the
    rays that stopped at the layer bound (``bound_rays``)."""
    table = loaded.alpha
    return {
        "rule": "kept where alpha >= cutoff (glTF 2.0 3.9.6); alpha = baseColorFactor.a x "
        "base colour texture alpha (base level, the sampler's magnification filter and wrap "
        "modes) x vertex alpha; rays go on through cut-out points (scenes.backend.alpha_hit)",
        "max_layers": MAX_ALPHA_LAYERS,
        "rays_at_layer_bound": int(bound_rays),
        "rays_at_layer_bound_counts": "camera rays and the point or sun light's shadow rays "
        "of every sample (an area light's shadow rays are not counted); such a ray stops on "
        "the cut-out surface it met last",
        "shapes": {
            loaded.shape_names[i]: table.masks[m].to_json()
            for i, m in enumerate(table.shape_mask)
            if m >= 0
        },
    }


def _area_stats(loaded, acc: Accumulators) -> dict:
    """How an area light was sampled (nothing for a punctual light, or when neither colour
    nor the soft channels integrate over it)."""
    if not _area_sampled(loaded, acc):
        return {}
    return {
        "light_samples_per_sample": light_samples(loaded.light),
        "light_sampling": f"{loaded.light.area} area light: a jittered 4x4 grid per camera "
        "sample, shifted toroidally per camera sample (oracle.reference.soft)",
    }


def _stats(settings, acc: Accumulators, channels, rays, wall, passes, size) -> dict:
    """The render's record: rays, time, passes and each group's standard-error summary."""
    primary, shadow = rays
    stats = {
        "rays_cast": int(primary + shadow),
        "primary_rays": int(primary),
        "shadow_rays": int(shadow),
        "wall_seconds": wall,
        "mrays_per_second": (primary + shadow) / wall / 1e6 if wall > 0 else 0.0,
        "passes": passes,
    }
    if settings.spp == 1 and not settings.adaptive:
        stats["stderr_note"] = (
            "spp = 1: no variance can be estimated; visibility/coverage stderr is the binomial "
            "floor, colour stderr is 0"
        )
    for name in SUMMARY_ORDER:
        g = acc.groups.get(name)
        if g is not None and g.output:
            stats.update(g.summary(channels))
    if settings.adaptive and acc.groups:
        stats["adaptive"] = adaptive_stats(settings, acc, *size)
    return stats
