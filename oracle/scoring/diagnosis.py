"""Diagnoses of a score with a large error (:func:`metrics.diagnose` on its first frame).

The likely cause (a flipped, transposed, inverted, wrongly encoded or shifted candidate) is
recorded in ``metrics.json`` (``diagnoses``), printed, listed in the Markdown summary and
shown on the report's first screen.
"""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ..reference.exr import read_exr
from .result import ScoreResult

__all__ = ["diagnose_result"]


def _stderr(result: ScoreResult) -> np.ndarray:
    channel = result.record["channel"]
    ch = read_exr(result.reference_folders[0] / "reference.exr")
    if channel == "color":
        return np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1)
    return ch[f"{channel}_stderr"]


def diagnose_result(result: ScoreResult) -> dict:
    """``{"error", "noise_floor", "tried", "likely"}`` of the first frame (see
    :func:`metrics.diagnose`), plus ``notes``: a hint for a grey mask stored as RGB."""
    frame = result.frames[0]
    channel = result.record["channel"]
    kind = (
        "color" if channel == "color" else ("visibility" if channel == "visibility" else "coverage")
    )
    # the score's own floor of the same mean |error| where it has one
    floors = result.record.get("noise_floor") or {}
    floor = floors.get({"visibility": "visibility_mae", "coverage": "coverage_mae"}.get(kind, ""))
    found = M.diagnose(
        frame.reference,
        frame.candidate,
        reference_stderr=_stderr(result),
        kind=kind,
        mask=frame.receivers,
        noise_floor=floor,
    )
    found["notes"] = []
    cand = frame.candidate
    if found["large"] and cand.ndim == 3 and np.array_equal(cand[..., 0], cand[..., 1]):
        if np.array_equal(cand[..., 0], cand[..., 2]):
            found["notes"].append(
                "the candidate's R, G and B are equal: a grey mask stored as RGB? score it "
                "with --channel visibility (or coverage)"
            )
    return found
