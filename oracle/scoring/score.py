"""Score a technique model or an engine's image against the reference.

The candidate's channel decides which metrics apply and which reference channels are
rendered:

- ``visibility`` (models of the shadow-map family, or an engine's shadow mask): shadow
  metrics on receivers (valid pixels with N.L > 0 at the pixel centre), edge/interior split,
  the per-pixel Z-test, and FLIP/SSIM/PSNR of the visibility image as display data (no tone
  mapping). Reference channels: visibility, edge, id, normal, position.
- ``soft_visibility`` and ``light_fraction`` (soft-shadow models such as PCSS, or an engine's
  soft shadow factor): the same metrics on receivers against the area-light truth (the
  optional ``soft`` group, :mod:`oracle.reference.soft`; a punctual light's is its
  visibility), its penumbra counted with the edges; the Z-test on its standard error.
- ``color`` (an engine's linear radiance): FLIP (LDR after the shared tone mapper, or HDR with
  the exposure bracket of the reference), SSIM, PSNR, CIEDE2000, edge/interior split and the
  Z-test. Reference channels: color, edge, id.

Every metric is also computed for a second, independently seeded reference of the same spp
against the first: its noise floor. With ``frames`` the camera path is scored frame by frame
(per-frame metrics averaged, each frame's kept in ``frames``) and the temporal metrics are
added: ``flicker`` (:func:`added_flicker`, non-negative) and ``temporal_error``, with noise
floors from every frame's second reference.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ... import metrics as M
from ...scenes.backend import provenance
from ...scenes.shading.phong import receiver_mask
from ..errors import InputError
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from .engine_metrics import add_engine_gate_metrics, exact_floors
from .temporal import add_temporal_aa

__all__ = [
    "COVERAGE_FLOOR_RMS",
    "COVERAGE_KEYS",
    "METRIC_KEYS",
    "REFERENCE_GROUPS",
    "SOFT_CHANNELS",
    "ScoreError",
    "ScoreResult",
    "added_flicker",
    "coverage_metrics",
    "coverage_truth",
    "failures",
    "metric_limit",
    "parse_thresholds",
    "reference_receivers",
    "score",
]

#: Coverage metrics (anti-aliasing techniques, or an engine's MSAA coverage mask).
COVERAGE_KEYS = (
    "coverage_mae",
    "coverage_rmse",
    "coverage_bias",
    "coverage_edge_rmse",
    "coverage_interior_mae",
    "coverage_floor_rms",
    "coverage_edge_rmse_over_floor",
)
#: Every metric key of ``metrics.json`` (None where it does not apply to the channel), in
#: the order of the metric catalogue (:mod:`metrics.catalog`: direction, unit, applicability).
_SHADOW_VALUES = tuple(k for k in M.SHADOW_KEYS if not k.endswith("_count"))
METRIC_KEYS = tuple(M.CATALOG)
#: RMS coverage error of a box-resolved N-sample standard pattern on one straight edge
#: (TECHNIQUES.md table; ``metrics.straight_edge_error_floor`` reproduces it).
COVERAGE_FLOOR_RMS = {1: 0.250, 2: 0.159, 4: 0.092, 8: 0.057, 16: 0.044}
#: Reference channel groups each scored channel reads.
REFERENCE_GROUPS = {
    "visibility": ("visibility", "edge", "id", "normal", "position"),
    # an area light's shadow factor (oracle.reference.soft; a punctual light's is its
    # visibility): what PCSS and other soft-shadow models are scored on
    "soft_visibility": ("soft", "edge", "id", "normal", "position"),
    "light_fraction": ("soft", "edge", "id", "normal", "position"),
    "color": ("color", "edge", "id"),
    "coverage": ("coverage", "coverage_exact", "edge", "id"),
    # the coverage of each pixel's front-most primitive (oracle.reference.coverage): what the
    # anti-aliasing models are scored on, so that backdrop scenes have coverage edges too
    "front_coverage": ("coverage", "coverage_exact", "edge", "id"),
}
#: Channels of sample counts (binary samples: binomial noise floor).
COVERAGE_CHANNELS = ("coverage", "front_coverage")
#: Soft-shadow channels: shadow metrics on the receivers against the area-light truth.
SOFT_CHANNELS = ("soft_visibility", "light_fraction")
#: Reference values strictly between these are an area light's penumbra (scored as edges).
PENUMBRA = (0.02, 0.98)
PSNR_CAP_DB = 100.0  # identical images: PSNR is infinite; JSON stores this cap instead


def coverage_truth(ref_ch: dict, channel: str):
    """The truth a coverage channel is scored against: the exact channel
    (``coverage_exact``/``front_coverage_exact``, standard error 0) where
    ``coverage_exact_valid``, the Monte Carlo estimate elsewhere. Returns ``(truth, stderr,
    record)``; the record names the truth used and the fraction of exact pixels."""
    ref = np.asarray(ref_ch[channel], np.float64)
    se = np.asarray(ref_ch[f"{channel}_stderr"], np.float64)
    exact = ref_ch.get(f"{channel}_exact")
    if exact is None:
        return ref, se, {"truth": "monte carlo", "exact_fraction": 0.0}
    valid = ref_ch["coverage_exact_valid"] > 0.5
    fraction = float(valid.mean())
    truth = "exact" if fraction == 1.0 else "exact where valid, monte carlo elsewhere"
    record = {"truth": truth if fraction > 0 else "monte carlo", "exact_fraction": fraction}
    return np.where(valid, exact, ref), np.where(valid, 0.0, se), record


class ScoreError(InputError):
    """Bad scoring request (unknown channel, bad threshold, ...)."""


@dataclass
class FrameScore:
    metrics: dict
    noise_floor: dict | None
    maps: dict
    reference: np.ndarray
    candidate: np.ndarray
    receivers: np.ndarray | None


@dataclass
class ScoreResult:
    """What ``score`` computed: the metrics record and the images behind it."""

    record: dict
    frames: list[FrameScore] = field(default_factory=list)
    reference_folders: list[Path] = field(default_factory=list)


def reference_receivers(ch: dict, light) -> np.ndarray:
    """Receivers of a reference (:func:`scenes.shading.phong.receiver_mask` at the pixel centres):
    ``(H, W)`` bool from its ``id``, ``normal`` and ``position`` channels."""
    valid = ch["id"] >= 0
    n = np.stack([ch[f"normal.{c}"] for c in "XYZ"], -1).astype(np.float64)
    p = np.stack([ch[f"position.{c}"] for c in "XYZ"], -1).astype(np.float64)
    wl, _ = light.to_light(p.reshape(-1, 3))
    cos = np.sum(n.reshape(-1, 3) * wl, axis=-1).reshape(valid.shape)
    return receiver_mask(valid=valid, cos_l=cos, to_light=wl, light=light)


def _rgb(ch: dict, name: str) -> np.ndarray:
    return np.stack([ch[f"{name}.{c}"] for c in "RGB"], -1)


def _finite(value):
    if value is None:
        return None
    value = float(value)
    if np.isinf(value):
        return PSNR_CAP_DB if value > 0 else -PSNR_CAP_DB
    return value


def _linear_display(ref, cand, *, ppd, full, out):
    """FLIP, SSIM and PSNR of data in [0, 1] shown as it is (no tone mapping)."""
    lin = dict(tone_mapper="clip", exposure=0.0)
    out["ssim"] = M.ssim(ref, cand, **lin)
    out["psnr_db"] = M.psnr_db(ref, cand, **lin)
    return M.flip(ref, cand, mode="LDR", ppd=ppd, full=full, **lin)


def _receivers_only(ref_ch, cand, *, light, out, channel="visibility"):
    """A shadow mask with the reference's values off the oracle's receivers. Engine
    conventions differ there (sky, back faces, outside a spot cone: 1 in most engines, 0 in
    the oracle): only receivers are scored, the rest are counted in ``out``."""
    ref = ref_ch[channel]
    rec = reference_receivers(ref_ch, light)
    out["outside_receivers"] = int((~rec).sum())
    out["outside_receivers_differing"] = int(((cand != ref) & ~rec).sum())
    return np.where(rec, cand, ref).astype(np.float32)


def _visibility_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """A shadow mask: shadow metrics on the receivers."""
    ref = ref_ch["visibility"]
    rec = reference_receivers(ref_ch, kw["light"])
    sm = M.shadow_metrics(ref, cand, receivers=rec, full=full)
    for k in _SHADOW_VALUES:
        out[k] = sm[k]
    out["receiver_count"] = sm["receiver_count"]
    out["edge_band_count"] = sm["edge_band_count"]
    if full:
        maps["visibility_error"] = sm["signed_error"]
        maps["misclassified"] = sm["misclassified"].astype(np.float32)
    fl = _linear_display(ref, cand, ppd=kw["ppd"], full=full, out=out)
    return ref, ref_ch["visibility_stderr"], rec, edge, fl


def _soft_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """A soft shadow factor against the area-light truth (``soft_visibility`` or
    ``light_fraction``): the shadow metrics on the receivers (classified at 0.5), with the
    reference's penumbra (values in :data:`PENUMBRA`) added to the edge pixels."""
    ref = np.asarray(ref_ch[channel], dtype=np.float32)
    rec = reference_receivers(ref_ch, kw["light"])
    sm = M.shadow_metrics(ref, cand, receivers=rec, full=full)
    for k in _SHADOW_VALUES:
        out[k] = sm[k]
    out["receiver_count"] = sm["receiver_count"]
    out["edge_band_count"] = sm["edge_band_count"]
    if full:
        maps["visibility_error"] = sm["signed_error"]
        maps["misclassified"] = sm["misclassified"].astype(np.float32)
    fl = _linear_display(ref, cand, ppd=kw["ppd"], full=full, out=out)
    penumbra = rec & (ref > PENUMBRA[0]) & (ref < PENUMBRA[1])
    return ref, ref_ch[f"{channel}_stderr"], rec, edge | penumbra, fl


