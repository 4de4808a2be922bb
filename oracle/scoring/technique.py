"""Score a technique model: run it on each frame's scene and score what it produces.

Shadow techniques are scored on visibility; anti-aliasing techniques on colour, with the
coverage metrics (against the straight-edge floor of their sample count) merged in. The model
runs once per frame whatever the number of channels scored.

Every colour candidate is linear radiance that scoring tone-maps with the reference's
exposure and the ACES curve (``tone_mapping`` in ``metrics.json``), the reference alike.
FXAA works in display space (:mod:`raster_models.aa.fxaa`): its ``color`` is the radiance the
same pipeline maps to its LDR sRGB output, so its blends are scored as displayed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ... import raster_models
from .request import ScoreRequest
from .result import ScoreError, ScoreResult
from .score import score

__all__ = ["score_model", "technique_channels"]


def technique_channels(technique: str) -> tuple[str, ...]:
    """The channels a registered technique's model produces and is scored on (first: the
    primary one; its family record's ``channels``). Raises ``raster_models.ModelError`` for
    an unknown technique."""
    return raster_models.family(technique).channels


def _sample_count(res) -> int:
    """Samples per pixel of an AA model run: its cost record's ``samples``, else its
    ``samples`` parameter, else 1 (no AA, FXAA: one sample at the pixel centre)."""
    n = res.cost.get("samples", res.params.get("samples", 1))
    return int(n) if isinstance(n, int | np.integer) and not isinstance(n, bool) else 1


def score_model(request: ScoreRequest) -> ScoreResult:
    """Score a technique model's request (:meth:`ScoreRequest.for_model`; ``raster-oracle
    score --technique``): an anti-aliasing model runs frame 0 first, its full parameter
    record giving the sample count its coverage floor needs; then :func:`score`, whose plan
    merges the coverage and adds the steady-state yardstick where the family asks."""
    if not request.is_model:
        raise ScoreError("score_model scores a technique model's request")
    family = request.family
    if family.coverage_channel is not None and request.aa_samples is None:
        request.candidate_frames()(request.frame_scenes[0], 0)
        request = replace(request, aa_samples=_sample_count(request.candidate.runs[0]))
    return score(request)
