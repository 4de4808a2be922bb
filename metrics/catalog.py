"""The metric catalogue: what every scored metric means for a gate, a report and a baseline.

Every metric key that ``raster-oracle score`` writes into ``metrics.json`` is declared here
once, with

``direction``
    ``"lower"`` (lower is better: errors, fractions), ``"higher"`` (higher is better: SSIM,
    PSNR), ``"zero"`` (a signed bias: closest to 0 is best, either sign is worse) or
    ``"info"`` (a reference value, not a score: never gated, never a regression).
``unit``
    What the number counts (``"fraction of receivers"``, ``"dB"``, ...).
``kinds``
    The candidate kinds it applies to: ``"visibility"`` (a shadow mask), ``"color"`` (linear
    radiance), ``"coverage"`` (an anti-aliasing coverage mask), ``"depth"`` (linear view
    depth, :mod:`metrics.depth`). On other kinds the scorer writes ``null``.
``min_frames``
    Frames a run must score for the metric to exist (the temporal metrics compare
    consecutive frames: 2).
``temporal_family``
    It also applies to every kind of a *temporal family*'s sequence (a family record's
    ``temporal``: a ray-traced shadow denoised over frames has a steady error, a lag and
    ghosting like a TAA); on other sequences of those kinds it stays null (a shadow map's
    frames are not judged as a history).

Judging is done in one place, on the metric's *error*: :func:`error_of` maps a value to a
number that is 0 for a perfect candidate and grows as it gets worse (``x`` for lower-is-better,
``1 - x`` for SSIM, the MSE ``10**(-x/10)`` behind a PSNR, ``|x|`` for a bias). So "within the
noise floor" (:func:`within_noise`) is ``error(value) <= error(floor)`` whatever the
direction, and a regression against a previous run (:func:`regressed`) is an error larger by
more than both runs' floor errors combined: for lower-is-better metrics exactly
``value - previous > floor + previous_floor``. A bad SSIM of 0.93 against a floor of 0.99 is
therefore not within the noise floor (error 0.07 > 0.01), and neither is a PSNR of 14 dB
against a floor of 45 dB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "CATALOG",
    "DIRECTIONS",
    "IMAGE_KINDS",
    "RECORD_KEYS",
    "KINDS",
    "Metric",
    "error_of",
    "metric",
    "regressed",
    "within_noise",
]

#: Candidate kinds a metric can apply to.
KINDS = ("visibility", "color", "coverage", "depth")
#: Valid ``Metric.direction`` values.
DIRECTIONS = ("lower", "higher", "zero", "info")

#: The kinds that are images: the display metrics, the edge split, the Z-test and the
#: diagnoses of a shifted or re-encoded image apply to them; a depth is scored by its
#: relative error alone.
IMAGE_KINDS = ("visibility", "color", "coverage")
_ALL = IMAGE_KINDS
_VIS = ("visibility",)
_COV = ("coverage",)
_DEPTH = ("depth",)


@dataclass(frozen=True)
class Metric:
    """One metric's semantics (see the module docstring)."""

    key: str
    direction: str
    unit: str
    kinds: tuple[str, ...]
    min_frames: int = 1
    meaning: str = ""
    #: written only when asked for (``--expect``): not a key of every record
    on_request: bool = False
    #: also applies to every kind of a temporal family's sequence (module docstring)
    temporal_family: bool = False

    def applies(self, kinds, *, temporal: bool = False) -> bool:
        """Whether the metric applies to a candidate of ``kinds`` (catalogue kinds), of a
        temporal family's sequence when ``temporal``."""
        return bool(set(self.kinds) & set(kinds)) or (temporal and self.temporal_family)

    @property
    def better(self) -> str:
        """``"lower-is-better"``, ``"higher-is-better"``, ``"closest-to-0-is-best"`` or
        ``"a reference value, not a score"``: how messages name the direction."""
        return {
            "lower": "lower-is-better",
            "higher": "higher-is-better",
            "zero": "closest-to-0-is-best",
            "info": "a reference value, not a score",
        }[self.direction]


def _m(
    key, direction, unit, kinds, meaning, min_frames=1, on_request=False, temporal_family=False
) -> Metric:
    return Metric(
        key, direction, unit, tuple(kinds), min_frames, meaning, on_request, temporal_family
    )


