"""``baseline accept RUN_DIR --into BASELINE_DIR --note TEXT``: approve a run as the baseline
of its platform (:func:`oracle.scoring.ci.baseline.accept_baseline`)."""

from __future__ import annotations

from . import args as A

__all__ = ["add_parser", "cmd_baseline"]


def add_parser(sub) -> None:
    """Add ``baseline accept`` to the subparsers ``sub``."""
    p = sub.add_parser("baseline", help="approve a scored run as the baseline of later runs")
    actions = p.add_subparsers(dest="action", required=True, parser_class=A.Parser)
    acc = actions.add_parser(
        "accept",
        help="copy RUN_DIR's metrics.json to BASELINE_DIR/<platform>/, keeping the previous "
        "baseline under previous/NNN/ and the note",
    )
    acc.add_argument("run", type=A.path, metavar="RUN_DIR", help="a score or score-folder --out")
    acc.add_argument("--into", type=A.path, required=True, metavar="BASELINE_DIR")
    acc.add_argument("--note", required=True, help="why this run is approved (kept with it)")


def cmd_baseline(args) -> int:
    from ..scoring.ci.baseline import accept_baseline

    if not args.run.is_dir():
        raise A.CliError(f"baseline accept: {args.run} is not a folder (a run's --out)")
    A.check_dir(args.into, label="--into")
    folder = accept_baseline(args.run, into=args.into, note=args.note)
    print(f"baseline: {args.run / 'metrics.json'} accepted as {folder / 'metrics.json'}")
    return 0
