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

from ... import metrics as M
from .candidates import load_candidate
from .gates import (
    Gate,
    Verdict,
    check_applicable,
    check_baseline_scene,
    compare_baseline,
    evaluate_gates,
)
from .output import write_score_folder
from .score import ScoreError, score
from .technique import score_model, technique_channels

__all__ = ["FRAME_PATTERN", "file_candidate", "score_to_folder"]

#: A ``{frame}`` field (with an optional format) in a candidate file pattern.
FRAME_PATTERN = re.compile(r"\{frame(?::[^}]*)?\}")


def _check_coverage(image: np.ndarray, path) -> None:
    if image.ndim != 2:
        raise ScoreError(
            f"candidate {Path(path).name} coverage must be one channel, got shape {image.shape}"
        )
    n_out = int(((image < 0) | (image > 1)).sum())
    if n_out:
        raise ScoreError(
            f"candidate {Path(path).name} coverage must be in [0, 1], got {n_out} values outside"
        )


def file_candidate(pattern: str, *, channel: str, frames: int | None):
    """Candidate callable ``(frame_scene, k) -> (image, info)`` reading (and validating) an
    engine's image of each frame: ``pattern`` formatted with ``frame=k`` when it has a
    ``{frame}`` field (required for ``frames`` > 1)."""
    has_frame = bool(FRAME_PATTERN.search(pattern))
    if frames and frames > 1 and not has_frame:
        raise ScoreError(
            "--frames needs a --candidate pattern with {frame}, e.g. frame_{frame:03d}.exr"
        )

    def run(frame_scene, k):
        path = pattern.format(frame=k) if has_frame else pattern
        # a PNG coverage mask is grey data, read as a PNG visibility mask is (not decoded)
        png = Path(path).suffix.lower() == ".png"
        image = load_candidate(
            path,
            channel="visibility" if channel == "coverage" and png else channel,
            expected_shape=(frame_scene.height, frame_scene.width),
        )
        if channel == "coverage":
            _check_coverage(image, path)
        return image, {"frame": k, "file": str(path)}

    return run


def _check_candidates(fn, loaded, frames, camera_path) -> None:
    """Read every candidate frame before rendering anything (bad files fail fast)."""
    n = frames or 1
    for k in range(n):
        scene_k = loaded.with_frame(k, path=camera_path, n_frames=n) if frames else loaded
        fn(scene_k, k)


def score_to_folder(
    loaded,
    *,
    out: Path,
    technique: str | None = None,
    params: dict | None = None,
    candidate: str | None = None,
    channel: str | None = None,
    spp: int = 64,
    seed: int = 0,
    frames: int | None = None,
    camera_path: str | None = "dolly",
    cache=None,
    quiet: bool = True,
    flip_mode: str = "LDR",
    ppd: float = M.DEFAULT_PPD,
    thresholds: dict[str, float] | None = None,
    gates: list[Gate] | None = None,
    baseline: dict | None = None,
    baseline_source: str = "baseline",
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
    channel : what is scored (None: the technique's primary channel; ``color`` for files).
    frames : score that many frames of ``camera_path`` and add the temporal metrics (None or
        1: the scene's own frame).
    thresholds : ``{metric: limit}`` (``--fail-above`` gates, as
        :func:`oracle.scoring.score.parse_thresholds` gives them).
    gates : from :func:`oracle.scoring.gates.parse_gates` (``--fail-above``/``--fail-below``).
    baseline, baseline_source : a previous run's ``metrics.json`` record (from
        :func:`oracle.scoring.gates.load_baseline`) and its path, for messages.
    """
    if (technique is None) == (candidate is None):
        raise ScoreError("score: give a technique or a candidate file (one of them)")
    frames = frames if frames and frames > 1 else None
    gates = [*(gates or []), *(Gate(k, "<=", v) for k, v in (thresholds or {}).items())]
    # gates and the baseline are checked before rendering anything where the kinds scored are
    # known, and again on the record (evaluate_gates, compare_baseline)
    if baseline is not None:
        check_baseline_scene(baseline, loaded, frames=frames or 1, source=baseline_source)
    opts = dict(spp=spp, seed=seed, frames=frames, camera_path=camera_path, cache=cache)
    opts.update(quiet=quiet, flip_mode=flip_mode, ppd=ppd)
    cost = None
    if technique is not None:
        params = dict(params or {})
        # a model is scored on every channel it produces: gates are checked before it runs
        check_applicable(gates, kinds=technique_channels(technique), frames=frames or 1)
        result = score_model(loaded, technique, params, channel=channel, **opts)
        info = result.record["candidate_info"][0]
        cost, params = info["cost"], info["params"]
        name = technique
    else:
        if params:
            raise ScoreError("--set applies to --technique, not to --candidate")
        params = None
        channel = channel or "color"
        # a layer name (not a kind) is resolved when the file is read: checked on the record
        kinds = (channel,) if channel in ("visibility", "color", "coverage") else None
        check_applicable(gates, kinds=kinds, frames=frames or 1)
        read = file_candidate(candidate, channel=channel, frames=frames)
        _check_candidates(read, loaded, frames, camera_path)
        result = score(loaded, channel=channel, candidate_frames=read, **opts)
        name = Path(candidate).name
    verdict = Verdict(scene=loaded.name, checks=evaluate_gates(gates, result.record))
    if baseline is not None:
        against = compare_baseline(result.record, baseline, source=baseline_source)
        verdict.add(against.checks, against.notes)
    write_score_folder(
        result,
        out,
        loaded=loaded,
        name=name,
        gates=gates,
        verdict=verdict,
        technique=technique,
        params=params,
        cost=cost,
    )
    return verdict