_ENTRIES = (
    _m("visibility_mae", "lower", "visibility (0..1)", _VIS, "mean |error| on receivers"),
    _m("visibility_rmse", "lower", "visibility (0..1)", _VIS, "RMS error on receivers"),
    _m(
        "misclassified_fraction",
        "lower",
        "fraction of receivers",
        _VIS,
        "receivers lit in one image and shadowed in the other (threshold 0.5)",
    ),
    _m("false_lit_fraction", "lower", "fraction of receivers", _VIS, "shadowed, shown lit"),
    _m("false_shadow_fraction", "lower", "fraction of receivers", _VIS, "lit, shown shadowed"),
    _m("edge_band_mae", "lower", "visibility (0..1)", _VIS, "mean |error| near shadow edges"),
    _m(
        "edge_band_misclassified_fraction",
        "lower",
        "fraction of edge-band receivers",
        _VIS,
        "misclassified receivers near shadow edges",
    ),
    _m("edge_mae", "lower", "channel units", _ALL, "mean |error| on geometric edge pixels"),
    _m("interior_mae", "lower", "channel units", _ALL, "mean |error| off geometric edges"),
    _m("flip_mean", "lower", "FLIP (0..1)", _ALL, "mean NVIDIA FLIP difference"),
    _m("ssim", "higher", "SSIM (-1..1, 1 = identical)", _ALL, "structural similarity"),
    _m("psnr_db", "higher", "dB", _ALL, "peak signal-to-noise ratio (100 = identical)"),
    _m("delta_e2000_mean", "lower", "CIEDE2000 dE", ("color",), "mean colour difference"),
    _m(
        "significant_fraction",
        "lower",
        "fraction of pixels",
        _ALL,
        "pixels whose difference the reference's noise does not explain (Z-test)",
    ),
    _m(
        "flicker",
        "lower",
        "channel units per frame",
        _ALL,
        "frame-to-frame change of the candidate in excess of the reference's",
        min_frames=2,
    ),
    _m(
        "temporal_error",
        "lower",
        "channel units per frame",
        _ALL,
        "mean change of the error between consecutive frames",
        min_frames=2,
    ),
    # temporal anti-aliasing over a sequence (metrics.ghosting): each frame against that
    # frame's truth; "steady" is the mean over the judged (last) frames
    _m(
        "steady_error",
        "lower",
        "channel units",
        ("color",),
        "mean |error| over the judged frames (the last --gate-frames, else all)",
        min_frames=2,
        temporal_family=True,
    ),
    _m(
        "convergence_frames",
        "lower",
        "frames",
        ("color",),
        "frames until the per-frame mean |error| reaches and stays within 10% of its steady level",
        min_frames=2,
        temporal_family=True,
    ),
    _m(
        "ghosting_error",
        "lower",
        "channel units",
        ("color",),
        "mean |error| on pixels disoccluded within the last N frames (reference disocclusion)",
        min_frames=2,
        temporal_family=True,
    ),
    _m(
        "history_error",
        "lower",
        "channel units",
        ("color",),
        "mean |error| where the truth changed along its motion since the previous frame",
        min_frames=2,
        temporal_family=True,
    ),
    _m(
        "lag_frames",
        "lower",
        "frames",
        ("color",),
        "frames after a disocclusion until the error there is within 10% of the settled error",
        min_frames=2,
        temporal_family=True,
    ),
    _m(
        "flicker_ratio",
        "lower",
        "ratio",
        ("color",),
        "mean frame-to-frame change of the candidate over the truth's (1: as steady as the truth)",
        min_frames=2,
        temporal_family=True,
    ),
    # a perceptual score of the whole sequence (metrics.video, the optional extra [video])
    _m(
        "cvvdp_jod",
        "higher",
        "JOD (10 = identical)",
        ("color",),
        "ColorVideoVDP quality of the tone-mapped sequence against the truth's (null without "
        "the extra raster-oracle[video])",
        min_frames=2,
    ),
    # an engine's velocity buffer against the reference motion (metrics.motion)
    _m(
        "motion_epe_mean",
        "lower",
        "pixels",
        ("color",),
        "mean end-point error of the motion vectors on pixels not disoccluded",
    ),
    _m("motion_epe_p99", "lower", "pixels", ("color",), "99th percentile end-point error"),
    _m(
        "motion_epe_over_half",
        "lower",
        "fraction of pixels",
        ("color",),
        "pixels (not disoccluded) whose motion vector is off by more than 0.5 px",
    ),
    _m(
        "disocclusion_recall",
        "higher",
        "fraction (0..1)",
        ("color",),
        "reference-disoccluded pixels the candidate marks disoccluded",
    ),
    _m(
        "disocclusion_precision",
        "higher",
        "fraction (0..1)",
        ("color",),
        "candidate-disoccluded pixels the reference marks disoccluded",
    ),
    *(
        _m(
            f"unreal_{level}_{which}_error",
            "lower",
            "fraction of pixels" if which == "global" else "fraction of a 10x10-grid block",
            _ALL,
            f"Unreal screenshot comparison, {level} tolerance: mismatched pixels "
            + ("of the image" if which == "global" else "of the worst block"),
        )
        for level in ("low", "medium", "high")
        for which in ("global", "local")
    ),
    _m(
        "unity_average_delta_e",
        "lower",
        "JzAzBz dE",
        _ALL,
        "Unity ImageAssert: mean JzAzBz delta E above the per-pixel 0.001",
    ),
    _m(
        "edge_aware_error_fraction",
        "lower",
        "fraction of pixels",
        ("visibility", "coverage"),
        "pixels beyond 3 standard errors (+ 0.25 px of edge position where the truth is "
        "fractional)",
    ),
    # conformance to the technique the engine claims (--expect): the candidate against the
    # oracle's model of it (oracle.scoring.conformance)
    _m(
        "conformance_misclassified_fraction",
        "lower",
        "fraction of receivers",
        _VIS,
        "receivers lit in the candidate and shadowed in the claimed technique's model, or the "
        "reverse",
        on_request=True,
    ),
    _m(
        "conformance_edge_displacement_px",
        "lower",
        "pixels",
        _ALL,
        "sub-pixel shift of the candidate's edges against the claimed technique's model",
        on_request=True,
    ),
    _m(
        "conformance_flip_mean",
        "lower",
        "FLIP (0..1)",
        _ALL,
        "mean FLIP difference between the candidate and the claimed technique's model",
        on_request=True,
    ),
    _m("coverage_mae", "lower", "coverage (0..1)", _COV, "mean |coverage error|"),
    _m("coverage_rmse", "lower", "coverage (0..1)", _COV, "RMS coverage error"),
    _m("coverage_bias", "zero", "coverage (-1..1)", _COV, "mean signed coverage error"),
    _m("coverage_edge_rmse", "lower", "coverage (0..1)", _COV, "RMS coverage error on edges"),
    _m("coverage_interior_mae", "lower", "coverage (0..1)", _COV, "mean |error| off edges"),
    _m(
        "coverage_floor_rms",
        "info",
        "coverage (0..1)",
        _COV,
        "RMS error N standard samples make on one straight edge (a technique's constant)",
    ),
    _m(
        "coverage_edge_rmse_over_floor",
        "lower",
        "ratio",
        _COV,
        "edge RMS over the N-sample straight-edge floor (1 = as good as the pattern allows)",
    ),
    _m(
        "depth_rel_error_mean",
        "lower",
        "relative error",
        _DEPTH,
        "mean |candidate - reference| / reference view depth where the reference sees a surface",
    ),
    _m("depth_rel_error_p99", "lower", "relative error", _DEPTH, "99th percentile of it"),
    _m("depth_rel_error_max", "lower", "relative error", _DEPTH, "largest relative error"),
    _m("depth_pixels", "info", "pixels", _DEPTH, "pixels scored: the reference sees a surface"),
    _m(
        "depth_beyond_precision_fraction",
        "lower",
        "fraction of depth pixels",
        _DEPTH,
        "pixels whose error exceeds the named depth buffer's rounding (--depth-buffer)",
    ),
)

