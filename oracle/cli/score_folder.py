"""``score-folder ROOT``: score a folder of engine images laid out by scene and frame.

Every scene of ``ROOT`` (:func:`oracle.scoring.folder.discover`) is checked first (scene
found, candidate layout unambiguous, size right), then scored into ``OUT/<scene>/`` as
``score`` would; ``OUT/metrics.json`` combines the scenes' records and ``OUT/report.html``
their cases. The gates (``--fail-above``, ``--fail-below``) are judged on every scene, a
``--baseline`` (a previous ``OUT/metrics.json``) scene by scene, and ``--junit`` holds one
test case per scene x gate. Exit 1 when a scene fails a gate or regresses.
"""

from __future__ import annotations

import json
from pathlib import Path

from . import args as A
from .gate_args import (
    add_gate_args,
    add_visibility_arg,
    check_junit,
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
        "--camera-path", default="dolly", help="camera path of frame folders (default dolly)"
    )
    add_visibility_arg(p)
    p.add_argument("--spp", type=A.spp, default=64, help="reference spp (default 64)")
    p.add_argument("--seed", type=A.nonneg_int, default=0, help="reference seed (default 0)")
    p.add_argument("--flip-mode", choices=["LDR", "HDR", "ldr", "hdr"], default="LDR")
    add_gate_args(
        p,
        baseline_help="a previous score-folder's metrics.json (or its OUT folder): exit 1 "
        "when a scene's metric is worse by more than both runs' noise floors",
    )
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/score-folder"), help="output folder")


def _scene_of(entry, exports: Path | None):
    from ... import scenes
    from ...scenes.inputs import load_input

    scene = entry.name
    if exports is not None and (exports / entry.name / "scene.xml").is_file():
        scene = str(exports / entry.name)
    elif entry.name not in scenes.BUILTIN_SCENES:
        where = f" nor an export in {exports}" if exports is not None else ""
        raise A.CliError(
            f"score-folder: {entry.name!r} is not a built-in scene{where}; name the files "
            f"after a scene ({', '.join(scenes.BUILTIN_SCENES)}) or pass --exports"
        )
    return load_input(scene, n_frames=entry.frames or 8)


def cmd_score_folder(args) -> int:
    from ... import metrics as M
    from ...scenes.files import atomic_write_json
    from ..scoring.baseline import check_platform, resolve_baseline
    from ..scoring.combine import combine_reports
    from ..scoring.folder import discover
    from ..scoring.gates import (
        check_baseline_scene,
        load_folder_baseline,
        parse_gates,
    )
    from ..scoring.options import ScoreOptions
    from ..scoring.request import score_to_folder
    from .score_inputs import resolve_layout

    gates = parse_gates(args.fail_above, args.fail_below)
    platform = check_platform(args.platform)
    baselines = None
    if args.baseline is not None:
        baselines = load_folder_baseline(resolve_baseline(args.baseline, platform=platform))
    A.check_out(args.out)
    check_junit(args.junit, out=args.out, summary=args.summary_md)
    entries = discover(args.root)
    names = {e.name for e in entries}
    if names & {"metrics.json", "report.html", "report.json"}:
        raise A.CliError("score-folder: a scene may not be named metrics or report")
    plan = []
    for entry in entries:  # everything checked before the first reference is rendered
        loaded = _scene_of(entry, args.exports)
        layout = resolve_layout(entry.pattern, channel=args.channel, kind=args.kind, loaded=loaded)
        if baselines is not None and entry.name in baselines:
            check_baseline_scene(
                baselines[entry.name],
                loaded,
                frames=entry.frames or 1,
                kinds=(layout.kind,),
                source=f"{args.baseline} scene {entry.name}",
                platform=platform,
            )
        plan.append((entry, loaded, layout))
    cache = A.reference_cache(args)
    combined = {"schema": "raster-oracle/score-folder/1", "root": str(args.root), "scenes": {}}
    failed, verdicts = {}, []
    for entry, loaded, layout in plan:
        out = args.out / entry.name
        baseline = (baselines or {}).get(entry.name)
        options = ScoreOptions(
            spp=args.spp,
            seed=args.seed,
            frames=entry.frames,
            camera_path=args.camera_path,
            quiet=args.quiet,
            flip_mode=args.flip_mode,
            ppd=M.DEFAULT_PPD,
            platform=platform,
            visibility=args.visibility,
        )
        verdict = score_to_folder(
            loaded,
            out=out,
            candidate=entry.pattern,
            channel=args.channel,
            options=options,
            cache=cache,
            gates=gates,
            baseline=baseline,
            baseline_source=f"{args.baseline} scene {entry.name}",
            layout=layout,
        )
        if baselines is not None and baseline is None:
            verdict.add(notes=[f"baseline: no scene {entry.name} in {args.baseline}"])
        verdicts.append(verdict)
        record = json.loads((out / "metrics.json").read_text())
        record["folder"] = entry.name
        combined["scenes"][entry.name] = record
        if verdict:
            failed[entry.name] = list(verdict)
    combined["failed"] = failed
    combined["platform"] = platform
    combined["exit_code"] = 1 if failed else 0
    atomic_write_json(args.out / "metrics.json", combined)
    folders = [args.out / e.name for e, _, _ in plan]
    combine_reports(folders, args.out / "report.html", title=f"{args.root.name}: engine images")
    print(f"score-folder: {len(plan)} scene(s): {args.out / 'metrics.json'}")
    for (entry, _, _), verdict in zip(plan, verdicts, strict=True):
        compared = args.baseline if entry.name in (baselines or {}) else None
        print_verdict(verdict, baseline=compared, prefix=f"{entry.name}: ")
    records = [combined["scenes"][e.name] for e, _, _ in plan]
    write_outputs(args, verdicts, records=records, report=args.out / "report.html")
    return 1 if failed else 0
