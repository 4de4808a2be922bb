"""Commands that run many cases: ``sweep``, ``tune`` and ``main`` (the main job)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from . import args as A

__all__ = ["COMMANDS", "add_parsers"]


def add_parsers(sub) -> None:
    """Add ``sweep``, ``tune`` and ``main`` to the subparsers ``sub``."""
    p = sub.add_parser("sweep", help="run a sweep spec (TOML) on Dask into a SQLite store")
    p.add_argument("spec", type=A.path, metavar="SPEC.toml")
    p.add_argument("--out", type=A.path, default=Path("out/sweep"), help="output folder")
    p.add_argument("--db", type=A.path, default=None, help="SQLite store (default OUT/sweep.db)")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument(
        "--worker-timeout",
        type=A.positive_float,
        default=None,
        help="seconds with no Dask worker before the sweep stops with 'no workers' "
        "(default 120; finished cases are kept)",
    )
    p.add_argument(
        "--workers",
        type=A.nonneg_int,
        default=None,
        help="local Dask workers (default: one per core; 0: run in this process)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run failed cases again")
    A.add_cache_args(p, no_cache=False)
    _add_tune_parser(sub)

    p = sub.add_parser("main", help="the main job: the default sweep, claims, extremes, report")
    p.add_argument("--out", type=A.path, default=Path("out"), help="output folder")
    p.add_argument("--spp", type=A.spp, default=None, help="reference spp (default: the spec's 64)")
    p.add_argument("--scenes", default=None, help="comma-separated scenes (default: all)")
    p.add_argument(
        "--workers",
        type=A.nonneg_int,
        default=None,
        help="Dask workers (default: one per core; 0: run in this process)",
    )
    p.add_argument("--width", type=A.positive_int, default=None, help="film width (default 640)")
    p.add_argument("--height", type=A.positive_int, default=None, help="film height (default 360)")
    A.add_cache_args(p, no_cache=False)


def _add_tune_parser(sub) -> None:
    p = sub.add_parser("tune", help="the cheapest configuration meeting an error target")
    p.add_argument("scene", metavar="SCENE")
    p.add_argument("--technique", required=True)
    p.add_argument("--target", required=True, metavar="METRIC<=X", help="e.g. flip_mean<=0.05")
    p.add_argument(
        "--minimize",
        default=None,
        metavar="COST",
        help="cost key to minimise (default: the family's memory cost)",
    )
    p.add_argument("--trials", type=A.positive_int, default=20)
    p.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY=SPEC",
        help="search space: KEY=lo:hi (int/float, log scale), KEY=a,b,c (choices); "
        "default: resolution=64:4096 where the technique has one",
    )
    A.add_set_arg(p, help="fixed technique parameter")
    p.add_argument("--width", type=A.positive_int, default=None)
    p.add_argument("--height", type=A.positive_int, default=None)
    p.add_argument("--light", type=A.nonneg_int, default=0)
    p.add_argument("--spp", type=A.spp, default=64)
    p.add_argument("--seed", type=A.nonneg_int, default=0)
    p.add_argument("--db", type=A.path, default=Path("out/tune.db"), help="SQLite store")
    p.add_argument("--study", default=None, help="Optuna study name (default: derived)")
    A.add_cache_args(p, no_cache=False)


def cmd_sweep(args) -> int:
    from ..sweeps.report import sweep_report
    from ..sweeps.run import check_scheduler, run_sweep
    from ..sweeps.spec import load_spec
    from ..sweeps.store import SweepStore

    expansion = load_spec(args.spec)
    A.check_out(args.out)
    db = args.db if args.db is not None else args.out / "sweep.db"
    A.check_db(db)
    page = args.out / "report.html"
    A.check_distinct(
        writes={"the report": page, "the report's JSON twin": page.with_suffix(".json")},
        reads={"the sweep store (--db)": db, "the spec": args.spec},
    )
    A.check_distinct(writes={"--db": db}, reads={"the spec": args.spec})
    cache = A.reference_cache(args)
    if args.scheduler is not None:
        check_scheduler(args.scheduler)  # before anything is written
    SweepStore(db).close()  # a file that is not a sweep store fails here, before any work
    summary = run_sweep(
        expansion,
        db,
        cache_root=cache.root,
        workers=args.workers,
        scheduler=args.scheduler,
        worker_timeout=args.worker_timeout,
        quiet=args.quiet,
        retry_failed=args.retry_failed,
    )
    for note in summary["not_applicable"]:
        print(f"not applicable: {note}", file=sys.stderr)
    report = sweep_report(db, args.out / "report.html", sweep=expansion.name)
    print(
        f"sweep {expansion.name}: {summary['cases']} cases, {summary['skipped_done']} already "
        f"in {db}, ran {summary['ran']} ({summary['done']} done, {summary['failed']} failed) "
        f"in {summary['wall_seconds']:.1f} s; report: {report}"
    )
    with SweepStore(db, readonly=True) as store:
        failed = [r for r in store.rows(sweep=expansion.name) if r["status"] == "failed"]
    if failed:
        print(
            f"raster-oracle: {len(failed)} case(s) failed, first: {failed[0]['error']}",
            file=sys.stderr,
        )
        return 1
    return 0


def cmd_tune(args) -> int:
    from ..sweeps.tune import parse_target, run_tune

    target = parse_target(args.target)
    A.check_db(args.db)
    result = run_tune(
        args.scene,
        technique=args.technique,
        target=target,
        minimize=args.minimize,
        trials=args.trials,
        vary=args.vary,
        fixed=args.params,
        width=args.width,
        height=args.height,
        light=args.light or 0,
        spp=args.spp,
        seed=args.seed,
        db=args.db,
        study_name=args.study,
        cache=A.reference_cache(args),
        quiet=args.quiet,
    )
    print(json.dumps(result, indent=2))
    return 0 if result["best"] is not None else 1


def _builtin(name: str):
    """The built-in scene ``name`` names (``meadow:n=1000`` too) or None; a bad parameter is
    a :class:`CliError`."""
    from ... import scenes

    try:
        return scenes.builtin_scene(name)
    except scenes.SceneParamError as exc:
        raise A.CliError(str(exc)) from None


def cmd_main(args) -> int:
    from ... import scenes
    from ..sweeps.mainjob import run_main

    names = None
    if args.scenes:
        names = tuple(A.names(args.scenes))
        unknown = [n for n in names if _builtin(n) is None]
        if unknown:
            raise A.CliError(
                f"unknown scene(s) {', '.join(unknown)}; choose from "
                f"{', '.join(scenes.BUILTIN_SCENES)}"
            )
    if (args.width is None) != (args.height is None):
        raise A.CliError("main: give both --width and --height, or neither")
    A.check_out(args.out)
    report, failed = run_main(
        names,
        args.out,
        spp=args.spp,
        cache=A.reference_cache(args),
        quiet=args.quiet,
        workers=args.workers,
        size=(args.width, args.height) if args.width else None,
    )
    print(f"report: {report.resolve()}")
    if failed:
        print(f"raster-oracle: main job: failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


COMMANDS = {"sweep": cmd_sweep, "tune": cmd_tune, "main": cmd_main}