#: Metric key -> :class:`Metric`, in ``metrics.json`` order.
CATALOG: dict[str, Metric] = {m.key: m for m in _ENTRIES}
#: The keys every ``metrics.json`` record holds (null where they do not apply); the
#: ``on_request`` ones join a record only when asked for.
RECORD_KEYS = tuple(k for k, m in CATALOG.items() if not m.on_request)


def metric(key: str) -> Metric:
    """The catalogue entry of ``key``; ``KeyError`` naming the known keys for an unknown one."""
    try:
        return CATALOG[key]
    except KeyError:
        raise KeyError(f"unknown metric {key!r}; known: {', '.join(CATALOG)}") from None


def error_of(key: str, value: float) -> float:
    """``value`` of metric ``key`` as an error: 0 for a perfect candidate, larger is worse.

    lower: ``value``; higher: ``1 - value`` (SSIM), ``10**(-value/10)`` (PSNR in dB: the
    MSE) or ``10 - value`` (JOD); zero: ``|value|``. ``ValueError`` for an ``info`` metric
    (it is not a score).
    """
    m = metric(key)
    value = float(value)
    if m.direction == "lower":
        return value
    if m.direction == "zero":
        return abs(value)
    if m.direction == "higher":
        if m.unit.startswith("JOD"):
            return 10.0 - value
        return 10.0 ** (-value / 10.0) if m.unit == "dB" else 1.0 - value
    raise ValueError(f"{key} is {m.better}: it has no error")


def within_noise(key: str, value: float, floor: float) -> bool:
    """True when ``value`` is no worse than the noise floor ``floor`` (what an exact
    candidate scores against a noisy reference), judged in the metric's direction."""
    if metric(key).direction == "info" or not _finite(value, floor):
        return False
    return error_of(key, value) <= error_of(key, floor)


def regressed(
    key: str,
    value: float,
    floor: float,
    previous: float,
    previous_floor: float,
    *,
    tolerance: float = 0.0,
    relative: bool = False,
) -> bool:
    """True when ``value`` is worse than ``previous`` (a baseline run's value) by more than
    both runs' noise floors combined and a ``tolerance``: ``error(value) - error(previous) >
    error(floor) + error(previous_floor) + t``, with ``t = tolerance`` (in the metric's error
    units) or, ``relative``, ``t = tolerance * error(previous)``. Never for an ``info``
    metric or a non-finite number."""
    if metric(key).direction == "info" or not _finite(value, floor, previous, previous_floor):
        return False
    worse = error_of(key, value) - error_of(key, previous)
    allowed = tolerance * abs(error_of(key, previous)) if relative else tolerance
    # a floor is a noise magnitude: a signed metric's floor below 0 counts as none
    floors = max(error_of(key, floor), 0.0) + max(error_of(key, previous_floor), 0.0)
    return worse > floors + allowed


def _finite(*values) -> bool:
    return all(v is not None and math.isfinite(float(v)) for v in values)
