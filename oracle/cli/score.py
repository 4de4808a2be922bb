"""Commands that score and report: ``score`` and ``report``."""

from __future__ import annotations

from pathlib import Path

from ...scenes.base.files import staged_folder
from . import args as A
from . import baseline_cmd, score_folder
from .gate_args import (
    add_gate_args,
    add_transfer_args,
    add_visibility_arg,
    baseline_options,
    check_junit,
    check_outputs_not_inputs,
    parse_all_gates,
    print_verdict,
    write_outputs,
)

__all__ = ["COMMANDS", "add_parsers"]

#: ``report --title`` default (a sweep report then gets its own title).
DEFAULT_TITLE = "raster-oracle report"


def add_parsers(sub) -> None:
    """Add ``score`` and ``report`` to the subparsers ``sub``."""
    p = sub.add_parser("score", help="score a model or an engine image against the reference")
    A.add_scene_args(p)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--technique", help="a technique model (see `techniques`)")
    what.add_argument(
        "--candidate",
        help="an EXR or PNG from your engine; with --frames use "
        "a pattern such as frame_{frame:03d}.exr",
    )
    A.add_set_arg(p)
    p.add_argument(
        "--channel",
        default=None,
        help="what to score: visibility, color, coverage or depth (an EXR's linear view depth: "
        "channel depth, Z, depth.Z or depth.Y), or for an engine's EXR a channel "
        "(msaa.coverage) or layer (shadow); default: a technique's primary channel, or the "
        "candidate file's only image (a grey one is visibility, RGB is color)",
    )
    p.add_argument(
        "--depth-buffer",
        type=A.depth_buffer,
        default=None,
        metavar="NEAR,FAR,BITS",
        help="a depth candidate's hyperbolic depth buffer (e.g. 0.01,1000,24): adds "
        "depth_beyond_precision_fraction, the pixels whose error exceeds its rounding",
    )
    p.add_argument(
        "--kind",
        choices=["visibility", "color", "coverage", "depth"],
        default=None,
        help="what a --channel layer or channel holds (default: from its name and contents)",
    )
    add_visibility_arg(p)
    add_transfer_args(p)
    p.add_argument(
        "--coverage-truth",
        choices=["any", "front"],
        default="any",
        help="what a coverage candidate is scored against: any (the fraction of samples any "
        "geometry covers) or front (the fraction covered by the surface seen at the pixel: "
        "an engine's MSAA coverage mask of the front-most primitive)",
    )
    p.add_argument("--spp", type=A.spp, default=64, help="reference spp (default 64)")
    A.add_exact_budget_arg(p)
    p.add_argument("--seed", type=A.nonneg_int, default=0, help="reference seed (default 0)")
    p.add_argument("--flip-mode", choices=["LDR", "HDR", "ldr", "hdr"], default="LDR")
    p.add_argument(
        "--ppd", type=A.positive_float, default=None, help="FLIP pixels per degree (default 67.02)"
    )
    p.add_argument(
        "--gate-frames",
        type=A.positive_int,
        default=None,
        metavar="N",
        help="with --frames: average the per-frame metrics over the last N frames (warm-up "
        "neither passes nor fails a gate); convergence is judged against their level",
    )
    p.add_argument(
        "--candidate-motion",
        default=None,
        metavar="LAYER",
        help="the candidate EXR's motion-vector layer (LAYER.X/Y, .R/G or .U/V): adds "
        "motion_epe_* against the reference motion",
    )
    p.add_argument(
        "--motion-convention",
        choices=["pixels", "unreal", "unity", "uv"],
        default="pixels",
        help="convention of --candidate-motion (docs/conventions.md; default pixels: previous "
        "minus current, y down)",
    )
    p.add_argument(
        "--candidate-disocclusion",
        default=None,
        metavar="CHANNEL",
        help="the candidate EXR's disocclusion mask channel (disocclusion recall/precision)",
    )
    add_gate_args(
        p,
        baseline_help="a previous run's metrics.json (or its folder): exit 1 when a metric is "
        "worse by more than both runs' noise floors",
    )
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/score"), help="output folder")

    score_folder.add_parser(sub)
    baseline_cmd.add_parser(sub)

    p = sub.add_parser("report", help="combine score folders (or a sweep) into one HTML report")
    p.add_argument("folders", nargs="*", type=Path, metavar="DIR")
    p.add_argument("--out", type=A.path, required=True, help="the report.html to write")
    p.add_argument("--title", default=DEFAULT_TITLE)
    p.add_argument("--sweep", type=Path, default=None, metavar="DB", help="a sweep store")
    p.add_argument("--cost", action="append", default=[], help="cost key of the fronts")
    p.add_argument("--metric", action="append", default=[], help="metric of the fronts")


def _check_frame_pattern(pattern: str | None) -> None:
    """A ``--candidate`` pattern with a ``{frame}`` field is a ``str.format`` pattern: it may
    hold ``{frame}`` fields only, with an integer format (a name without one is literal)."""
    from ..scoring.inputs.frames import FRAME_PATTERN
    from ..scoring.inputs.out_names import check_frame_pattern

    if pattern is None or not FRAME_PATTERN.search(pattern):
        return
    check_frame_pattern(pattern, "--candidate", error=A.CliError)


