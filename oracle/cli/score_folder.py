"""``score-folder ROOT``: score a folder of engine images laid out by scene and frame, or
as a manifest (``--manifest ci.toml``) says.

Without a manifest every scene of ``ROOT`` (:func:`oracle.scoring.folder.discover`) is
checked first (scene found, candidate layout unambiguous, size right). With one, each
scene's channels are its cases (:mod:`oracle.scoring.manifest`); a case whose file or layer
is missing is an error of its own (a JUnit ``<error>`` case) while the others are scored.
The library's :func:`oracle.scoring.folder.score_folder` scores the cases into
``OUT/<case>/``, ``OUT/metrics.json`` and ``OUT/report.html``. The gates are judged on every
case, a ``--baseline`` case by case, and ``--junit`` holds one test case per case x check.
Exit 1 when a case fails a check, regresses or could not be scored.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from . import args as A
from .gate_args import (
    add_gate_args,
    add_visibility_arg,
    check_junit,
    parse_all_gates,
    print_verdict,
    write_outputs,
)

__all__ = ["add_parser", "cmd_score_folder"]


def add_parser(sub) -> None:
    """Add ``score-folder`` to the subparsers ``sub``."""
    p = sub.add_parser(
        "score-folder",
        help="score ROOT/<scene>.exr or ROOT/<scene>/frame_NNN.exr for every scene in ROOT",
    )
    p.add_argument("root", type=A.path, metavar="ROOT", help="folder of engine images")
    p.add_argument(
        "--exports",
        type=A.path,
        default=None,
        help="folder of `export` folders: <scene> is EXPORTS/<scene> when it exists "
        "(default: built-in scenes)",
    )
    p.add_argument("--channel", default=None, help="as for `score` (default: inferred)")
    p.add_argument("--kind", choices=["visibility", "color", "coverage"], default=None)
    p.add_argument(
        "--manifest",
        type=A.path,
        default=None,
        metavar="TOML",
        help="a CI manifest: each scene's file, channels (several EXR layers), gates, frames "
        "and camera path (docs/cli.md)",
    )
    p.add_argument(
        "--camera-path",
        default=None,
        help="camera path the frame folders were rendered along (required with frame "
        "folders, unless their export records one)",
    )
    add_visibility_arg(p)
    p.add_argument("--spp", type=A.spp, default=None, help="reference spp (default 64)")
    p.add_argument("--seed", type=A.nonneg_int, default=None, help="reference seed (default 0)")
    p.add_argument("--flip-mode", choices=["LDR", "HDR", "ldr", "hdr"], default=None)
    add_gate_args(
        p,
        baseline_help="a previous score-folder's metrics.json (or its OUT folder): exit 1 "
        "when a scene's metric is worse by more than both runs' noise floors",
    )
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/score-folder"), help="output folder")


def _scene_of(entry, exports: Path | None):
    from ...scenes.formats.inputs import load_input, named_input

    return load_input(named_input(entry.name, exports=exports), n_frames=entry.frames or 8)


def _options(args, manifest=None, **case):
    """The :class:`ScoreOptions` of a case: the command line's, else the manifest's."""
    from ... import metrics as M
    from ..scoring.options import ScoreOptions

    def pick(key, default):
        given = getattr(args, key)
        if given is not None:
            return given
        from_manifest = getattr(manifest, key, None) if manifest is not None else None
        return from_manifest if from_manifest is not None else default

    return ScoreOptions(
        spp=pick("spp", 64),
        seed=pick("seed", 0),
        flip_mode=pick("flip_mode", "LDR"),
        ppd=M.DEFAULT_PPD,
        quiet=args.quiet,
        platform=args.platform,
        **case,
    ).validate()


def _discovered_cases(args, gates) -> list:
    """The cases of ``ROOT``'s layout (every one checked: a problem is exit 2, except a
    file that lacks the ``--channel`` asked for: that scene's own error, the others scored)."""
    from ..scoring.candidates import MissingChannelError
    from ..scoring.folder import FolderCase, discover
    from .score_inputs import resolve_layout

    entries = discover(args.root)
    names = {e.name for e in entries}
    if names & {"metrics.json", "report.html", "report.json"}:
        raise A.CliError("score-folder: a scene may not be named metrics or report")
    cases = []
    for entry in entries:
        loaded = _scene_of(entry, args.exports)
        error = layout = None
        try:
            layout = resolve_layout(
                entry.pattern, channel=args.channel, kind=args.kind, loaded=loaded
            )
        except MissingChannelError as exc:
            if args.channel is None:
                raise
            print(f"{entry.name}: error: {exc}")
            error = str(exc)
        camera_path = args.camera_path or loaded.camera_path
        if entry.frames and camera_path is None:
            raise A.CliError(
                f"score-folder: {entry.name} holds {entry.frames} frames: give the camera path "
                "they were rendered along (--camera-path, or a manifest's camera_path)"
            )
        options = _options(
            args,
            frames=entry.frames,
            camera_path=camera_path,
            visibility=args.visibility,
        )
        cases.append(
            FolderCase(
                entry.name,
                entry.name,
                loaded,
                entry.pattern,
                args.channel,
                layout,
                options,
                tuple(gates),
                error,
            )
        )
    return cases


