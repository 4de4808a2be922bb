"""The CI gate options shared by ``score`` and ``score-folder``, and how their verdict is shown.

``--fail-above METRIC=V`` / ``--fail-below METRIC=V`` (:func:`oracle.scoring.ci.gates.parse_gates`),
``--baseline`` (a previous run's metrics record) and ``--junit FILE`` (JUnit XML, one test case
per scene x gate). Exit codes: 0 every gate passed, 1 a gate failed or a metric regressed, 2 a
gate or baseline that cannot be judged.
"""

from __future__ import annotations

import sys
from pathlib import Path

from . import args as A

__all__ = [
    "add_gate_args",
    "add_transfer_args",
    "add_visibility_arg",
    "baseline_options",
    "check_junit",
    "check_output_file",
    "parse_all_gates",
    "print_verdict",
    "write_outputs",
]


def add_gate_args(p, *, baseline_help: str) -> None:
    """Add ``--fail-above``, ``--fail-below``, ``--baseline`` and ``--junit`` to ``p``."""
    p.add_argument(
        "--fail-above",
        action="append",
        default=[],
        metavar="METRIC=VALUE",
        help="exit 1 when METRIC is above VALUE (lower-is-better metrics; repeatable)",
    )
    p.add_argument(
        "--fail-below",
        action="append",
        default=[],
        metavar="METRIC=VALUE",
        help="exit 1 when METRIC is below VALUE (higher-is-better metrics such as ssim, "
        "psnr_db; repeatable)",
    )
    p.add_argument(
        "--gate-profile",
        action="append",
        default=[],
        metavar="NAME",
        help="the gates of a tool engine teams use, at its published defaults (repeatable): "
        "unreal-low, unreal-medium, unreal-high (screenshot comparison: per-channel tolerance, "
        "10%% local and 2%% global error), unity (average JzAzBz delta E 0.005 above 0.001 a "
        "pixel), edge-aware (0.5%% of pixels beyond 3 standard errors + 0.25 px at edges)",
    )
    p.add_argument(
        "--baseline", type=A.path, default=None, metavar="METRICS_JSON", help=baseline_help
    )
    p.add_argument(
        "--baseline-metrics",
        action="append",
        default=[],
        metavar="M1,M2",
        help="the metrics --baseline compares (repeatable, comma-separated; `all`: every "
        "scored metric; default: the gated metrics, every metric when nothing is gated)",
    )
    p.add_argument(
        "--baseline-tolerance",
        action="append",
        default=[],
        metavar="METRIC=T",
        help="a regression must also exceed T (the metric's error units) or T%% of the "
        "baseline's error (METRIC=5%%) beyond both noise floors (repeatable)",
    )
    p.add_argument(
        "--baseline-strict",
        action="store_true",
        help="a metric that cannot be compared with the baseline (a value or noise floor "
        "missing) fails (default: named, NOT COMPARED); score-folder: a case of the baseline "
        "missing from this run, or new in it, fails (default: named in a note)",
    )
    p.add_argument(
        "--junit",
        type=A.path,
        default=None,
        metavar="FILE",
        help="write the gates and baseline comparisons as JUnit XML (one test case each)",
    )
    p.add_argument(
        "--platform",
        default=None,
        metavar="NAME",
        help="the platform this run stands for (GPU, driver, OS: e.g. linux-llvmpipe), "
        "recorded; --baseline BASELINE_DIR then reads BASELINE_DIR/NAME (see `baseline "
        "accept`), and a baseline of another platform is refused",
    )
    p.add_argument(
        "--summary-md",
        type=A.path,
        default=None,
        metavar="FILE",
        help="write a Markdown summary (the verdict, failed checks first) for a pull-request "
        "comment",
    )


def parse_all_gates(args) -> list:
    """``--fail-above``, ``--fail-below`` and ``--gate-profile`` as gates (a later limit of
    the same metric and direction replaces an earlier one)."""
    from ..scoring.ci.checks import GateError
    from ..scoring.ci.gates import parse_gates
    from ..scoring.ci.profiles import profile_gates

    gates = profile_gates(args.gate_profile, error=GateError)
    gates += parse_gates(args.fail_above, args.fail_below)
    return list({(g.metric, g.op): g for g in gates}.values())


def baseline_options(args):
    """:class:`BaselineOptions` of ``--baseline-metrics``, ``--baseline-tolerance`` and
    ``--baseline-strict`` (metrics None: the gated ones, decided per case)."""
    from ..scoring.ci.regression import BaselineOptions, parse_baseline_metrics, parse_tolerance

    tolerances = dict(parse_tolerance(t) for t in args.baseline_tolerance)
    metrics = parse_baseline_metrics(args.baseline_metrics)
    return BaselineOptions(metrics, tolerances, bool(getattr(args, "baseline_strict", False)))


def add_transfer_args(p) -> None:
    """``--transfer`` (how a PNG's colour is decoded), ``--expect`` (the technique the
    engine claims to implement, scored for conformance) and ``--family`` (the technique
    family its frames come from: its record decides the passes)."""
    p.add_argument(
        "--transfer",
        choices=["srgb", "gamma2.2", "linear"],
        default=None,
        help="how an 8/16-bit PNG candidate's colour is made linear (default srgb; "
        "gamma2.2: a pure 2.2 power, as pyrender and many GL samples write; linear: as is); "
        "recorded in metrics.json",
    )
    p.add_argument(
        "--expect",
        default=None,
        metavar="TECHNIQUE:KEY=V,...",
        help="what the engine claims to implement (a technique and its --set keys, e.g. "
        "shadow-map:resolution=2048,filter=pcf,pcf_size=3): its model runs too, and the "
        "candidate is scored against it (conformance_* metrics, gateable)",
    )
    p.add_argument(
        "--family",
        default=None,
        metavar="FAMILY",
        help="the technique family the candidate files' frames come from (rtshadows: a "
        "denoised ray-traced shadow): its record decides the passes (a temporal family's "
        "sequence gets the temporal metrics, gateable on its channels)",
    )