def _coverage_channel_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """A coverage mask: coverage error against the N-sample straight-edge floor, against
    the exact coverage where it is valid (:func:`coverage_truth`)."""
    ref, ref_se, _ = coverage_truth(ref_ch, channel)
    out.update(coverage_metrics(ref, cand, edge=edge, aa_samples=kw["aa_samples"]))
    if full:
        maps["coverage_error"] = (cand - ref).astype(np.float32)
    fl = None  # coverage_only: no FLIP, SSIM, PSNR (their values would be dropped)
    if not kw["coverage_only"]:
        fl = _linear_display(ref, cand, ppd=kw["ppd"], full=full, out=out)
    # silhouettes against the sky are edges of coverage even where one shape is seen
    return ref, ref_se, None, edge | ((ref > 0) & (ref < 1)), fl


def _color_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """Linear radiance: tone-mapped FLIP (or HDR-FLIP), SSIM, PSNR and CIEDE2000."""
    ref = _rgb(ref_ch, "color")
    exposure = kw["exposure"]
    if kw["flip_mode"] == "HDR":
        fl = M.flip(
            ref, cand, mode="HDR", ppd=kw["ppd"], exposure_range=kw["flip_range"], full=full
        )
    else:
        fl = M.flip(ref, cand, mode="LDR", ppd=kw["ppd"], exposure=exposure, full=full)
    out["ssim"] = M.ssim(ref, cand, exposure=exposure)
    out["psnr_db"] = M.psnr_db(ref, cand, exposure=exposure)
    de = M.delta_e2000(ref, cand, exposure=exposure, full=full)
    out["delta_e2000_mean"] = de[0] if full else de
    if full:
        maps["delta_e2000"] = de[1]
    return ref, _rgb(ref_ch, "color_stderr"), None, edge, fl


