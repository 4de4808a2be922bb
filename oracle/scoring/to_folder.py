"""Score a technique model or an engine's images into a score folder (``raster-oracle score``).

The candidate is either a registered technique (run on each frame) or image files of an
engine (one file, or a ``str.format`` pattern with a ``{frame}`` field for a camera path).
Every candidate file is read and checked before any reference is rendered, and the folder is
written only when everything is computed (:func:`oracle.scoring.output.write_score_folder`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from .channels import CHANNEL_KIND
from .ci.checks import Gate, Verdict
from .ci.gates import applicable_gates, check_applicable, evaluate_gates, support_record
from .ci.regression import BaselineOptions, check_baseline_scene, compare_baseline
from .conformance import CONFORMANCE_KEYS, parse_expect
from .inputs.frames import candidate_name
from .output import write_score_folder
from .request import ScoreRequest
from .result import ScoreError
from .score import score
from .technique import score_model

__all__ = ["score_to_folder"]


def _check_before_rendering(request: ScoreRequest, gates, *, baseline, source) -> tuple:
    """Gates that do not apply to the kinds scored or the frame count, a baseline of another
    scene, size, light, frame count or kind, a bad ``--expect`` and every candidate file fail
    here, before any reference is rendered; returns the gates kept and the notes of the
    profile gates left out."""
    o = request.options
    family = request.family
    kinds = family.channels if family is not None else (request.channel,)
    # the gates judge catalogue kinds; a temporal family's sequence has the temporal metrics
    gate_kinds = tuple(dict.fromkeys(CHANNEL_KIND.get(c, c) for c in kinds))
    temporal = family is not None and family.temporal and request.sequence
    gates, notes = applicable_gates(gates, kinds=gate_kinds, temporal=temporal)
    check_applicable(gates, kinds=gate_kinds, frames=o.frames or 1, temporal=temporal)
    if baseline is not None:
        check_baseline_scene(
            baseline,
            request.loaded,
            frames=o.frames or 1,
            kinds=gate_kinds,
            source=source,
            platform=o.platform,
        )
    if request.is_file:
        if o.expect is not None:
            parse_expect(o.expect, kind=request.channel)  # a bad claim fails before rendering
        else:
            asked = [g.metric for g in gates if g.metric in CONFORMANCE_KEYS]
            if asked:
                raise ScoreError(f"{asked[0]} is scored against --expect TECHNIQUE:...; give one")
        read = request.candidate_frames()
        for k, frame_scene in enumerate(request.frame_scenes):  # bad files fail fast
            read(frame_scene, k)
    return gates, notes


def _check_request(request: ScoreRequest) -> None:
    o = request.options
    if request.is_model:
        if o.motion is not None:
            raise ScoreError("--candidate-motion applies to --candidate, not to --technique")
        if o.transfer is not None or o.expect is not None:
            raise ScoreError("--transfer and --expect apply to --candidate, not to --technique")
        if o.family is not None:
            raise ScoreError("--family applies to --candidate (a technique has its own)")
    elif not request.is_file:
        raise ScoreError("score: give a technique or a candidate file (one of them)")


def score_to_folder(
    request: ScoreRequest,
    *,
    out: Path,
    gates: list[Gate] | None = None,
    baseline: dict | None = None,
    baseline_source: str = "baseline",
    name: str | None = None,
    baseline_options: BaselineOptions | None = None,
) -> tuple[Verdict, dict]:
    """Score ``request`` (a technique model's, :meth:`ScoreRequest.for_model`, or an
    engine's image files', :meth:`ScoreRequest.for_files`), judge the gates and the baseline,
    and write the score folder ``out``; returns the
    :class:`oracle.scoring.ci.checks.Verdict` (its checks, their lines, the exit code; as a
    list, the names of the failed checks) and the ``metrics.json`` record written.

    A gate that cannot be judged (a metric that does not apply to the candidate's kind or
    frame count, a null value) or a baseline of another run is a
    :class:`oracle.scoring.ci.checks.GateError` raised before anything is written; a profile's
    gate whose metric does not apply to the candidate's kind is left out with a note.

    Parameters
    ----------
    gates : from :func:`oracle.scoring.ci.gates.parse_gates` (``--fail-above``/``--fail-below``)
        and :func:`oracle.scoring.ci.profiles.profile_gates`.
    baseline, baseline_source : a previous run's ``metrics.json`` record (from
        :func:`oracle.scoring.ci.regression.load_baseline`) and its path, for messages; a
        baseline of another platform (``options.platform``) is a
        :class:`oracle.scoring.ci.checks.GateError`.
    baseline_options : which metrics the baseline compares and their tolerances
        (:class:`oracle.scoring.ci.regression.BaselineOptions`; None: the gated metrics).
    name : how the report names the case (default: the technique, or the candidate's file
        name; ``score-folder`` gives its case name, ``scene/channel``).
    """
    request = replace(request, options=request.options.validate())
    _check_request(request)
    o = request.options
    gates, notes = _check_before_rendering(
        request, list(gates or []), baseline=baseline, source=baseline_source
    )
    technique = params = cost = None
    if request.is_model:
        result = score_model(request)
        info = result.record["candidate_info"][0]
        technique, cost, params = request.candidate.technique, info["cost"], info["params"]
        label = technique
    else:
        result = score(request)
        label = candidate_name(
            request.candidate.pattern, frames=o.frames, camera_path=o.camera_path
        )
    support_record(result.record)  # a metric over an empty set is None, support 0
    verdict = Verdict(scene=request.loaded.name, checks=evaluate_gates(gates, result.record))
    verdict.add(notes=notes + result.notes)
    if baseline is not None:
        bo = baseline_options or BaselineOptions.gated(gates)
        against = compare_baseline(result.record, baseline, source=baseline_source, options=bo)
        verdict.add(against.checks, against.notes)
    record = write_score_folder(
        result,
        out,
        loaded=request.loaded,
        name=name or label,
        gates=gates,
        verdict=verdict,
        technique=technique,
        params=params,
        cost=cost,
    )
    return verdict, record