def _manifest_cases(args, gates) -> list:
    """The cases of ``--manifest``: a bad manifest, scene or option is exit 2; a missing
    file or layer is that case's own error."""
    from ...scenes.formats.inputs import load_input
    from ..scoring.candidates import CandidateError
    from ..scoring.folder import FolderCase
    from ..scoring.manifest import read_manifest
    from ..scoring.request import frame_file
    from .score_inputs import resolve_layout

    manifest = read_manifest(args.manifest)
    cases, scenes = [], {}
    for mc in manifest.cases:
        if mc.scene_key not in scenes:
            scenes[mc.scene_key] = load_input(mc.scene, n_frames=mc.frames or 8)
        loaded = scenes[mc.scene_key]
        pattern = str(args.root / mc.file)
        camera_path = mc.camera_path or loaded.camera_path
        if mc.frames and camera_path is None:
            raise A.CliError(
                f"--manifest {args.manifest}: scene {mc.scene_key} has frames = {mc.frames} "
                "but no camera_path (nor an export made with one)"
            )
        options = _options(
            args,
            manifest,
            frames=mc.frames,
            camera_path=camera_path,
            visibility=mc.visibility,
        )
        case = FolderCase(mc.name, mc.scene_key, loaded, pattern, mc.channel, None, options)
        case = replace(case, gates=tuple(gates) + mc.gates)
        try:
            if not Path(frame_file(pattern, 0)).is_file():
                raise CandidateError(f"candidate file not found: {frame_file(pattern, 0)}")
            layout = resolve_layout(pattern, channel=mc.channel, kind=mc.kind, loaded=loaded)
            case = replace(case, layout=layout)
        except CandidateError as exc:
            print(f"{mc.name}: error: {exc}")
            case = replace(case, error=str(exc))
        cases.append(case)
    return cases


def cmd_score_folder(args) -> int:
    from ..scoring.baseline import check_platform, resolve_baseline
    from ..scoring.folder import score_folder
    from ..scoring.gates import check_baseline_scene, load_folder_baseline

    gates = parse_all_gates(args)
    check_platform(args.platform)
    baselines = None
    if args.baseline is not None:
        path = resolve_baseline(args.baseline, platform=args.platform)
        baselines = load_folder_baseline(path)
    A.check_out(args.out)
    check_junit(args.junit, out=args.out, summary=args.summary_md)
    if args.manifest is not None:
        if args.channel is not None or args.kind is not None:
            raise A.CliError("--channel and --kind are given per scene in --manifest")
        if not args.root.is_dir():
            raise A.CliError(f"score-folder: {args.root} is not a folder")
        cases = _manifest_cases(args, gates)
    else:
        cases = _discovered_cases(args, gates)
    for case in cases:  # everything checked before the first reference is rendered
        if case.error is None and baselines is not None and case.name in baselines:
            check_baseline_scene(
                baselines[case.name],
                case.loaded,
                frames=case.options.frames or 1,
                kinds=(case.layout.kind,),
                source=f"{args.baseline} scene {case.name}",
                platform=args.platform,
            )
    run = score_folder(
        cases,
        out=args.out,
        cache=A.reference_cache(args),
        baselines=baselines,
        baseline_source=str(args.baseline),
        root=str(args.root),
        title=f"{args.root.name}: engine images",
    )
    print(f"score-folder: {len(cases)} case(s): {args.out / 'metrics.json'}")
    for case, verdict in zip(cases, run.verdicts, strict=True):
        compared = args.baseline if case.name in (baselines or {}) else None
        print_verdict(verdict, baseline=compared, prefix=f"{case.name}: ")
    records = [run.record["scenes"].get(c.name) for c in cases]
    write_outputs(args, run.verdicts, records=records, report=args.out / "report.html")
    return run.exit_code
