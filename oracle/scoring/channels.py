"""The scored channels and the metrics each one computes on one candidate frame.

- ``visibility`` (models of the shadow-map family, or an engine's shadow mask): shadow
  metrics on receivers (valid pixels with N.L > 0 at the pixel centre), edge/interior split,
  the per-pixel Z-test, and FLIP/SSIM/PSNR of the visibility image as display data (no tone
  mapping). Reference channels: visibility, edge, id, normal, position.
- ``soft_visibility`` and ``light_fraction`` (soft-shadow models such as PCSS, or an engine's
  soft shadow factor): the visibility metrics on receivers against the area-light truth (the
  optional ``soft`` group, :mod:`oracle.reference.soft`; a punctual light's is its
  visibility), its penumbra counted with the edges; the Z-test on its standard error.
- ``color`` (an engine's linear radiance): FLIP (LDR after the shared tone mapper, or HDR with
  the exposure bracket of the reference), SSIM, PSNR, CIEDE2000, edge/interior split and the
  Z-test. Reference channels: color, edge, id.
- ``depth`` (an engine's linear view depth): relative error against the reference's view
  depth at the pixel centre, over the pixels where the reference sees a surface (not sky;
  ``depth_pixels`` counts them), and with the engine's depth buffer named (``depth_buffer``:
  near, far, bits) the fraction beyond that buffer's rounding (:mod:`metrics.depth`).
  Reference channels: depth, edge, id.
- ``coverage`` / ``front_coverage``: coverage error against the N-sample straight-edge floor
  (:func:`metrics.aliasing.coverage_metrics`), against the exact coverage where valid.

Which metrics a channel keeps is the metric catalogue's word (:mod:`metrics.catalog`: a
metric not declared for the channel's kind stays None).
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ...metrics.aliasing import coverage_metrics
from ...metrics.catalog import IMAGE_KINDS, RECORD_KEYS
from ...metrics.depth import depth_metrics
from ...scenes.shading.phong import receiver_mask

__all__ = [
    "CHANNEL_KIND",
    "CHANNEL_METRICS",
    "COVERAGE_CHANNELS",
    "METRIC_KEYS",
    "PSNR_CAP_DB",
    "PENUMBRA",
    "REFERENCE_GROUPS",
    "SOFT_CHANNELS",
    "coverage_truth",
    "finite",
    "metrics_for",
    "on_receivers",
    "reference_receivers",
    "rgb",
    "scored_channel",
    "second_reference",
]

#: Every metric key of ``metrics.json`` (None where it does not apply to the channel), in
#: the order of the metric catalogue (:mod:`metrics.catalog`: direction, unit, applicability).
METRIC_KEYS = RECORD_KEYS
_SHADOW_VALUES = tuple(k for k in M.SHADOW_KEYS if not k.endswith("_count"))
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
    "depth": ("depth", "edge", "id"),
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


def reference_receivers(ch: dict, light) -> np.ndarray:
    """Receivers of a reference (:func:`scenes.shading.receiver_mask` at the pixel centres):
    ``(H, W)`` bool from its ``id``, ``normal`` and ``position`` channels."""
    valid = ch["id"] >= 0
    n = np.stack([ch[f"normal.{c}"] for c in "XYZ"], -1).astype(np.float64)
    p = np.stack([ch[f"position.{c}"] for c in "XYZ"], -1).astype(np.float64)
    wl, _ = light.to_light(p.reshape(-1, 3))
    cos = np.sum(n.reshape(-1, 3) * wl, axis=-1).reshape(valid.shape)
    return receiver_mask(valid=valid, cos_l=cos, to_light=wl, light=light)


def rgb(ch: dict, name: str) -> np.ndarray:
    return np.stack([ch[f"{name}.{c}"] for c in "RGB"], -1)


def finite(value):
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


def _shadow_on_receivers(ref, ref_ch, cand, *, full, kw, out, maps):
    """The shadow metrics of ``cand`` against ``ref`` on the reference's receivers (values
    into ``out``, error maps into ``maps``); returns the receivers and the FLIP record."""
    rec = reference_receivers(ref_ch, kw["light"])
    sm = M.shadow_metrics(ref, cand, receivers=rec, full=full)
    for k in _SHADOW_VALUES:
        out[k] = sm[k]
    out["receiver_count"] = sm["receiver_count"]
    out["edge_band_count"] = sm["edge_band_count"]
    if full:
        maps["visibility_error"] = sm["signed_error"]
        maps["misclassified"] = sm["misclassified"].astype(np.float32)
    return rec, _linear_display(ref, cand, ppd=kw["ppd"], full=full, out=out)


def _visibility_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """A shadow mask: shadow metrics on the receivers."""
    ref = ref_ch["visibility"]
    rec, fl = _shadow_on_receivers(ref, ref_ch, cand, full=full, kw=kw, out=out, maps=maps)
    return ref, ref_ch["visibility_stderr"], rec, edge, fl


def _soft_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """A soft shadow factor against the area-light truth (``soft_visibility`` or
    ``light_fraction``): the shadow metrics on the receivers (classified at 0.5), with the
    reference's penumbra (values in :data:`PENUMBRA`) added to the edge pixels."""
    ref = np.asarray(ref_ch[channel], dtype=np.float32)
    rec, fl = _shadow_on_receivers(ref, ref_ch, cand, full=full, kw=kw, out=out, maps=maps)
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
    ref = rgb(ref_ch, "color")
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
    return ref, rgb(ref_ch, "color_stderr"), None, edge, fl


