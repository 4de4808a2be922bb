"""Score a technique model or an engine's images into a score folder (``raster-oracle score``).

The candidate is either a registered technique (run on each frame) or image files of an
engine (one file, or a ``str.format`` pattern with a ``{frame}`` field for a camera path).
Every candidate file is read and checked before any reference is rendered, and the folder is
written only when everything is computed (:func:`oracle.scoring.output.write_score_folder`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ...scenes.formats.inputs import read_export_record
from .candidates import load_motion
from .diagnosis import diagnose_result
from .gates import (
    Gate,
    Verdict,
    check_applicable,
    check_baseline_scene,
    compare_baseline,
    evaluate_gates,
)
from .layout import CandidateLayout, candidate_layout, read_candidate
from .options import ScoreOptions
from .output import write_score_folder
from .score import ScoreError, score
from .technique import score_model, technique_channels

__all__ = ["FRAME_PATTERN", "candidate_name", "file_candidate", "frame_file", "score_to_folder"]

#: A ``{frame}`` field (with an optional format) in a candidate file pattern.
FRAME_PATTERN = re.compile(r"\{frame(?::[^}]*)?\}")


def frame_file(pattern: str, k: int) -> str:
    """The candidate file of frame ``k``: ``pattern`` formatted with ``frame=k`` when it has a
    ``{frame}`` field, else ``pattern`` itself."""
    return pattern.format(frame=k) if FRAME_PATTERN.search(pattern) else pattern


def file_candidate(
    pattern: str,
    *,
    channel: str | None,
    frames: int | None,
    layout: CandidateLayout | None = None,
    motion: dict | None = None,
    visibility: str = "1-is-lit",
):
    """Candidate callable ``(frame_scene, k) -> (image, info)`` reading (and validating) an
    engine's image of each frame: ``pattern`` formatted with ``frame=k`` when it has a
    ``{frame}`` field (required for ``frames`` > 1). Every frame is read as ``layout`` says
    (None: :func:`oracle.scoring.layout.candidate_layout` of frame 0's file and ``channel``).
    ``motion`` (``layer``, ``convention``, optional ``disocclusion``): also read each frame's
    motion vectors (:func:`oracle.scoring.candidates.load_motion`) into the info's
    ``motion`` / ``disocclusion``, which ``score`` turns into the end-point error metrics.
    A visibility mask whose 1 means shadowed (``visibility="1-is-shadowed"``) is read as
    ``1 - value``.
    """
    has_frame = bool(FRAME_PATTERN.search(pattern))
    if frames and frames > 1 and not has_frame:
        raise ScoreError(
            "--frames needs a --candidate pattern with {frame}, e.g. frame_{frame:03d}.exr"
        )
    if layout is None:
        layout = candidate_layout(frame_file(pattern, 0), channel=channel)

    def run(frame_scene, k):
        path = frame_file(pattern, k)
        shape = (frame_scene.height, frame_scene.width)
        image = read_candidate(path, layout, expected_shape=shape)
        if layout.kind == "visibility" and visibility == "1-is-shadowed":
            image = (1.0 - image).astype(np.float32)
        info = {"frame": k, "file": str(path)}
        if motion is not None:
            info["motion"], info["disocclusion"] = load_motion(path, expected_shape=shape, **motion)
        return image, info

    return run


def candidate_name(pattern: str, *, frames: int | None, camera_path: str | None) -> str:
    """How the record and the report name an engine's candidate: the file name (frame 0's
    for a one-frame pattern), or for several frames the camera path and the frame list
    (``dolly frames 0-7``), never the raw ``{frame}`` pattern."""
    n = frames or 1
    if n == 1 or not FRAME_PATTERN.search(pattern):
        return Path(frame_file(pattern, 0)).name
    return f"{camera_path or 'camera'} frames 0-{n - 1}"


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
    thresholds: dict[str, float] | None = None,
    baseline: dict | None = None,
    baseline_source: str = "baseline",
    layout: CandidateLayout | None = None,
    name: str | None = None,
) -> Verdict:
    """Score ``technique`` (with ``params``) or the engine image file(s) ``candidate`` on
    ``loaded``, judge the gates and the baseline, and write the score folder ``out``; returns
    the :class:`oracle.scoring.gates.Verdict` (its checks, their lines, the exit code; as a
    list, the names of the failed checks).

    A gate that cannot be judged (a metric that does not apply to the candidate's kind or
    frame count, a null value) or a baseline of another run is a
    :class:`oracle.scoring.gates.GateError` raised before anything is written.

    Parameters
    ----------
    technique, params : a registered technique and its parsed parameters.
    candidate : an EXR or PNG file, or a pattern with ``{frame}`` (one of the two).
    channel : what is scored (None: the technique's primary channel; for files, inferred
        from the file when unambiguous); for files also an EXR channel or layer name.
    options : :class:`oracle.scoring.options.ScoreOptions` (reference spp and seed, frames
        and camera path, FLIP options, platform, the candidate mask's convention).
    layout : for files, what to read (:func:`oracle.scoring.layout.candidate_layout`; None:
        resolved here from frame 0's file and ``channel``).
    thresholds : ``{metric: limit}`` (``--fail-above`` gates, as
        :func:`oracle.scoring.score.parse_thresholds` gives them).
    gates : from :func:`oracle.scoring.gates.parse_gates` (``--fail-above``/``--fail-below``).
    baseline, baseline_source : a previous run's ``metrics.json`` record (from
        :func:`oracle.scoring.gates.load_baseline`) and its path, for messages; a baseline
        of another platform (``options.platform``) is a
        :class:`oracle.scoring.gates.GateError`.
    name : how the report names the case (default: the technique, or the candidate's file
        name; ``score-folder`` gives its case name, ``scene/channel``).
    """
    o = (options or ScoreOptions()).validate()
    frames, camera_path, platform = o.frames, o.camera_path, o.platform
    if (technique is None) == (candidate is None):
        raise ScoreError("score: give a technique or a candidate file (one of them)")
    gates = [*(gates or []), *(Gate(k, "<=", v) for k, v in (thresholds or {}).items())]
    # gates and the baseline are checked before rendering anything, against the kinds that
    # will be scored, and again on the record (evaluate_gates, compare_baseline)
    check = dict(gates=gates, baseline=baseline, loaded=loaded, frames=frames or 1)
    check.update(source=baseline_source, platform=platform)
    opts = dict(o.score_kwargs(), cache=cache)
    if o.motion is not None and technique is not None:
        raise ScoreError("--candidate-motion applies to --candidate, not to --technique")
    cost = None
    if technique is not None:
        params = dict(params or {})
        # a model is scored on every channel it produces
        _check_before_rendering(kinds=technique_channels(technique), **check)
        result = score_model(loaded, technique, params, channel=channel, **opts)
        info = result.record["candidate_info"][0]
        cost, params = info["cost"], info["params"]
        label = technique
    else:
        if params:
            raise ScoreError("--set applies to --technique, not to --candidate")
        params = None
        if layout is None:
            layout = candidate_layout(frame_file(candidate, 0), channel=channel)
        if o.visibility != "1-is-lit" and layout.kind != "visibility":
            raise ScoreError(
                f"--visibility {o.visibility} applies to shadow masks; this candidate is "
                f"{layout.kind}"
            )
        _check_before_rendering(kinds=(layout.kind,), **check)
        read = file_candidate(
            candidate,
            channel=channel,
            frames=frames,
            layout=layout,
            motion=o.motion,
            visibility=o.visibility,
        )
        _check_candidates(read, loaded, frames, camera_path)
        result = score(loaded, channel=layout.kind, candidate_frames=read, **opts)
        result.record["candidate_layout"] = {
            "kind": layout.kind,
            "channels": list(layout.names),
            "source": layout.source,
            "visibility": o.visibility if layout.kind == "visibility" else None,
        }
        label = candidate_name(candidate, frames=frames, camera_path=camera_path)
    # what an export was made for (size, light, camera path and frame): recorded with it
    source = Path(str(loaded.source))
    if source.name in ("scene.xml", "scene.glb") and source.is_file():
        result.record["export"] = read_export_record(source.parent)
    # the machine and driver the run stands for: baselines are kept per platform
    result.record["platform"] = platform
    verdict = Verdict(scene=loaded.name, checks=evaluate_gates(gates, result.record))
    # an engine's image that went wrong on its way out (flipped, encoded twice, shifted):
    # diagnosed; a model's output is what the technique computes, not a file to diagnose
    result.record["diagnoses"] = []
    if candidate is not None:
        found = diagnose_result(result)
        result.record["diagnosis"] = {k: found[k] for k in ("error", "noise_floor", "tried")}
        if found["likely"]:
            result.record["diagnoses"].append(found["likely"])
        result.record["diagnoses"] += [{"transform": None, "message": n} for n in found["notes"]]
        verdict.add(notes=[d["message"] for d in result.record["diagnoses"]])
    outside = result.record.get("outside_receivers") or {}
    if outside.get("differing"):
        verdict.add(
            notes=[
                f"visibility: {outside['differing']} of the {outside['pixels']} pixels off the "
                "oracle's receivers (sky, back faces, outside a spot cone) differ from the "
                "reference there; they are not scored"
            ]
        )
    if baseline is not None:
        against = compare_baseline(result.record, baseline, source=baseline_source)
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