def _camera_path(args, loaded) -> str | None:
    """The camera path of ``--frames``: ``--camera-path``, or the one an export was made for
    (a light path alone keeps the camera still); ``--frames`` without any path is exit 2,
    never a silent default. A scene whose objects move, or a camera file, has its own
    default path."""
    path = args.camera_path or loaded.camera_path
    if path is None and args.light_path is None and loaded.default_camera_path != "dolly":
        path = loaded.default_camera_path  # a camera file's or moving objects' own path
    if args.frames is None or path is not None or args.light_path is not None:
        return path
    from ...scenes.inputs import resolve_input

    rec = resolve_input(args.scene).export or {}
    made = ""
    if rec.get("camera_path"):
        made = (
            f"; {args.scene} was exported at frame {rec.get('frame')} of "
            f"{rec['camera_path']}: export its frame 0 to score the path"
        )
    raise A.CliError(
        f"--frames {args.frames} needs the camera path the frames were rendered along: "
        f"--camera-path ({', '.join(_paths())}) or --light-path{made}"
    )


def _paths() -> tuple[str, ...]:
    from ...scenes import CAMERA_PATHS

    return tuple(CAMERA_PATHS)


def cmd_score(args) -> int:
    from ... import metrics as M
    from ... import raster_models
    from ..scoring.ci.baseline import check_platform, resolve_baseline
    from ..scoring.ci.regression import load_baseline
    from ..scoring.options import ScoreOptions
    from ..scoring.output import stale_files
    from ..scoring.request import ScoreRequest
    from ..scoring.result import ScoreError
    from ..scoring.to_folder import score_to_folder
    from .score_inputs import candidate_inputs

    gates = parse_all_gates(args)
    platform = check_platform(args.platform)
    baseline = baseline_path = None
    if args.baseline is not None:
        baseline_path = resolve_baseline(args.baseline, platform=platform)
        baseline = load_baseline(baseline_path)
    _check_frame_pattern(args.candidate)
    A.check_out(args.out)
    check_junit(args.junit, out=args.out, summary=args.summary_md)
    check_outputs_not_inputs(
        args,
        reads={
            "the candidate": args.candidate,
            "--baseline": baseline_path,
            "the scene": args.scene,
            "--camera-file": getattr(args, "camera_file", None),
        },
        folders={"the candidate folder": args.candidate, "the scene folder": args.scene},
    )
    loaded = A.load_scene(args)
    layout = candidate_inputs(args, loaded)
    cache = A.reference_cache(args)
    params = None
    if args.technique:
        params = raster_models.parse_params(args.technique, args.params)
    elif args.params:
        raise ScoreError("--set applies to --technique, not to --candidate")
    options = ScoreOptions(
        spp=args.spp,
        seed=args.seed,
        frames=args.frames,
        camera_path=_camera_path(args, loaded),
        quiet=args.quiet,
        flip_mode=args.flip_mode,
        ppd=args.ppd or M.DEFAULT_PPD,
        platform=platform,
        visibility=args.visibility,
        gate_frames=args.gate_frames,
        transfer=args.transfer,
        expect=args.expect,
        coverage_truth=args.coverage_truth,
        depth_buffer=args.depth_buffer,
        family=args.family,
        exact_budget=A.exact_budget(args),
        motion=None
        if args.candidate_motion is None
        else {
            "layer": args.candidate_motion,
            "convention": args.motion_convention,
            "disocclusion": args.candidate_disocclusion,
        },
    )
    if args.technique:
        request = ScoreRequest.for_model(
            loaded, args.technique, params, channel=args.channel, options=options, cache=cache
        )
    else:
        request = ScoreRequest.for_files(
            loaded,
            args.candidate,
            channel=args.channel,
            layout=layout,
            options=options,
            cache=cache,
        )
    # an earlier score's own files in --out (its metrics.json lists them) are superseded;
    # anything else there (a note, the engine's render) is kept
    earlier = tuple(p.name for p in stale_files(args.out, []))
    with staged_folder(args.out, last=("metrics.json",), replaces=earlier) as out:
        verdict, record = score_to_folder(
            request,
            out=out,
            gates=gates,
            baseline=baseline,
            baseline_source=str(args.baseline),
            baseline_options=baseline_options(args).for_gates(gates),
        )
    print(f"score: {args.out / 'metrics.json'} and {args.out / 'report.html'}")
    print_verdict(verdict, baseline=args.baseline)
    write_outputs(args, [verdict], records=[record], report=args.out / "report.html")
    return verdict.exit_code


def cmd_report(args) -> int:
    from ..scoring.combine import combine_reports

    if not args.title.strip():
        raise A.CliError("--title must not be empty")
    if (args.sweep is None) == (not args.folders):
        raise A.CliError("report: give score folders or --sweep DB (one of them)")
    out = args.out
    if out.suffix.lower() == ".json":
        raise A.CliError(f"--out must name the HTML file (its JSON goes beside it), got {out}")
    if out.is_dir():
        raise A.CliError(f"--out {out} is a folder; give the report file to write")
    A.check_dir(out.parent, label=f"--out {out}: folder")
    writes = {"--out": out, "the report's JSON twin": out.with_suffix(".json")}
    if args.sweep is not None:
        A.check_distinct(writes=writes, reads={"the sweep store": args.sweep})
    else:
        A.check_distinct(
            writes=writes,
            reads={
                f"the record of score folder {f}:": Path(f) / "report.json" for f in args.folders
            },
        )
    if args.sweep is not None:
        from ..sweeps.report import sweep_report

        title = None if args.title == DEFAULT_TITLE else args.title
        sweep_report(args.sweep, out, title=title, costs=args.cost, metrics=args.metric)
        print(f"sweep report: {out}")
        return 0
    try:
        n = combine_reports(args.folders, out, title=args.title)
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        # Score folders are user data: a wrong schema, missing keys or unsafe links.
        if isinstance(exc, A.input_errors()):
            raise
        detail = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise A.CliError(f"report: bad score folder data: {detail}") from None
    print(f"report of {n} case(s): {args.out}")
    return 0


COMMANDS = {
    "score": cmd_score,
    "score-folder": score_folder.cmd_score_folder,
    "baseline": baseline_cmd.cmd_baseline,
    "report": cmd_report,
}