#: Scored channel -> (its catalogue kind, the function computing its own metrics).
CHANNEL_METRICS = {
    "visibility": ("visibility", _visibility_metrics),
    "soft_visibility": ("visibility", _soft_metrics),
    "light_fraction": ("visibility", _soft_metrics),
    "coverage": ("coverage", _coverage_channel_metrics),
    "front_coverage": ("coverage", _coverage_channel_metrics),
    "color": ("color", _color_metrics),
}


def _metrics_for(
    channel,
    ref_ch,
    cand,
    *,
    light,
    exposure,
    flip_mode,
    flip_range,
    ppd,
    full: bool,
    samples,
    aa_samples=None,
    coverage_only: bool = False,
):
    """Metric values (and, with ``full``, error maps) of one candidate frame: the channel's
    own metrics (:data:`CHANNEL_METRICS`), then those every kind shares; a metric the
    catalogue does not declare for the channel's kind stays None.

    ``coverage_only`` (a coverage channel scored beside colour, which keeps only its
    :data:`COVERAGE_KEYS`): FLIP, SSIM and PSNR of the coverage image are not computed
    (None), FLIP being the most expensive metric of a case."""
    out = dict.fromkeys(METRIC_KEYS)
    maps = {}
    kind, own = CHANNEL_METRICS[channel]
    kw = dict(
        light=light,
        exposure=exposure,
        flip_mode=flip_mode,
        flip_range=flip_range,
        ppd=ppd,
        aa_samples=aa_samples,
        coverage_only=coverage_only,
    )
    edge = ref_ch["edge"] > 0.5
    if channel == "visibility" or channel in SOFT_CHANNELS:
        cand = _receivers_only(ref_ch, cand, light=light, out=out, channel=channel)
    ref, ref_se, rec, edge, fl = own(
        ref_ch, cand, channel=channel, edge=edge, full=full, kw=kw, out=out, maps=maps
    )
    if fl is None:
        out["flip_mean"] = None
    elif full:
        out["flip_mean"], maps["flip"] = fl[0], fl[1]
    else:
        out["flip_mean"] = fl
    ei = M.edge_interior_error(ref, cand, edge_mask=edge)
    out["edge_mae"], out["interior_mae"] = ei["edge_mae"], ei["interior_mae"]
    # radiance a missed sub-pixel feature could have: the reference's 99th percentile
    scale = 1.0 if ref.ndim == 2 else np.percentile(ref.reshape(-1, ref.shape[-1]), 99, axis=0)
    binary = channel in ("visibility", *COVERAGE_CHANNELS)
    zt = M.z_test(ref, ref_se, cand, samples=samples, floor_scale=scale, binary=binary, full=full)
    out["significant_fraction"] = zt["significant_fraction"]
    if full:
        p = zt["p_value"]
        p = p if p.ndim == 2 else p.min(axis=-1)
        # -log10 p: 0 where the difference is pure noise, large where it is significant
        maps["neg_log10_p"] = -np.log10(np.maximum(p, 1e-300))
    for key in METRIC_KEYS:
        if kind not in M.CATALOG[key].kinds:
            out[key] = None
    return {k: _finite(v) if k in METRIC_KEYS else v for k, v in out.items()}, maps, ref, rec