def _depth_metrics(ref_ch, cand, *, channel, edge, full, kw, out, maps):
    """Linear view depth: relative error where the reference sees a surface (its ``id`` >= 0
    and depth > 0: sky is 0), the named depth buffer's rounding reported beside it."""
    ref = np.asarray(ref_ch["depth"], dtype=np.float32)
    seen = (ref_ch["id"] >= 0) & (ref > 0)
    near, far, bits = kw.get("depth_buffer") or (None, None, None)
    dm = depth_metrics(ref, cand, valid=seen, near=near, far=far, bits=bits, full=full)
    if full:
        maps["depth_rel_error"] = dm.pop("map")
    out.update(dm)
    # the reference depth is exact at the pixel centre: no noise, no display metrics
    return ref, np.zeros_like(ref), None, edge, None


#: Scored channel -> (its catalogue kind, the function computing its own metrics).
CHANNEL_METRICS = {
    "visibility": ("visibility", _visibility_metrics),
    "soft_visibility": ("visibility", _soft_metrics),
    "light_fraction": ("visibility", _soft_metrics),
    "coverage": ("coverage", _coverage_channel_metrics),
    "front_coverage": ("coverage", _coverage_channel_metrics),
    "color": ("color", _color_metrics),
    "depth": ("depth", _depth_metrics),
}


#: Scored channel -> its kind in the metric catalogue.
CHANNEL_KIND = {channel: kind for channel, (kind, _) in CHANNEL_METRICS.items()}


def scored_channel(kind: str, names) -> str:
    """The channel an engine's image of ``kind`` read from the file channels ``names`` is
    scored as: the scored channel its one channel is named after (``soft_visibility``,
    ``shadow.light_fraction``: against the area-light truth) where that channel is of
    ``kind``, else the kind itself (a mask named ``Y`` or ``shadow.Y`` is ``visibility``)."""
    names = tuple(names)
    base = names[0].rsplit(".", 1)[-1] if len(names) == 1 else None
    return base if base is not None and CHANNEL_KIND.get(base) == kind else kind


def on_receivers(channel: str) -> bool:
    """The receivers rule, stated once: a channel of the visibility kind (a shadow mask, hard
    or soft) is scored on the reference's receivers only; the pixels off them keep the
    reference's values and are counted (``outside_receivers`` in the record, and a note
    when some differ)."""
    return CHANNEL_KIND[channel] == "visibility"


def metrics_for(
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
    depth_buffer=None,
):
    """Metric values (and, with ``full``, error maps) of one candidate frame: the channel's
    own metrics (:data:`CHANNEL_METRICS`), then those every kind shares; a metric the
    catalogue does not declare for the channel's kind stays None.

    ``coverage_only`` (a coverage channel scored beside colour, which keeps only its
    :data:`COVERAGE_KEYS`): FLIP, SSIM and PSNR of the coverage image are not computed
    (None), FLIP being the most expensive metric of a case. ``depth_buffer``: a depth
    candidate's ``(near, far, bits)`` hyperbolic buffer (None: not named)."""
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
        depth_buffer=depth_buffer,
    )
    edge = ref_ch["edge"] > 0.5
    if on_receivers(channel):
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
    if coverage_only or kind not in IMAGE_KINDS:
        # beside colour, only the coverage metrics are kept; a depth has no noise to test
        # and no display: no edge split, no Z-test
        keep = {k: finite(v) if k in METRIC_KEYS else v for k, v in out.items()}
        return keep, maps, ref, rec
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
    return {k: finite(v) if k in METRIC_KEYS else v for k, v in out.items()}, maps, ref, rec


def second_reference(ref2_ch: dict, channel: str) -> np.ndarray:
    """The independently seeded reference of the noise floor (exact where its coverage is:
    an exact truth has no noise floor)."""
    if channel == "color":
        return rgb(ref2_ch, "color")
    if channel in COVERAGE_CHANNELS:
        return coverage_truth(ref2_ch, channel)[0]
    return ref2_ch[channel]
