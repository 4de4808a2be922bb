"""``score-folder ROOT``: score a folder of engine images laid out by scene and frame, or
as a manifest (``--manifest ci.toml``) says.

Without a manifest every scene of ``ROOT`` (:func:`oracle.scoring.inputs.folder_layout.discover`) is
checked first (scene found, candidate layout unambiguous, size right). With one, each
scene's channels are its cases (:mod:`oracle.scoring.inputs.manifest`); a case whose file or layer
is missing is an error of its own (a JUnit ``<error>`` case) while the others are scored.
The library builds and scores the cases (:func:`oracle.scoring.inputs.folder_cases.run_folder`,
the same function ``raster_oracle.score_folder`` calls) into ``OUT/<case>/``,
``OUT/metrics.json`` and ``OUT/report.html``; this command parses the options and prints the
first screen: per case its gates, its regressions grouped in one row, its notes, then the
baseline's missing and new cases. The gates are judged on every case, a ``--baseline`` case
by case, and ``--junit`` holds one test case per case x check. Exit 1 when a case fails a
check, regresses or could not be scored (or, with ``--baseline-strict``, is missing from the
baseline or from this run).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ...scenes.base.files import staged_folder
from . import args as A
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
    p.add_argument("--kind", choices=["visibility", "color", "coverage", "depth"], default=None)
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
    add_transfer_args(p)
    p.add_argument("--spp", type=A.spp, default=None, help="reference spp (default 64)")
    A.add_exact_budget_arg(p)
    p.add_argument("--seed", type=A.nonneg_int, default=None, help="reference seed (default 0)")
    p.add_argument("--flip-mode", choices=["LDR", "HDR", "ldr", "hdr"], default=None)
    add_gate_args(
        p,
        baseline_help="a previous score-folder's metrics.json (or its OUT folder): exit 1 "
        "when a scene's metric is worse by more than both runs' noise floors",
    )
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/score-folder"), help="output folder")


def cmd_score_folder(args) -> int:
    from ..scoring.inputs.folder_cases import run_folder

    gates = parse_all_gates(args)
    bo = baseline_options(args)
    A.check_out(args.out)
    check_junit(args.junit, out=args.out, summary=args.summary_md)
    check_outputs_not_inputs(
        args,
        reads={"--manifest": args.manifest, "--baseline": args.baseline},
        folders={"ROOT": args.root, "--exports": args.exports, "--baseline": args.baseline},
    )
    options = {
        "spp": args.spp,
        "seed": args.seed,
        "flip_mode": args.flip_mode,
        "transfer": args.transfer,
        "expect": args.expect,
        "family": args.family,
        "channel": args.channel,
        "kind": args.kind,
        "camera_path": args.camera_path,
        "visibility": args.visibility,
        "exports": args.exports,
        "quiet": args.quiet,
        "platform": args.platform,
        "exact_budget": A.exact_budget(args),
    }
    # the whole run appears at once, its combined record last; an earlier run's case folders
    # go with it (a reused --out never shows an earlier record beside new results)
    earlier = _earlier_cases(args.out)
    with staged_folder(args.out, last=("metrics.json",), replaces=earlier) as out:
        cases, run = run_folder(
            args.root,
            out=out,
            manifest=args.manifest,
            options=options,
            gates=gates,
            baseline=args.baseline,
            baseline_options=bo,
            cache=A.reference_cache(args),
        )
    print(f"score-folder: {len(cases)} case(s): {args.out / 'metrics.json'}")
    # the first screen: one line a case (its gates, its regressions grouped, its notes)
    for verdict in run.verdicts:
        compared = args.baseline if verdict.scene in run.record["scenes"] else None
        print_verdict(verdict, baseline=compared, prefix=f"{verdict.scene}: ", grouped=True)
    _print_totals(run)
    records = [run.record["scenes"].get(c.name) for c in cases]
    write_outputs(args, run.verdicts, records=records, report=args.out / "report.html")
    return run.exit_code


def _earlier_cases(out: Path) -> tuple[str, ...]:
    """The case folders (top-level names) that an earlier score-folder run's combined record
    in ``out`` lists; nothing when ``out`` holds no such record."""
    from ...scenes.base.untrusted import UntrustedError, read_json
    from ..scoring.ci.checks import FOLDER_SCHEMA

    try:
        record = read_json(out / "metrics.json", what="earlier run's record")
    except (UntrustedError, OSError):
        return ()
    if not isinstance(record, dict) or record.get("schema") != FOLDER_SCHEMA:
        return ()
    scenes = record.get("scenes")
    names = {str(name).split("/")[0] for name in scenes} if isinstance(scenes, dict) else set()
    return tuple(sorted(n for n in names if n and not n.startswith(".") and "\\" not in n))


def _print_totals(run) -> None:
    """The run's verdict in one line (and the baseline's missing and new cases)."""
    failed = run.record["failed"]
    regressed = {v.scene for v in run.verdicts for c in v.failed_checks if c.kind == "baseline"}
    base = run.record.get("baseline")
    if base is not None:
        print(
            f"baseline {base['source']}: {len(regressed)} case(s) regressed; missing from this "
            f"run: {', '.join(base['missing']) or 'none'}; new: {', '.join(base['new']) or 'none'}"
            f"{' (--baseline-strict: they fail)' if base['strict'] else ''}"
        )
    if failed or run.record["errors"]:
        names = sorted(set(failed) | set(run.record["errors"]))
        print(f"raster-oracle: failed: {len(names)} case(s): {', '.join(names)}", file=sys.stderr)