def coverage_metrics(ref, cand, *, edge, aa_samples) -> dict:
    """Coverage error overall, on edge and interior pixels, and against the N-sample floor.

    Edge pixels: the reference's ``edge`` channel or fractional reference coverage.
    The floor is the RMS error of N box-resolved standard samples on one straight edge;
    ``coverage_edge_rmse_over_floor`` near 1 means the technique is as good as its pattern
    allows (above 1 also where an edge pixel holds more than one edge, or the reference's
    own noise adds to the error).
    """
    edge = edge | ((ref > 0) & (ref < 1))
    every = M.coverage_error(ref, cand)
    on_edge = M.coverage_error(ref, cand, mask=edge)
    inside = M.coverage_error(ref, cand, mask=~edge)
    floor = COVERAGE_FLOOR_RMS.get(int(aa_samples)) if aa_samples else None
    ratio = on_edge["rmse"] / floor if floor and on_edge["count"] else None
    return {
        "coverage_mae": every["mae"],
        "coverage_rmse": every["rmse"],
        "coverage_bias": every["bias"],
        "coverage_edge_rmse": on_edge["rmse"] if on_edge["count"] else None,
        "coverage_interior_mae": inside["mae"] if inside["count"] else None,
        "coverage_floor_rms": floor,
        "coverage_edge_rmse_over_floor": ratio,
    }


