"""Score a technique model or an engine's images into a score folder (``raster-oracle score``).

The candidate is either a registered technique (run on each frame) or image files of an
engine (one file, or a ``str.format`` pattern with a ``{frame}`` field for a camera path).
Every candidate file is read and checked before any reference is rendered, and the folder is
written only when everything is computed (:func:`oracle.scoring.output.write_score_folder`).
"""

from __future__ import annotations

from pathlib import Path

from ...scenes.inputs import read_export_record
from .ci.checks import Gate, Verdict
from .ci.gates import applicable_gates, check_applicable, evaluate_gates, support_record
from .ci.regression import BaselineOptions, check_baseline_scene, compare_baseline
from .conformance import CONFORMANCE_KEYS, add_conformance, parse_expect
from .diagnosis import diagnose_result, explain_colour
from .inputs.frames import candidate_name, file_candidate, frame_file
from .inputs.layout import CandidateLayout, candidate_layout
from .options import ScoreOptions
from .output import write_score_folder
from .result import ScoreError
from .score import score
from .technique import score_model, technique_channels

__all__ = ["score_to_folder"]


def _check_candidates(fn, loaded, frames, camera_path) -> None:
    """Read every candidate frame before rendering anything (bad files fail fast)."""
    n = frames or 1
    for k in range(n):
        scene_k = loaded.with_frame(k, path=camera_path, n_frames=n) if frames else loaded
        fn(scene_k, k)


def _check_before_rendering(*, gates, baseline, loaded, kinds, frames, source, platform) -> None:
    """Gates that do not apply to ``kinds`` / ``frames`` and a baseline of another scene,
    size, light, frame count or kind fail here, before any reference is rendered."""
    check_applicable(gates, kinds=kinds, frames=frames)
    if baseline is not None:
        check_baseline_scene(
            baseline, loaded, frames=frames, kinds=kinds, source=source, platform=platform
        )


def _transfer(candidate: str, layout: CandidateLayout, transfer: str | None) -> str | None:
    """The transfer a candidate's colour is decoded with: ``srgb`` (default) or the one
    asked for, for a colour PNG; None for an EXR (linear) or data. ``--transfer`` on a
    candidate it does not apply to is a :class:`ScoreError`."""
    png = frame_file(candidate, 0).lower().endswith(".png")
    if png and layout.kind == "color":
        return transfer or "srgb"
    if transfer is not None:
        raise ScoreError(
            f"--transfer applies to the colour of a PNG candidate; this candidate is "
            f"{layout.kind} {'PNG' if png else 'EXR'}"
        )
    return None


def _score_files(loaded, candidate, *, channel, layout, o, opts, check):
    """Score the engine image file(s) ``candidate`` (checked and read before rendering)."""
    if layout is None:
        layout = candidate_layout(frame_file(candidate, 0), channel=channel)
    if o.visibility != "1-is-lit" and layout.kind != "visibility":
        raise ScoreError(
            f"--visibility {o.visibility} applies to shadow masks; this candidate is {layout.kind}"
        )
    transfer = _transfer(candidate, layout, o.transfer)
    gates, notes = applicable_gates(check.pop("gates"), kinds=(layout.kind,))
    _check_before_rendering(kinds=(layout.kind,), gates=gates, **check)
    if o.expect is not None:
        parse_expect(o.expect, kind=layout.kind)  # a bad claim fails before rendering
    else:
        asked = [g.metric for g in gates if g.metric in CONFORMANCE_KEYS]
        if asked:
            raise ScoreError(f"{asked[0]} is scored against --expect TECHNIQUE:...; give one")
    read = file_candidate(
        candidate,
        channel=channel,
        frames=o.frames,
        layout=layout,
        motion=o.motion,
        visibility=o.visibility,
        transfer=transfer,
    )
    _check_candidates(read, loaded, o.frames, o.camera_path)
    result = score(loaded, channel=layout.kind, candidate_frames=read, **opts)
    if o.expect is not None:
        n = o.frames or 1
        scenes_k = [
            loaded.with_frame(k, path=o.camera_path, n_frames=n) if o.frames else loaded
            for k in range(n)
        ]
        notes += add_conformance(
            result, scenes_k, o.expect, kind=layout.kind, ppd=o.ppd, gate_frames=o.gate_frames
        )
    result.record["candidate_layout"] = {
        "kind": layout.kind,
        "channels": list(layout.names),
        "source": layout.source
        if transfer in (None, "srgb")
        else layout.source.replace("sRGB-decoded", f"{transfer}-decoded"),
        "visibility": o.visibility if layout.kind == "visibility" else None,
        # how 8-bit colour was made linear (None: an EXR's linear values, or data)
        "transfer": transfer,
    }
    return result, gates, notes


def _notes(result, candidate, names=None) -> list[str]:
    """The diagnoses of an engine's image (flipped, encoded twice, shifted: a model's output
    is what the technique computes, not a file to diagnose) into the record, and the notes
    they and the receivers' count make."""
    result.record["diagnoses"] = []
    notes = []
    if candidate is not None:
        found = diagnose_result(result)
        result.record["diagnosis"] = {k: found[k] for k in ("error", "noise_floor", "tried")}
        causes, details = [], []
        if result.record["channel"] == "color" and names is not None:
            causes, details = explain_colour(result, names)
            best = result.record["colour_causes"]["causes"]
            # a gain read as a transfer curve: the cause that leaves less error is the one named
            if found["likely"] and best and best[0]["error"] < found["likely"]["error"]:
                found["likely"] = None
        if found["likely"]:
            result.record["diagnoses"].append(found["likely"])
        result.record["diagnoses"] += [{"transform": None, "message": n} for n in found["notes"]]
        result.record["diagnoses"] += [{"transform": None, "message": n} for n in causes]
        notes += [d["message"] for d in result.record["diagnoses"]] + details
    outside = result.record.get("outside_receivers") or {}
    if outside.get("differing"):
        notes.append(
            f"visibility: {outside['differing']} of the {outside['pixels']} pixels off the "
            "oracle's receivers (sky, back faces, outside a spot cone) differ from the "
            "reference there; they are not scored"
        )
    return notes


