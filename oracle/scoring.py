"""The ``score`` and ``report`` commands: glue between CLI arguments and the library."""

from __future__ import annotations

import json
import re
from pathlib import Path

import metrics as M
import reports

from .candidates import load_candidate
from .score import ScoreError, parse_thresholds, score
from .score_output import write_score_folder

__all__ = ["combine_reports", "model_candidate", "score_command", "score_technique"]

_FRAME_PATTERN = re.compile(r"\{frame(?::[^}]*)?\}")


def model_candidate(technique: str, params: dict):
    """Candidate callable running a technique model on each frame's scene."""
    import raster_models

    def run(frame_scene, k):
        res = raster_models.run(technique, frame_scene, **params)
        info = {
            "frame": k,
            "technique": technique,
            "cost": res.cost,
            "params": res.params,
            "diagnostics": res.diagnostics,
            "model_seconds": res.wall_seconds,
        }
        return res.outputs["visibility"].astype("float32"), info

    return run


def file_candidate(pattern: str, channel: str, frames: int | None):
    """Candidate callable reading (and validating) an engine's image of each frame."""
    has_frame = bool(_FRAME_PATTERN.search(pattern))
    if frames and frames > 1 and not has_frame:
        raise ScoreError(
            "--frames needs a --candidate pattern with {frame}, e.g. frame_{frame:03d}.exr"
        )

    def run(frame_scene, k):
        path = pattern.format(frame=k) if has_frame else pattern
        image = load_candidate(
            path, channel=channel, expected_shape=(frame_scene.height, frame_scene.width)
        )
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
    camera_path = args.camera_path or "dolly"
    frames = args.frames if args.frames and args.frames > 1 else None
    params, cost = None, None
    if args.technique:
        import raster_models

        if args.channel == "color":
            raise ScoreError(
                f"technique {args.technique} produces visibility; --channel color does not apply"
            )
        params = raster_models.parse_params(args.technique, args.params)
        channel = "visibility"
        candidate = model_candidate(args.technique, params)
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
    )
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
    """Score one technique model on one scene frame into ``out`` (the main job's unit)."""
    result = score(
        loaded,
        channel="visibility",
        candidate_frames=model_candidate(technique, params),
        spp=spp,
        seed=seed,
        cache=cache,
        quiet=quiet,
    )
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