def _noise_floor(
    frame_scene, ref, ref_ch, ref_img, *, channel, settings, kw, cache, quiet, floor_cache
) -> dict:
    """Metrics an exact candidate would score against ``ref``: an independently seeded second
    reference (``settings``) stands for it. Cached in ``floor_cache`` by reference and options.
    """
    floor_key = (ref.meta.get("cache_key"), channel, kw["flip_mode"], kw["ppd"], kw["samples"])
    floor_key += (kw["aa_samples"], kw["coverage_only"])
    cached = floor_cache.get(floor_key) if floor_cache is not None else None
    if cached is not None and floor_key[0] is not None:
        return dict(cached)
    ref2_ch = get_reference(frame_scene, settings, cache=cache, quiet=quiet).channels()
    second = _second(ref2_ch, channel)
    # what an exact candidate would score: A + (B - A)/sqrt(2) differs from A by noise of
    # A's variance (B itself would overstate the floor by about sqrt(2))
    exact = M.exact_surrogate(ref_img, second)
    floor, _, _, rec = _metrics_for(channel, ref_ch, exact, full=False, **kw)
    floor = {key: floor[key] for key in METRIC_KEYS if floor.get(key) is not None}
    # the engine teams' gates (Unreal, Unity, edge-aware) on the same exact surrogate
    floor.update(
        exact_floors(ref_img, exact, ref_ch, channel=channel, exposure=kw["exposure"], mask=rec)
    )
    if floor_cache is not None and floor_key[0] is not None:
        floor_cache[floor_key] = dict(floor)
    return floor


def _second(ref2_ch: dict, channel: str) -> np.ndarray:
    """The independently seeded reference of the noise floor (exact where its coverage is:
    an exact truth has no noise floor)."""
    if channel == "color":
        return _rgb(ref2_ch, "color")
    if channel in COVERAGE_CHANNELS:
        return coverage_truth(ref2_ch, channel)[0]
    return ref2_ch[channel]


def added_flicker(reference_frames: np.ndarray, candidate_frames: np.ndarray) -> float:
    """Flicker the candidate adds, non-negative: ``mean(max(0, |c[t+1] - c[t]| -
    |r[t+1] - r[t]|))`` over frame pairs, pixels and channels.

    ``metrics.flicker`` (METRICS.md's temporal metric) subtracts the two means, so a candidate
    that is steadier than the reference in one region cancels flicker elsewhere and the value
    can be negative. Here the reference's own change is subtracted per pixel and only the
    excess counts: 0 when the candidate never changes more than the reference, and a
    smoothed-away change is not credited against a crawling edge. Its noise floor is what
    an exact candidate scores (the seed + 1 reference, as for the other metrics).
    """
    ref = np.asarray(reference_frames, dtype=np.float64)
    cand = np.asarray(candidate_frames, dtype=np.float64)
    if ref.shape != cand.shape or ref.shape[0] < 2:
        raise ScoreError(f"flicker needs two equal sequences of >= 2 frames, got {ref.shape}")
    excess = np.abs(np.diff(cand, axis=0)) - np.abs(np.diff(ref, axis=0))
    return float(np.maximum(excess, 0.0).mean())


def _temporal_floor(result, scenes_k, settings, channel, *, cache, quiet):
    """Temporal metrics an exact candidate scores: every frame's independently seeded second
    reference (``settings``) turned into the exact surrogate of its first; and those exact
    frames (``(T, H, W[, 3])``, for the temporal AA metrics' floors)."""
    exact = []
    for frame, frame_scene in zip(result.frames, scenes_k, strict=True):
        ch2 = get_reference(frame_scene, settings, cache=cache, quiet=quiet).channels()
        second = _second(ch2, channel)
        exact.append(M.exact_surrogate(frame.reference, second))
    refs = np.stack([f.reference for f in result.frames])
    exact = np.stack(exact)
    return {
        "flicker": added_flicker(refs, exact),
        "temporal_error": M.temporal_error(refs, exact),
    }, exact


