"""The ``score`` and ``report`` commands: glue between CLI arguments and the library."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

import metrics as M
import reports

from ..scoring.candidates import load_candidate
from ..scoring.output import write_score_folder
from ..scoring.score import COVERAGE_KEYS, ScoreError, parse_thresholds, score

__all__ = [
    "combine_reports",
    "model_candidate",
    "score_command",
    "score_model",
    "score_technique",
    "technique_family",
]

#: Candidate channels each technique family produces (the first is scored first).
FAMILY_CHANNELS = {"shadow": ("visibility",), "aa": ("color", "coverage")}

_FRAME_PATTERN = re.compile(r"\{frame(?::[^}]*)?\}")


def technique_family(technique: str) -> str:
    """``"shadow"`` or ``"aa"``: the family of a registered technique."""
    import raster_models

    t = raster_models.TECHNIQUES.get(technique)
    return getattr(t, "family", "shadow") if t is not None else "shadow"


def model_candidate(technique: str, params: dict, *, channel: str = "visibility", runs=None):
    """Candidate callable running a technique model on each frame's scene.

    ``channel`` picks the output scored (``visibility``; ``color`` or ``coverage`` for the
    anti-aliasing family). ``runs``, a dict shared between callables, keeps each frame's
    model result so that scoring colour and coverage runs the model once per frame.
    """
    import raster_models

    runs = {} if runs is None else runs

    def run(frame_scene, k):
        if k not in runs:
            runs[k] = raster_models.run(technique, frame_scene, **params)
        res = runs[k]
        info = {
            "frame": k,
            "technique": technique,
            "cost": res.cost,
            "params": res.params,
            "diagnostics": res.diagnostics,
            "model_seconds": res.wall_seconds,
        }
        return np.asarray(res.outputs[channel], dtype=np.float32), info

    return run


def _sample_count(res) -> int:
    """Samples per pixel of an AA model run: its cost record's ``samples``, else its
    ``samples`` parameter, else 1 (no AA, FXAA: one sample at the pixel centre)."""
    n = res.cost.get("samples", res.params.get("samples", 1))
    return int(n) if isinstance(n, int | np.integer) and not isinstance(n, bool) else 1


def _check_technique_channel(technique: str, family: str, channel: str | None) -> None:
    produced = FAMILY_CHANNELS.get(family, ("visibility",))
    if channel is not None and channel not in produced:
        raise ScoreError(
            f"technique {technique} produces {' and '.join(produced)}; "
            f"--channel {channel} does not apply"
        )


def _merge_coverage(result, coverage) -> None:
    """Add the coverage metrics, floor and error map of ``coverage`` to the colour result."""
    for key in COVERAGE_KEYS:
        result.record[key] = coverage.record.get(key)
    floor = result.record.get("noise_floor")
    cov_floor = coverage.record.get("noise_floor") or {}
    if floor is not None:
        floor.update({k: v for k, v in cov_floor.items() if k in COVERAGE_KEYS})
    if result.record.get("frames") and coverage.record.get("frames"):
        for mine, theirs in zip(result.record["frames"], coverage.record["frames"], strict=True):
            mine.update({k: theirs.get(k) for k in COVERAGE_KEYS})
    for mine, theirs in zip(result.frames, coverage.frames, strict=True):
        mine.metrics.update({k: theirs.metrics.get(k) for k in COVERAGE_KEYS})
        if "coverage_error" in theirs.maps:
            mine.maps["coverage_error"] = theirs.maps["coverage_error"]
    result.record["coverage_reference"] = coverage.record["reference"]
    result.record["wall_seconds"] += coverage.record["wall_seconds"]


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


def file_candidate(pattern: str, channel: str, frames: int | None):
    """Candidate callable reading (and validating) an engine's image of each frame."""
    has_frame = bool(_FRAME_PATTERN.search(pattern))
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


def _check_candidates(fn, loaded, frames, camera_path):
    """Read every candidate frame before rendering anything (bad files fail fast)."""
    n = frames or 1
    for k in range(n):
        scene_k = loaded.with_frame(k, path=camera_path, n_frames=n) if frames else loaded
        fn(scene_k, k)


