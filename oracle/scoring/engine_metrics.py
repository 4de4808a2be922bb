"""The engine teams' gates as metrics of a score (:mod:`metrics.engine_gates`), with their
noise floors; :mod:`oracle.scoring.ci.profiles` names the profiles that judge them.

Metrics (every frame; the record holds their mean over frames):

- ``unreal_{low,medium,high}_global_error`` / ``_local_error``: Unreal's screenshot
  comparison at its Low, Medium and High tolerances;
- ``unity_average_delta_e``: Unity's average JzAzBz delta E above the per-pixel 0.001;
- ``edge_aware_error_fraction`` (visibility, coverage): pixels beyond the edge-aware
  tolerance.

The images compared are what a screenshot holds: colour through the shared tone mapper
(sRGB-encoded display values), visibility and coverage as grey data; a shadow mask on the
oracle's receivers only (elsewhere the reference's value, as the other metrics see it).

Noise floors: the fractions get :func:`metrics.fraction_floor` of their value (the flagged
pixels near a tolerance flip when the reference is re-rendered, as for
``significant_fraction``), at least what the exact surrogate scores; Unity's average its
exact surrogate's mean delta E without the per-pixel allowance: ``max(0, dE - t)`` moves by
at most ``dE(r, r')`` when the reference ``r`` is re-rendered as ``r'``.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ...metrics import engine_gates as G
from ...metrics.catalog import KINDS
from ..reference.exr import read_exr

__all__ = [
    "ENGINE_CHANNELS",
    "ENGINE_GATE_KEYS",
    "add_engine_gate_metrics",
    "engine_gates_apply",
    "frame_stderr",
    "prepared_reference",
    "exact_floors",
]

#: The channels an engine writes (a model's front-most coverage is not one): the metric
#: catalogue's kinds.
ENGINE_CHANNELS = KINDS

_FRACTIONS = tuple(
    f"unreal_{level}_{which}_error"
    for level in G.UNREAL_TOLERANCES
    for which in ("global", "local")
)
#: The metric keys this module adds.
ENGINE_GATE_KEYS = (*_FRACTIONS, "unity_average_delta_e", "edge_aware_error_fraction")


def _applies(channel: str) -> bool:
    """The engine-gate pass runs on an engine's channels whose kind the metric catalogue
    declares one of :data:`ENGINE_GATE_KEYS` for."""
    return channel in ENGINE_CHANNELS and any(
        channel in M.CATALOG[k].kinds for k in ENGINE_GATE_KEYS
    )


def _display(image: np.ndarray, channel: str, exposure) -> np.ndarray:
    if channel == "color":
        return M.tonemap(image, exposure=exposure or 0.0)
    return np.clip(image, 0.0, 1.0)


#: References whose side of the engine gates a worker keeps (:func:`prepared_reference`).
PREPARED_REFERENCES = 8


def prepared_reference(ref, *, channel, exposure, key=None, memo=None) -> dict:
    """:func:`metrics.engine_gates.prepare_reference` of the reference ``ref`` as displayed;
    with ``memo`` (a worker's dict) and ``key`` (the reference's cache key), kept there for
    the next case judged against the same reference (the last :data:`PREPARED_REFERENCES`)."""
    if memo is None or key is None:
        return G.prepare_reference(_display(ref, channel, exposure))
    kept = memo.setdefault("engine gate references", {})
    mkey = (key, channel, exposure)
    if mkey in kept:
        kept[mkey] = kept.pop(mkey)  # the most recent last
        return kept[mkey]
    found = G.prepare_reference(_display(ref, channel, exposure))
    kept[mkey] = found
    while len(kept) > PREPARED_REFERENCES:
        kept.pop(next(iter(kept)))
    return found


def _values(ref, cand, se, *, channel, exposure, mask, prepared=None) -> dict:
    """The engine-gate metrics of one frame (and the pixel counts of their fractions)."""
    if prepared is None:
        prepared = prepared_reference(ref, channel=channel, exposure=exposure)
    r, c = None, _display(cand, channel, exposure)
    out, counts = {}, {}
    h, w = ref.shape[:2]
    block = int(np.ceil(h / 10.0)) * int(np.ceil(w / 10.0))
    found_all = G.unreal_comparisons(r, c, tolerances=G.UNREAL_TOLERANCES, prepared=prepared)
    for level, found in found_all.items():
        out[f"unreal_{level}_global_error"] = found["global_error"]
        out[f"unreal_{level}_local_error"] = found["local_error"]
        counts[f"unreal_{level}_global_error"] = h * w
        counts[f"unreal_{level}_local_error"] = block
    unity = G.unity_delta_e(r, c, prepared=prepared)
    out["unity_average_delta_e"] = unity["average"]
    if channel in M.CATALOG["edge_aware_error_fraction"].kinds:
        edge = G.edge_aware_error(ref, cand, reference_stderr=se, mask=mask)
        n = int(mask.sum()) if mask is not None else h * w
        # no receiver in view: nothing to judge (null, as the shadow metrics are)
        out["edge_aware_error_fraction"] = edge["fraction"] if n else None
        counts["edge_aware_error_fraction"] = n
    return out, counts, unity


def _stderr(ch: dict, channel: str) -> np.ndarray:
    if channel == "color":
        return np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1)
    return ch[f"{channel}_stderr"]


def exact_floors(
    reference, exact, reference_channels: dict, *, channel, exposure, mask, prepared=None
) -> dict:
    """What the exact surrogate ``exact`` scores on the engine-gate metrics against
    ``reference`` (the noise floors before the fractions' binomial bound; Unity's: the mean
    delta E, see the module docstring). Empty for channels other than visibility, color
    and coverage. ``prepared``: :func:`prepared_reference` of ``reference``."""
    if not _applies(channel):
        return {}
    se = _stderr(reference_channels, channel)
    if mask is not None:  # a shadow mask is judged on the receivers, as the candidate is
        exact = np.where(mask, exact, reference)
    values, _, unity = _values(
        reference, exact, se, channel=channel, exposure=exposure, mask=mask, prepared=prepared
    )
    values["unity_average_delta_e"] = float(np.mean(unity["map"]))
    return values


def engine_gates_apply(channel: str) -> bool:
    """True where the engine-gate pass runs on ``channel`` (:func:`add_engine_gate_metrics`)."""
    return _applies(channel)


def frame_stderr(reference_channels: dict, channel: str) -> np.ndarray:
    """The reference's standard error of ``channel`` (colour: ``(H, W, 3)``)."""
    return _stderr(reference_channels, channel)