def _summary(result: ScoreResult, *, temporal: bool, gate_frames: int | None = None) -> dict:
    """Per-frame metrics averaged over the frames (the last ``gate_frames`` only, when
    given: warm-up does not pass or fail a gate), and the temporal metrics of the path."""
    per_frame = [f.metrics for f in result.frames][-(gate_frames or len(result.frames)) :]
    summary = {}
    for key in METRIC_KEYS:
        vals = [m[key] for m in per_frame if m.get(key) is not None]
        summary[key] = float(np.mean(vals)) if vals else None
    if temporal:
        refs = np.stack([f.reference for f in result.frames])
        cands = np.stack([f.candidate for f in result.frames])
        summary["flicker"] = added_flicker(refs, cands)
        summary["temporal_error"] = M.temporal_error(refs, cands)
    return summary


def _tone(channel, exposure, flip_mode, flip_range) -> dict | None:
    """The record's ``tone_mapping`` (colour only)."""
    if channel != "color":
        return None
    return {
        "exposure_stops": exposure,
        "tone_mapper": "aces",
        "flip_mode": flip_mode,
        "flip_exposure_range": list(flip_range) if flip_range else None,
    }


def _record(
    result, loaded, ref_meta, *, channel, summary, frames, camera_path, tone, ppd, spp, seed
) -> dict:
    """The ``metrics.json`` record of a score (before thresholds and the candidate's cost)."""
    return {
        "schema": "raster-oracle/metrics/1",
        "channel": channel,
        # this run's backend, device and self-check (a model ran here; the reference's
        # own are under "reference")
        "provenance": provenance(),
        **summary,
        "noise_floor": result.frames[0].noise_floor,
        "frames": [f.metrics for f in result.frames] if frames else None,
        "camera_path": camera_path if frames else None,
        "light_path": loaded.light_path,
        "tone_mapping": tone,
        "ppd": ppd,
        "reference": {
            # the cached reference may have been rendered from another file of the same content
            # (an export copied into CI's folder): the scene is named as this run loaded it
            "scene": {**ref_meta["scene"], "name": loaded.name, "source": loaded.source},
            "spp": spp,
            "seed": seed,
            "noise_floor_seed": seed + 1,
            "channels": list(REFERENCE_GROUPS[channel]),
            "variant": ref_meta["variant"],
            # the machine that rendered the reference and its self-check (older cache
            # entries have neither)
            "device": ref_meta.get("device"),
            "self_check": ref_meta.get("self_check"),
            "versions": ref_meta["versions"],
            "cache_key": ref_meta["cache_key"],
            "filter": ref_meta["filter"],
        },
    }


