"""Diagnoses of a score with a large error (:func:`metrics.diagnose` on its first frame).

The likely cause (a flipped, transposed, inverted, wrongly encoded or shifted candidate) is
recorded in ``metrics.json`` (``diagnoses``), printed, listed in the Markdown summary and
shown on the report's first screen. A sub-pixel shift of a mask's edges is named with its
estimate in pixels. An engine's colour also gets :func:`explain_colour`: the per-shape
table (``materials``), the gaps that explain its error (``colour_causes``: a global or
per-material gain, gamma 2.2 against sRGB, a sub-pixel edge shift) and its metrics after
the best per-material gain (``gain_corrected``) beside the raw ones.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ...metrics.colour_causes import (
    EXPLAINED,
    colour_causes,
    material_gain_corrected,
    material_rows,
)
from ...metrics.diagnose import REMOVED_FRACTION
from ...metrics.shift import apply_shift, subpixel_shift
from ..reference.exr import read_exr
from .result import ScoreResult

__all__ = ["diagnose_result", "explain_colour"]

#: Sub-pixel shifts of a mask's edges below this many pixels are not named.
MIN_SHIFT_PX = 0.2
#: Material gains within this of 1 are no gain (:mod:`metrics.colour_causes`).
NO_GAIN = 0.01
#: Rows of the per-shape table named on the report's first screen.
SHOWN_ROWS = 3


def _stderr(result: ScoreResult, channel: str) -> np.ndarray:
    ch = read_exr(result.reference_folders[0] / "reference.exr")
    if channel == "color":
        return np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1)
    return ch[f"{channel}_stderr"]


def diagnose_result(result: ScoreResult, *, channel: str, floors: dict | None) -> dict:
    """``{"error", "noise_floor", "tried", "likely"}`` of the first frame (see
    :func:`metrics.diagnose`) of a score of ``channel`` whose noise floors are ``floors``,
    plus ``notes``: a hint for a grey mask stored as RGB."""
    frame = result.frames[0]
    kind = (
        "color" if channel == "color" else ("visibility" if channel == "visibility" else "coverage")
    )
    # the score's own floor of the same mean |error| where it has one
    floors = floors or {}
    floor = floors.get({"visibility": "visibility_mae", "coverage": "coverage_mae"}.get(kind, ""))
    found = M.diagnose(
        frame.reference,
        frame.candidate,
        reference_stderr=_stderr(result, channel),
        kind=kind,
        mask=frame.receivers,
        noise_floor=floor,
    )
    found["notes"] = []
    if kind != "color" and found["large"] and found["likely"] is None:
        found["notes"] += _mask_shift(frame, found["error"])
    cand = frame.candidate
    if found["large"] and cand.ndim == 3 and np.array_equal(cand[..., 0], cand[..., 1]):
        if np.array_equal(cand[..., 0], cand[..., 2]):
            found["notes"].append(
                "the candidate's R, G and B are equal: a grey mask stored as RGB? score it "
                "with --channel visibility (or coverage)"
            )
    return found


def _mask_shift(frame, error: float) -> list[str]:
    """A mask's edges moved by a fraction of a pixel (a shadow map read one texel over, a
    half-pixel offset): the shift estimated, named when undoing it leaves at most
    :data:`metrics.colour_causes.EXPLAINED` of the error."""
    mask = frame.receivers
    shift = subpixel_shift(frame.reference, frame.candidate, mask=mask)
    if shift["magnitude"] < MIN_SHIFT_PX:
        return []
    back = apply_shift(frame.candidate, -shift["dx"], -shift["dy"])
    d = np.abs(back - frame.reference)
    left = float(d[mask].mean() if mask is not None else d.mean())
    if left > EXPLAINED * error:
        return []
    size = "sub-pixel" if shift["magnitude"] < 1.0 else "more than a pixel"
    return [
        f"likely cause: edges shifted by ({shift['dx']:+.2f}, {shift['dy']:+.2f}) px "
        f"({shift['magnitude']:.2f} px, {size}): undone, the mean |error| drops from "
        f"{error:.4g} to {left:.4g} (a shadow map read one texel over, a half-pixel offset)"
    ]


def explain_colour(
    result: ScoreResult, record: dict, *, exposure, names=None
) -> tuple[list[str], list[str]]:
    """Per-shape rows, the gaps that explain the colour error and the metrics after the best
    per-material gain, into ``record`` (``materials``, ``colour_causes``, ``gain_corrected``;
    it also holds the score's ``diagnosis``, ``flip_mean`` and ``delta_e2000_mean``) for
    frame 0; ``exposure``: the score's tone mapping. Returns ``(causes, details)``: a
    message per gap that explains the error (diagnoses), and the worst rows and the
    gain-corrected metrics when the error is large or explained
    (``colour_causes["details"]``: printed and shown on the report's first screen)."""
    frame = result.frames[0]
    ch = read_exr(result.reference_folders[0] / "reference.exr")
    ids = np.asarray(ch["id"]).astype(np.int64)
    ref, cand = frame.reference, frame.candidate
    rows = material_rows(ref, cand, ids, flip_map=frame.maps.get("flip"), names=names)
    floor = (record.get("diagnosis") or {}).get("noise_floor") or 0.0
    # an EXR (no transfer) holds linear values: a transfer-curve cause names the file's content
    layout = record.get("candidate_layout") or {}
    linear_file = "transfer" in layout and layout["transfer"] is None
    found = colour_causes(ref, cand, ids, noise_floor=floor, names=names, linear_file=linear_file)
    exposure = exposure or 0.0
    record["materials"] = rows
    record["colour_causes"] = found
    gains = [g for g in found["material_gains"].values() if g is not None]
    if any(abs(g - 1.0) > NO_GAIN for g in gains):
        fixed = material_gain_corrected(ref, cand, ids).astype(np.float32)
        flip = float(M.flip(ref, fixed, mode="LDR", exposure=exposure))
        de = float(M.delta_e2000(ref, fixed, exposure=exposure))
    else:  # no material off by a gain: the raw values (FLIP is a case's costliest metric)
        flip, de = record.get("flip_mean"), record.get("delta_e2000_mean")
    record["gain_corrected"] = {
        "flip_mean": flip,
        "delta_e2000_mean": de,
        "gains": {str(k): v for k, v in found["material_gains"].items()},
    }
    causes = [f"colour: {c['message']}" for c in found["causes"]]
    details = []
    large = (record.get("diagnosis") or {}).get("error", 0.0) > 5.0 * max(floor, 1e-6)
    if large or causes:
        for row in rows[:SHOWN_ROWS]:
            details.append(
                f"shape {row['name'] or row['id']}: {row['pixels']} px, candidate/reference "
                f"{row['mean_ratio']:.4g}, FLIP {row['flip_mean']:.4g}"
                if row["mean_ratio"] is not None and row["flip_mean"] is not None
                else f"shape {row['name'] or row['id']}: {row['pixels']} px"
            )
    if found["causes"] and found["causes"][0]["error"] <= REMOVED_FRACTION * found["error"]:
        g = record["gain_corrected"]
        details.append(
            f"after the best per-material gain: FLIP {g['flip_mean']:.4g} (raw "
            f"{record.get('flip_mean') or 0:.4g}), dE2000 {g['delta_e2000_mean']:.4g}"
        )
    found["details"] = details
    return causes, details
