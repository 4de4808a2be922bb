"""The CI gate options shared by ``score`` and ``score-folder``, and how their verdict is shown.

``--fail-above METRIC=V`` / ``--fail-below METRIC=V`` (:func:`oracle.scoring.gates.parse_gates`),
``--baseline`` (a previous run's metrics record) and ``--junit FILE`` (JUnit XML, one test case
per scene x gate). Exit codes: 0 every gate passed, 1 a gate failed or a metric regressed, 2 a
gate or baseline that cannot be judged.
"""

from __future__ import annotations

import sys

from . import args as A

__all__ = ["add_gate_args", "check_junit", "print_verdict"]


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
        "--baseline", type=A.path, default=None, metavar="METRICS_JSON", help=baseline_help
    )
    p.add_argument(
        "--junit",
        type=A.path,
        default=None,
        metavar="FILE",
        help="write the gates and baseline comparisons as JUnit XML (one test case each)",
    )


def check_junit(path) -> None:
    """A ``--junit`` file can be written: not a folder, in an existing folder."""
    if path is None:
        return
    if path.is_dir():
        raise A.CliError(f"--junit {path} is a folder; give the XML file to write")
    A.check_dir(path.parent, label=f"--junit {path}: folder")


def print_verdict(verdict, *, baseline=None, prefix: str = "") -> None:
    """Print the gate lines (``PASS``/``FAIL``), the regressions, a one-line baseline summary
    (when ``baseline`` names one) and the notes, each line after ``prefix``."""
    for check in verdict.checks:
        if check.kind == "gate" or not check.passed:
            print(f"{prefix}{check.line}")
    if baseline is not None:
        n = sum(c.kind == "baseline" for c in verdict.checks)
        bad = sum(c.kind == "baseline" and not c.passed for c in verdict.checks)
        print(f"{prefix}baseline {baseline}: {n} metrics compared, {bad} regressed")
    for note in verdict.notes:
        print(f"{prefix}{note}")
    if verdict.failed:
        print(f"raster-oracle: {prefix}failed: {', '.join(verdict.failed)}", file=sys.stderr)