def score(
    loaded,
    *,
    channel: str,
    candidate_frames,
    spp: int = 64,
    seed: int = 0,
    frames: int | None = None,
    camera_path: str = "dolly",
    cache=None,
    quiet: bool = True,
    flip_mode: str = "LDR",
    ppd: float = M.DEFAULT_PPD,
    aa_samples: int | None = None,
    floor_cache: dict | None = None,
    coverage_only: bool = False,
    gate_frames: int | None = None,
) -> ScoreResult:
    """Score candidate frames against references of ``loaded``.

    Parameters
    ----------
    channel : ``"visibility"``, ``"color"``, ``"coverage"`` or ``"front_coverage"``.
    candidate_frames : callable ``(frame_scene, k) -> (image, info)`` giving the candidate of
        frame ``k`` (a model run, or an image file read and validated) and a plain record
        (cost, diagnostics, file name) for the report.
    frames : score ``frames`` frames of ``camera_path`` (None: the scene's own camera only).
    aa_samples : samples per pixel of an anti-aliasing technique: picks the straight-edge
        coverage floor ``coverage_floor_rms`` (None: no floor).
    floor_cache : a dict shared between calls (a sweep worker's): the noise floor depends on
        the references and scoring options only, so it is computed once per reference.
    coverage_only : a coverage channel whose coverage metrics alone are kept (an AA model's
        ``front_coverage`` beside its colour): no FLIP, SSIM or PSNR of it.
    gate_frames : average the per-frame metrics over the last ``gate_frames`` frames only
        (None: all), and judge convergence against their level.

    A colour sequence (``frames`` >= 2) also gets the temporal AA metrics
    (:mod:`oracle.scoring.temporal`); a candidate whose ``info`` carries ``"motion"`` (its
    motion vectors, ``(H, W, 2)`` in the oracle's convention) and optionally
    ``"disocclusion"`` gets their end-point error (the arrays leave ``info`` before it is
    recorded).
    """
    if gate_frames is not None and not 1 <= int(gate_frames) <= (frames or 1):
        raise ScoreError(f"--gate-frames must be in [1, {frames or 1}], got {gate_frames}")
    if channel not in REFERENCE_GROUPS:
        raise ScoreError(f"channel must be one of {', '.join(REFERENCE_GROUPS)}, got {channel!r}")
    flip_mode = flip_mode.upper()
    if flip_mode not in ("LDR", "HDR"):
        raise ScoreError(f"flip mode must be LDR or HDR, got {flip_mode!r}")
    t0 = time.perf_counter()
    groups = REFERENCE_GROUPS[channel]
    settings = ReferenceSettings(spp=spp, seed=seed, channels=groups).validate()
    noise_settings = ReferenceSettings(spp=spp, seed=seed + 1, channels=groups).validate()
    n = frames or 1
    result = ScoreResult(record={})
    exposure = flip_range = None
    infos = []
    engine = []
    scenes_k = []
    for k in range(n):
        frame_scene = loaded.with_frame(k, path=camera_path, n_frames=n) if frames else loaded
        scenes_k.append(frame_scene)
        ref = get_reference(frame_scene, settings, cache=cache, quiet=quiet)
        ref_ch = ref.channels()
        cand, info = candidate_frames(frame_scene, k)
        engine.append((info.pop("motion", None), info.pop("disocclusion", None)))
        infos.append(info)
        if k == 0 and channel == "color":
            ref_rgb = _rgb(ref_ch, "color")
            exposure = M.exposure_from_reference(ref_rgb)
            flip_range = M.hdr_exposure_range(ref_rgb) if flip_mode == "HDR" else None
        kw = dict(
            light=frame_scene.light,
            exposure=exposure,
            flip_mode=flip_mode,
            flip_range=flip_range,
            ppd=ppd,
            samples=spp,
            aa_samples=aa_samples,
            coverage_only=coverage_only and channel in COVERAGE_CHANNELS,
        )
        values, maps, ref_img, rec = _metrics_for(channel, ref_ch, cand, full=True, **kw)
        floor = None
        if k == 0:
            ref_meta = ref.meta
            truth = coverage_truth(ref_ch, channel)[2] if channel in COVERAGE_CHANNELS else None
            floor = _noise_floor(
                frame_scene,
                ref,
                ref_ch,
                ref_img,
                channel=channel,
                settings=noise_settings,
                kw=kw,
                cache=cache,
                quiet=quiet,
                floor_cache=floor_cache,
            )
        result.frames.append(FrameScore(values, floor, maps, ref_img, cand, rec))
        result.reference_folders.append(ref.folder)
    exact_frames = None
    if frames and n >= 2:
        floor = dict(result.frames[0].noise_floor or {})
        tf, exact_frames = _temporal_floor(
            result, scenes_k, noise_settings, channel, cache=cache, quiet=quiet
        )
        floor.update(tf)
        result.frames[0].noise_floor = floor
    tone = _tone(channel, exposure, flip_mode, flip_range)
    summary = _summary(result, temporal=bool(frames) and n >= 2, gate_frames=gate_frames)
    taa_detail = None
    if frames and n >= 2 and channel == "color":
        taa, taa_detail = add_temporal_aa(
            result,
            scenes_k,
            seed=seed,
            cache=cache,
            quiet=quiet,
            gate_frames=gate_frames,
            engine_motion=engine,
            exact_frames=exact_frames,
        )
        summary.update(taa)
    result.record = _record(
        result,
        loaded,
        ref_meta,
        channel=channel,
        summary=summary,
        frames=frames,
        camera_path=camera_path,
        tone=tone,
        ppd=ppd,
        spp=spp,
        seed=seed,
    )
    _engine_records(result, channel=channel, exposure=exposure)
    if truth is not None:
        # which truth the coverage metrics used: exact (noise floor 0 there) or Monte Carlo
        result.record["reference"]["coverage_truth"] = truth
    result.record["candidate_info"] = infos
    result.record["gate_frames"] = gate_frames
    result.record["temporal_aa"] = taa_detail
    result.record["wall_seconds"] = time.perf_counter() - t0
    return result


