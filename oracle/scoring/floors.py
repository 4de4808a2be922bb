"""Noise floors: what an exact candidate would score on every metric of a score.

An independently seeded second reference of the same spp stands for the exact candidate
(:func:`metrics.exact_surrogate` of the two: it differs from the first by noise of the
first's variance). The temporal metrics of a path get every frame's second reference; the
fractions of pixels are raised to at least their binomial flip bound
(:func:`metrics.fraction_floor`).
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from .channels import COVERAGE_CHANNELS, METRIC_KEYS, metrics_for, second_reference
from .engine_metrics import engine_gates_apply, exact_floors, prepared_reference

__all__ = ["fraction_floors", "noise_floor", "noise_settings", "temporal_floor"]


def noise_settings(request) -> ReferenceSettings:
    """The settings of the noise floor's second reference: the request's, seeded ``seed + 1``."""
    o = request.options
    return ReferenceSettings(
        spp=o.spp, seed=o.seed + 1, channels=request.groups, exact_budget=o.exact_budget
    ).validate()


def noise_floor(
    frame_scene, ref, ref_ch, ref_img, *, channel, settings, kw, cache, quiet, floor_cache
) -> dict:
    """Metrics an exact candidate would score against ``ref``: an independently seeded second
    reference (``settings``) stands for it. Cached in ``floor_cache`` by reference and options.
    """
    floor_key = (ref.meta.get("cache_key"), channel, kw["flip_mode"], kw["ppd"], kw["samples"])
    if channel in COVERAGE_CHANNELS:
        # the straight-edge floor and the kept metrics of coverage depend on these; the other
        # channels' floors do not (one colour floor serves every sample count)
        floor_key += (kw["aa_samples"], kw["coverage_only"])
    cached = floor_cache.get(floor_key) if floor_cache is not None else None
    if cached is not None and floor_key[0] is not None:
        return dict(cached)
    ref2_ch = get_reference(frame_scene, settings, cache=cache, quiet=quiet).channels()
    second = second_reference(ref2_ch, channel)
    # what an exact candidate would score: A + (B - A)/sqrt(2) differs from A by noise of
    # A's variance (B itself would overstate the floor by about sqrt(2))
    exact = M.exact_surrogate(ref_img, second)
    floor, _, _, rec = metrics_for(channel, ref_ch, exact, full=False, **kw)
    floor = {key: floor[key] for key in METRIC_KEYS if floor.get(key) is not None}
    # the engine teams' gates (Unreal, Unity, edge-aware) on the same exact surrogate; the
    # reference's side of them kept for the cases judged against it
    prepared = None
    if engine_gates_apply(channel) and not kw["coverage_only"]:
        prepared = prepared_reference(
            ref_img,
            channel=channel,
            exposure=kw["exposure"],
            key=ref.meta.get("cache_key"),
            memo=floor_cache,
        )
    floor.update(
        exact_floors(
            ref_img,
            exact,
            ref_ch,
            channel=channel,
            exposure=kw["exposure"],
            mask=rec,
            prepared=prepared,
        )
    )
    if floor_cache is not None and floor_key[0] is not None:
        floor_cache[floor_key] = dict(floor)
    return floor


def temporal_floor(result, scenes_k, settings, channel, *, cache, quiet):
    """Temporal metrics an exact candidate scores: every frame's independently seeded second
    reference (``settings``) turned into the exact surrogate of its first; and those exact
    frames (``(T, H, W[, 3])``, for the temporal AA metrics' floors)."""
    exact = []
    for frame, frame_scene in zip(result.frames, scenes_k, strict=True):
        ch2 = get_reference(frame_scene, settings, cache=cache, quiet=quiet).channels()
        second = second_reference(ch2, channel)
        exact.append(M.exact_surrogate(frame.reference, second))
    refs = np.stack([f.reference for f in result.frames])
    exact = np.stack(exact)
    return {
        "flicker": M.added_flicker(refs, exact),
        "temporal_error": M.temporal_error(refs, exact),
    }, exact


#: Fractions of pixels and the frame metric holding how many pixels each is a fraction of
#: (None: every tested value of the image).
_FRACTION_OF = {
    "significant_fraction": None,
    "misclassified_fraction": "receiver_count",
    "false_lit_fraction": "receiver_count",
    "false_shadow_fraction": "receiver_count",
    "edge_band_misclassified_fraction": "edge_band_count",
}


def fraction_floors(result, values: dict, floors: dict | None) -> None:
    """The noise floors of the fractions of pixels: an exact candidate flags ~0 pixels
    (``significant_fraction``'s Sidak correction; a 0.5 threshold), yet a re-rendered
    reference flips the pixels near the threshold; each floor is at least that flip's bound
    (:func:`metrics.fraction_floor` of the run's fraction over the pixels it counts), so an
    unchanged candidate against another seed's reference is no regression."""
    if floors is None:
        return
    for key, count_key in _FRACTION_OF.items():
        value = values.get(key)
        if value is None:
            continue
        if count_key is None:
            n = sum(int(f.candidate.size) for f in result.frames)
        else:
            n = sum(int(f.metrics.get(count_key) or 0) for f in result.frames)
        if n > 0:
            floors[key] = max(floors.get(key) or 0.0, M.fraction_floor(value, n))