def score_to_folder(
    loaded,
    *,
    out: Path,
    technique: str | None = None,
    params: dict | None = None,
    candidate: str | None = None,
    channel: str | None = None,
    options: ScoreOptions | None = None,
    cache=None,
    gates: list[Gate] | None = None,
    baseline: dict | None = None,
    baseline_source: str = "baseline",
    layout: CandidateLayout | None = None,
    name: str | None = None,
    baseline_options: BaselineOptions | None = None,
) -> Verdict:
    """Score ``technique`` (with ``params``) or the engine image file(s) ``candidate`` on
    ``loaded``, judge the gates and the baseline, and write the score folder ``out``; returns
    the :class:`oracle.scoring.ci.checks.Verdict` (its checks, their lines, the exit code; as a
    list, the names of the failed checks).

    A gate that cannot be judged (a metric that does not apply to the candidate's kind or
    frame count, a null value) or a baseline of another run is a
    :class:`oracle.scoring.ci.checks.GateError` raised before anything is written; a profile's
    gate whose metric does not apply to the candidate's kind is left out with a note.

    Parameters
    ----------
    technique, params : a registered technique and its parsed parameters.
    candidate : an EXR or PNG file, or a pattern with ``{frame}`` (one of the two).
    channel : what is scored (None: the technique's primary channel; for files, inferred
        from the file when unambiguous); for files also an EXR channel or layer name.
    options : :class:`oracle.scoring.options.ScoreOptions` (reference spp and seed, frames
        and camera path, FLIP options, platform, the candidate mask's convention, the PNG
        transfer, the technique the engine claims: ``expect``).
    layout : for files, what to read (:func:`oracle.scoring.inputs.layout.candidate_layout`; None:
        resolved here from frame 0's file and ``channel``).
    gates : from :func:`oracle.scoring.ci.gates.parse_gates` (``--fail-above``/``--fail-below``)
        and :func:`oracle.scoring.ci.profiles.profile_gates`.
    baseline, baseline_source : a previous run's ``metrics.json`` record (from
        :func:`oracle.scoring.ci.regression.load_baseline`) and its path, for messages; a baseline
        of another platform (``options.platform``) is a
        :class:`oracle.scoring.ci.checks.GateError`.
    baseline_options : which metrics the baseline compares and their tolerances
        (:class:`oracle.scoring.ci.regression.BaselineOptions`; None: the gated metrics).
    name : how the report names the case (default: the technique, or the candidate's file
        name; ``score-folder`` gives its case name, ``scene/channel``).
    """
    o = (options or ScoreOptions()).validate()
    if (technique is None) == (candidate is None):
        raise ScoreError("score: give a technique or a candidate file (one of them)")
    if o.motion is not None and technique is not None:
        raise ScoreError("--candidate-motion applies to --candidate, not to --technique")
    # gates and the baseline are checked before rendering anything, against the kinds that
    # will be scored, and again on the record (evaluate_gates, compare_baseline)
    check = dict(gates=list(gates or []), baseline=baseline, loaded=loaded)
    check.update(frames=o.frames or 1, source=baseline_source, platform=o.platform)
    opts = dict(o.score_kwargs(), cache=cache)
    cost, notes = None, []
    if technique is not None:
        if o.transfer is not None or o.expect is not None:
            raise ScoreError("--transfer and --expect apply to --candidate, not to --technique")
        params = dict(params or {})
        kinds = technique_channels(technique)
        gates, notes = applicable_gates(check.pop("gates"), kinds=kinds)
        # a model is scored on every channel it produces
        _check_before_rendering(kinds=kinds, gates=gates, **check)
        result = score_model(loaded, technique, params, channel=channel, **opts)
        info = result.record["candidate_info"][0]
        cost, params = info["cost"], info["params"]
        label = technique
    else:
        if params:
            raise ScoreError("--set applies to --technique, not to --candidate")
        params = None
        result, gates, notes = _score_files(
            loaded, candidate, channel=channel, layout=layout, o=o, opts=opts, check=check
        )
        label = candidate_name(candidate, frames=o.frames, camera_path=o.camera_path)
    # what an export was made for (size, light, camera path and frame): recorded with it
    source = Path(str(loaded.source))
    if source.name in ("scene.xml", "scene.glb") and source.is_file():
        result.record["export"] = read_export_record(source.parent)
    # the machine and driver the run stands for: baselines are kept per platform
    result.record["platform"] = o.platform
    support_record(result.record)  # a metric over an empty set is None, support 0
    verdict = Verdict(scene=loaded.name, checks=evaluate_gates(gates, result.record))
    verdict.add(notes=notes + _notes(result, candidate, list(loaded.shape_names)))
    if baseline is not None:
        bo = baseline_options or BaselineOptions.gated(gates)
        against = compare_baseline(result.record, baseline, source=baseline_source, options=bo)
        verdict.add(against.checks, against.notes)
    write_score_folder(
        result,
        out,
        loaded=loaded,
        name=name or label,
        gates=gates,
        verdict=verdict,
        technique=technique,
        params=params,
        cost=cost,
    )
    return verdict