#: Fractions of pixels and the frame metric holding how many pixels each is a fraction of
#: (None: every tested value of the image).
_FRACTION_OF = {
    "significant_fraction": None,
    "misclassified_fraction": "receiver_count",
    "false_lit_fraction": "receiver_count",
    "false_shadow_fraction": "receiver_count",
    "edge_band_misclassified_fraction": "edge_band_count",
}


def _engine_records(result: ScoreResult, *, channel: str, exposure) -> None:
    """The pixel-fraction noise floors, the engine teams' gate metrics and, for a shadow
    mask, the pixels off the oracle's receivers (ignored and counted) of a scored result."""
    _fraction_floors(result)
    add_engine_gate_metrics(result, channel=channel, exposure=exposure)
    if channel == "visibility":
        result.record["outside_receivers"] = {
            key: sum(int(f.metrics[k]) for f in result.frames)
            for key, k in (
                ("pixels", "outside_receivers"),
                ("differing", "outside_receivers_differing"),
            )
        }


def _fraction_floors(result: ScoreResult) -> None:
    """The noise floors of the fractions of pixels: an exact candidate flags ~0 pixels
    (``significant_fraction``'s Sidak correction; a 0.5 threshold), yet a re-rendered
    reference flips the pixels near the threshold; each floor is at least that flip's bound
    (:func:`metrics.fraction_floor` of the run's fraction over the pixels it counts), so an
    unchanged candidate against another seed's reference is no regression."""
    floors = result.record.get("noise_floor")
    if floors is None:
        return
    for key, count_key in _FRACTION_OF.items():
        value = result.record.get(key)
        if value is None:
            continue
        if count_key is None:
            n = sum(int(f.candidate.size) for f in result.frames)
        else:
            n = sum(int(f.metrics.get(count_key) or 0) for f in result.frames)
        if n > 0:
            floors[key] = max(floors.get(key) or 0.0, M.fraction_floor(value, n))


def metric_limit(
    text: str, *, separator: str, option: str, error: type[Exception] = ScoreError
) -> tuple[str, float]:
    """``"flip_mean<sep>0.1"`` -> ``("flip_mean", 0.1)``: a metric key and a finite limit.

    Raises ``error`` with a message naming ``option`` (the command-line option) for a missing
    separator, an unknown metric (listing the valid ones) or a value that is not a finite
    number.
    """
    metric, sep, value = str(text).partition(separator)
    metric, value = metric.strip(), value.strip()
    if not sep:
        raise error(f"{option} expects METRIC{separator}VALUE, got {text!r}")
    if metric not in METRIC_KEYS:
        raise error(f"{option}: unknown metric {metric!r}; choose from {', '.join(METRIC_KEYS)}")
    try:
        limit = float(value)
    except ValueError:
        raise error(f"{option} {metric}: expected a number, got {value!r}") from None
    if not math.isfinite(limit):
        raise error(f"{option} {metric}: expected a finite number, got {value!r}")
    return metric, limit


def parse_thresholds(pairs: list[str] | None) -> dict[str, float]:
    """``["flip_mean=0.1", ...]`` -> ``{"flip_mean": 0.1}``; unknown metrics are errors."""
    return dict(metric_limit(p, separator="=", option="--fail-above") for p in pairs or [])


def failures(record: dict, thresholds: dict[str, float]) -> list[str]:
    """Metrics whose value exceeds its threshold (a metric that does not apply never fails)."""
    return [k for k, limit in thresholds.items() if record.get(k) is not None and record[k] > limit]