def add_engine_gate_metrics(
    result, values: dict, floors: dict | None, *, channel, exposure, stderrs=None, prepared=None
):
    """Add the engine-gate metrics to every frame's metrics, their mean to ``values`` (the
    record's metric values), and raise each fraction's noise floor in ``floors`` (the exact
    surrogate's, from :func:`exact_floors`) to at least its binomial bound (channels
    visibility, color and coverage: what an engine writes). ``stderrs``: each frame's
    :func:`frame_stderr` (None: read from the frame's reference file); ``prepared``: a
    callable ``k -> prepared_reference`` of frame ``k`` (None: prepared here)."""
    if not _applies(channel):
        return
    per_frame, counts = [], []
    for k, frame in enumerate(result.frames):
        mask = frame.receivers
        cand = frame.candidate if mask is None else np.where(mask, frame.candidate, frame.reference)
        if stderrs is not None:
            se = stderrs[k]
        else:
            se = _stderr(read_exr(result.reference_folders[k] / "reference.exr"), channel)
        ready = prepared(k) if prepared is not None else None
        found, count, _ = _values(
            frame.reference, cand, se, channel=channel, exposure=exposure, mask=mask, prepared=ready
        )
        frame.metrics.update(found)
        per_frame.append(found)
        counts.append(count)
    record = values
    totals = {}
    for key in per_frame[0]:
        vals = [v[key] for v in per_frame if v[key] is not None]
        record[key] = float(np.mean(vals)) if vals else None
        if key in counts[0]:
            # the last frame's count for every frame, as the records have always been made
            # (their bytes kept); the frames' sum where that frame saw no receiver
            last = counts[-1][key] * len(counts)
            totals[key] = last if last > 0 else sum(c[key] for c in counts)
    if floors is None:
        return
    for key, n in totals.items():
        if record[key] is None or n == 0:  # no pixel counted (no receiver in view)
            floors.pop(key, None)
            continue
        floors[key] = max(floors.get(key) or 0.0, M.fraction_floor(record[key], n))