def add_visibility_arg(p) -> None:
    """``--visibility 1-is-lit|1-is-shadowed``: what a candidate mask's 1 means."""
    p.add_argument(
        "--visibility",
        choices=["1-is-lit", "1-is-shadowed"],
        default="1-is-lit",
        help="what a shadow mask's 1 means (default 1-is-lit, the oracle's convention; "
        "1-is-shadowed: a shadow-factor buffer, read as 1 - value)",
    )


def check_output_file(path, *, option: str, out=None) -> None:
    """An output file (``--junit``, ``--summary-md``) can be written: not a folder, its folder
    writable or creatable (created when the file is written), and not one of the files of
    the ``--out`` folder ``out``. Checked before any work: a bad path is exit 2 and nothing
    is written."""
    if path is None:
        return
    if path.is_dir():
        raise A.CliError(f"{option} {path} is a folder; give the file to write")
    if path.exists() and not path.is_file():
        raise A.CliError(f"{option} {path} exists and is not a file")
    A.check_dir(path.parent if str(path.parent) else Path("."), label=f"{option} {path}: folder")
    if out is not None:
        from ..scoring.output import SCORE_FILES

        A.check_distinct(
            writes={option: path},
            reads={f"--out's own file {f}:": Path(out) / f for f in SCORE_FILES},
        )


def check_junit(path, *, out=None, summary=None) -> None:
    """``--junit`` and ``--summary-md`` can be written (:func:`check_output_file`) and are
    two files."""
    check_output_file(path, option="--junit", out=out)
    check_output_file(summary, option="--summary-md", out=out)
    if path is not None and summary is not None:
        A.check_distinct(writes={"--summary-md": summary}, reads={"--junit": path})


def check_outputs_not_inputs(args, *, reads: dict, folders: dict | None = None) -> None:
    """``--junit`` and ``--summary-md`` name none of the command's inputs (``reads``: label ->
    file; ``folders``: label -> a folder every file of which is an input), links followed:
    exit 2 before any work (issue 48)."""
    writes = {"--junit": args.junit, "--summary-md": getattr(args, "summary_md", None)}
    A.check_not_inputs(writes=writes, reads=reads, folders=folders)


def write_outputs(args, verdicts, *, records=None, report=None) -> None:
    """Write ``--junit`` and ``--summary-md`` of ``verdicts`` (their folders created)."""
    from ..scoring.ci.junit import write_junit
    from ..scoring.ci.summary import write_summary_md

    if args.junit is not None:
        args.junit.parent.mkdir(parents=True, exist_ok=True)
        write_junit(args.junit, verdicts)
        print(f"junit: {args.junit}")
    if getattr(args, "summary_md", None) is not None:
        args.summary_md.parent.mkdir(parents=True, exist_ok=True)
        write_summary_md(args.summary_md, verdicts, records=records, report=report)
        print(f"summary: {args.summary_md}")


def print_verdict(verdict, *, baseline=None, prefix: str = "", grouped: bool = False) -> None:
    """Print the gate lines (``PASS``/``FAIL``), the regressions, a one-line baseline summary
    (when ``baseline`` names one) and the notes, each line after ``prefix``. ``grouped``
    (a folder run's first screen): the regressions and the summary as one line, their count
    and first metrics."""
    compared = [c for c in verdict.checks if c.kind == "baseline" and c.metric != "case"]
    regressions = [c for c in compared if not c.passed]
    for check in verdict.checks:
        if check.kind == "gate" or (not check.passed and not (grouped and check in compared)):
            _say(f"{prefix}{check.line}")
    if baseline is not None and grouped and regressions:
        shown = ", ".join(c.metric for c in regressions[:5])
        more = f" and {len(regressions) - 5} more" if len(regressions) > 5 else ""
        _say(
            f"{prefix}REGRESSION {shown}{more} ({len(regressions)} of {len(compared)} "
            f"compared metrics, baseline {baseline})"
        )
    elif baseline is not None:
        _say(
            f"{prefix}baseline {baseline}: {len(compared)} metrics compared, "
            f"{len(regressions)} regressed"
        )
    for note in verdict.notes:
        _say(f"{prefix}{note}")
    for _name, message in verdict.errors:
        _say(f"raster-oracle: {prefix}error: {message}", file=sys.stderr)
    failed = list(verdict.failed)
    if grouped and regressions:
        failed = [c.name for c in verdict.failed_checks if c not in regressions]
        failed.append(f"{len(regressions)} regression(s)")
    if failed:
        _say(f"raster-oracle: {prefix}failed: {', '.join(failed)}", file=sys.stderr)


def _say(text: str, **kwargs) -> None:
    """``print`` of a line holding user text (scene, case and check names, messages):
    control characters written out (:func:`scenes.base.untrusted.terminal`)."""
    from ...scenes.base.untrusted import terminal

    print(terminal(text), **kwargs)
