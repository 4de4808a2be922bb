"""The ``sweep`` and ``tune`` commands and ``report --sweep``: argument parsers and glue.

:mod:`oracle.cli.app` registers these parsers and dispatches to the ``cmd_*`` functions; the
work is in :mod:`oracle.sweeps.run`, :mod:`oracle.sweeps.tune` and :mod:`reports.sweep`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = [
    "add_parsers",
    "cmd_sweep",
    "cmd_tune",
    "known_errors",
    "report_sweep_args",
    "sweep_report",
]


def known_errors() -> tuple[type[BaseException], ...]:
    """Errors of the sweep commands that mean bad input (one line, exit 2)."""
    from ..sweeps.run import SweepError
    from ..sweeps.spec import SpecError
    from ..sweeps.store import StoreError
    from ..sweeps.tune import TuneError

    return (SpecError, StoreError, SweepError, TuneError)


def add_parsers(sub) -> None:
    """Add ``sweep`` and ``tune`` to the CLI's subparsers."""
    from .app import _nonneg_int, _path, _positive_int, _spp

    p = sub.add_parser("sweep", help="run a sweep spec (TOML) on Dask into a SQLite store")
    p.add_argument("spec", type=_path, metavar="SPEC.toml")
    p.add_argument("--out", type=_path, default=Path("out/sweep"), help="output folder")
    p.add_argument("--db", type=_path, default=None, help="SQLite store (default OUT/sweep.db)")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument(
        "--workers",
        type=_nonneg_int,
        default=None,
        help="local Dask workers (default: one per core; 0: run in this process)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run failed cases again")
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--quiet", action="store_true")

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
    p.add_argument("--trials", type=_positive_int, default=20)
    p.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY=SPEC",
        help="search space: KEY=lo:hi (int/float, log scale), KEY=a,b,c (choices); "
        "default: resolution=64:4096 where the technique has one",
    )
    p.add_argument(
        "--set",
        dest="params",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="fixed technique parameter (repeatable)",
    )
    p.add_argument("--width", type=_positive_int, default=None)
    p.add_argument("--height", type=_positive_int, default=None)
    p.add_argument("--light", type=_nonneg_int, default=0)
    p.add_argument("--spp", type=_spp, default=64)
    p.add_argument("--seed", type=_nonneg_int, default=0)
    p.add_argument("--db", type=_path, default=Path("out/tune.db"), help="SQLite store")
    p.add_argument("--study", default=None, help="Optuna study name (default: derived)")
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--quiet", action="store_true")


def _check_db(db: Path) -> None:
    from .app import CliError, _check_dir

    if db.exists() and not db.is_file():
        raise CliError(f"--db {db} exists and is not a file")
    _check_dir(db.parent if str(db.parent) else Path("."), label=f"--db {db}: folder")


def cmd_sweep(args) -> int:
    from ..sweeps.run import run_sweep
    from ..sweeps.spec import load_spec
    from ..sweeps.store import SweepStore
    from .app import _cache, _check_out

    expansion = load_spec(args.spec)
    _check_out(args.out)
    db = args.db if args.db is not None else args.out / "sweep.db"
    _check_db(db)
    cache = _cache(args)
    if args.scheduler is not None:
        from ..sweeps.run import check_scheduler

        check_scheduler(args.scheduler)  # before anything is written
    SweepStore(db).close()  # a file that is not a sweep store fails here, before any work
    summary = run_sweep(
        expansion,
        db,
        cache_root=cache.root,
        workers=args.workers,
        scheduler=args.scheduler,
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


def sweep_report(
    db: Path,
    out: Path,
    *,
    sweep: str | None = None,
    title: str | None = None,
    costs=None,
    metrics=None,
    extra_sections=None,
) -> Path:
    """Write the sweep report of the store ``db`` (rows of ``sweep``, or all) to ``out``."""
    from reports.sweep import write_sweep_report

    from ..sweeps.store import SweepStore

    with SweepStore(db, readonly=True) as store:
        rows = store.rows(sweep=sweep)
        images = store.images(r["key"] for r in rows if r["status"] == "done")
    _check_keys(rows, costs, metrics)
    write_sweep_report(
        rows,
        out,
        title=title or f"raster-oracle sweep {sweep or Path(db).name}",
        provenance={"database": str(Path(db).resolve()), "sweep": sweep or "all"},
        costs=costs,
        metrics=metrics,
        extra_sections=extra_sections,
        images=images,
    )
    return out


def _check_keys(rows, costs, metrics) -> None:
    """Requested ``--cost`` / ``--metric`` keys must be in some case of the store."""
    from reports.sweep import with_memory

    from ..sweeps.run import SweepError

    done = [r for r in rows if r["status"] == "done"]
    have = {
        "--cost": sorted({k for r in done for k in with_memory(r.get("cost"))}),
        "--metric": sorted({k for r in done for k in (r.get("metrics") or {})} - {"noise_floor"}),
    }
    for option, wanted in (("--cost", costs or []), ("--metric", metrics or [])):
        for key in wanted:
            if key not in have[option]:
                raise SweepError(
                    f"report {option} {key}: in no finished case; choose from "
                    f"{', '.join(have[option]) or '(none)'}"
                )


def cmd_tune(args) -> int:
    from ..sweeps.tune import parse_target, run_tune
    from .app import _cache

    target = parse_target(args.target)
    _check_db(args.db)
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
        light=args.light,
        spp=args.spp,
        seed=args.seed,
        db=args.db,
        study_name=args.study,
        cache=_cache(args),
        quiet=args.quiet,
    )
    import json

    print(json.dumps(result, indent=2))
    return 0 if result["best"] is not None else 1


def report_sweep_args(p: argparse.ArgumentParser) -> None:
    """Options ``report --sweep DB [--cost KEY] [--metric KEY]``."""
    p.add_argument("--sweep", type=Path, default=None, metavar="DB", help="a sweep store")
    p.add_argument("--cost", action="append", default=[], help="cost key of the fronts")
    p.add_argument("--metric", action="append", default=[], help="metric of the fronts")