def score_command(args, loaded, cache) -> list[str]:
    """Run ``raster-oracle score``; returns the metrics above their thresholds."""
    thresholds = parse_thresholds(args.fail_above)
    # A light path alone keeps the scene's camera still (frames move the light only).
    camera_path = args.camera_path or (None if getattr(args, "light_path", None) else "dolly")
    frames = args.frames if args.frames and args.frames > 1 else None
    params, cost = None, None
    aa_samples = None
    if args.technique:
        import raster_models

        params = raster_models.parse_params(args.technique, args.params)
        family = technique_family(args.technique)
        _check_technique_channel(args.technique, family, args.channel)
        channel = FAMILY_CHANNELS.get(family, ("visibility",))[0]
        runs = {}
        candidate = model_candidate(args.technique, params, channel=channel, runs=runs)
        if family == "aa":
            # run frame 0 first: its full parameter record gives the sample count
            scene0 = loaded.with_frame(0, path=camera_path, n_frames=frames) if frames else loaded
            candidate(scene0, 0)
            aa_samples = _sample_count(runs[0])
        name = args.technique
    else:
        if args.params:
            raise ScoreError("--set applies to --technique, not to --candidate")
        channel = args.channel or "color"
        candidate = file_candidate(args.candidate, channel, frames)
        _check_candidates(candidate, loaded, frames, camera_path)
        name = Path(args.candidate).name
    result = score(
        loaded,
        channel=channel,
        candidate_frames=candidate,
        spp=args.spp,
        seed=args.seed,
        frames=frames,
        camera_path=camera_path,
        cache=cache,
        quiet=args.quiet,
        flip_mode=args.flip_mode,
        ppd=args.ppd or M.DEFAULT_PPD,
        aa_samples=aa_samples,
    )
    if args.technique and technique_family(args.technique) == "aa":
        coverage = score(
            loaded,
            channel="coverage",
            candidate_frames=model_candidate(args.technique, params, channel="coverage", runs=runs),
            spp=args.spp,
            seed=args.seed,
            frames=frames,
            camera_path=camera_path,
            cache=cache,
            quiet=args.quiet,
            ppd=args.ppd or M.DEFAULT_PPD,
            aa_samples=aa_samples,
        )
        _merge_coverage(result, coverage)
    if args.technique:
        info = result.record["candidate_info"][0]
        cost, params = info["cost"], info["params"]
    return write_score_folder(
        result,
        args.out,
        loaded=loaded,
        name=name,
        thresholds=thresholds,
        technique=args.technique,
        params=params,
        cost=cost,
    )


def score_model(
    loaded,
    technique: str,
    params: dict,
    *,
    spp: int,
    seed: int,
    cache,
    quiet: bool,
    floor_cache: dict | None = None,
):
    """Score one technique configuration on one scene frame: the :class:`ScoreResult` of
    ``raster-oracle score --technique`` (the model runs once per frame).

    Shadow techniques are scored on visibility; anti-aliasing techniques on colour, with the
    coverage metrics (against the N-sample floor of their ``samples``) merged in.
    ``floor_cache``: see :func:`oracle.scoring.score.score` (a sweep worker's noise floors).
    """
    family = technique_family(technique)
    runs: dict = {}
    aa_samples = None
    if family == "aa":
        model_candidate(technique, params, channel="color", runs=runs)(loaded, 0)
        aa_samples = _sample_count(runs[0])
    kw = dict(spp=spp, seed=seed, cache=cache, quiet=quiet, aa_samples=aa_samples)
    if floor_cache is not None:
        kw["floor_cache"] = floor_cache
    channel = FAMILY_CHANNELS.get(family, ("visibility",))[0]
    result = score(
        loaded,
        channel=channel,
        candidate_frames=model_candidate(technique, params, channel=channel, runs=runs),
        **kw,
    )
    if family == "aa":
        coverage = score(
            loaded,
            channel="coverage",
            candidate_frames=model_candidate(technique, params, channel="coverage", runs=runs),
            **kw,
        )
        _merge_coverage(result, coverage)
    return result


def score_technique(
    loaded,
    technique: str,
    params: dict,
    *,
    out: Path,
    spp: int,
    seed: int,
    cache,
    quiet: bool,
    name: str | None = None,
    thresholds: dict | None = None,
) -> list[str]:
    """Score one technique model on one scene frame into ``out`` (the main job's unit).

    Shadow techniques are scored on visibility; anti-aliasing techniques on colour, with the
    coverage metrics added.
    """
    result = score_model(loaded, technique, params, spp=spp, seed=seed, cache=cache, quiet=quiet)
    info = result.record["candidate_info"][0]
    return write_score_folder(
        result,
        out,
        loaded=loaded,
        name=name or technique,
        thresholds=thresholds or {},
        technique=technique,
        params=info["params"],
        cost=info["cost"],
    )


def combine_reports(folders: list[Path], out: Path, *, title: str) -> int:
    """Combine the cases of several score folders into one report; returns the case count."""
    out = Path(out)
    if out.exists() and out.is_dir():
        raise ScoreError(f"--out {out} is a folder; give the report file to write")
    cases, scenes, provs = [], [], []
    for folder in folders:
        js = Path(folder) / "report.json"
        if not js.is_file():
            raise ScoreError(f"{folder} is not a score folder (no report.json)")
        try:
            data = json.loads(js.read_text())
        except ValueError as exc:
            raise ScoreError(f"{js} is not valid JSON: {exc}") from None
        cases.extend(reports.read_cases(js, relative_to=out.parent.resolve()))
        provs.append(data.get("provenance", {}))
        scenes.append(str(data.get("provenance", {}).get("scene", "?")))
    provenance = {"folders": [str(f) for f in folders], "scenes": sorted(set(scenes))}
    for key in ("backend", "reference spp", "seed", "filter", "ppd", "tone mapper", "versions"):
        values = {json.dumps(p.get(key), sort_keys=True) for p in provs}
        provenance[key] = provs[0].get(key) if len(values) == 1 else "varies"
    report = reports.build_report(cases, title=title, provenance=provenance)
    out.parent.mkdir(parents=True, exist_ok=True)
    reports.write_report(report, out)
    return len(cases)
