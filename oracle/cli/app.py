"""``raster-oracle``: the command line, a thin layer over the library.

Exit codes, for every command:

- **0**: success; for ``score``, every ``--fail-above``/``--fail-below`` gate passed and no
  metric regressed against ``--baseline``.
- **1**: a gate failed (``FAIL`` lines give value, threshold and noise floor), a metric is
  significantly worse than the ``--baseline`` run (``REGRESSION`` lines), or, for the
  sweep and study commands, a case or section failed. The outputs are written.
- **2**: usage or input error: one line on stderr naming what is wrong, nothing written to
  the output folder; also a backend that failed its self-check on this machine (the
  failed checks named) unless ``--trust-backend``. For ``score`` this includes a gate
  that cannot be judged (unknown metric, a direction that makes it meaningless such as
  ``--fail-above ssim=...``, a metric that does not apply to the candidate's kind or
  frame count, a null value) and a baseline that is not a metrics.json or is of another
  scene, size, light, kind or frame count.
- **130**: interrupted.

``raster-oracle --version`` prints ``raster-oracle X.Y.Z``. Each command group lives in its
own module (:mod:`.reference`, :mod:`.model`,
:mod:`.score`, :mod:`.sweeps`, :mod:`.studies`) with its parsers and its ``COMMANDS``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import threading
import warnings

from ..errors import InputWarning, one_line
from . import model, reference, score, studies, sweeps
from .args import CliError, Parser, input_errors
from .stops import Stops

__all__ = ["COMMANDS", "build_parser", "main"]

#: Command name -> function of the parsed arguments returning the exit code.
COMMANDS = {
    **reference.COMMANDS,
    **model.COMMANDS,
    **score.COMMANDS,
    **sweeps.COMMANDS,
    **studies.COMMANDS,
}


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command (its errors raise :class:`CliError`)."""
    parser = Parser(
        prog="raster-oracle",
        description="Ground truth for real-time shadows and anti-aliasing.",
    )
    parser.add_argument(
        "--backend",
        default=None,
        help="Mitsuba variant: auto, cuda_ad_rgb, llvm_ad_rgb or scalar_rgb "
        "(default: $RASTER_ORACLE_BACKEND or auto)",
    )
    parser.add_argument(
        "--trust-backend",
        action="store_true",
        help="use the backend even if its self-check (doctor --check) failed on this machine",
    )
    parser.add_argument("--version", action="version", version=f"raster-oracle {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for group in (reference, model, score, sweeps, studies):
        group.add_parsers(sub)
    return parser


def _version() -> str:
    from ... import __version__

    return __version__


#: The stop handlers of the command running now (one at a time: ``main`` is not re-entered).
_stops: list = [None]


def _deferred_stops():
    """The running command's :meth:`Stops.deferred` (a library called ``main``: nothing)."""
    stops = _stops[0]
    return stops.deferred() if stops is not None else contextlib.nullcontext()


def _exit_now(code: int) -> None:
    """Stopped by a signal, everything cleaned up: exit now rather than wait at interpreter
    shutdown for library threads (Dask's event loop and thread pools, joined at exit, after
    a sweep's cluster was closed in a hurry). Only when another thread is alive; a process
    of one thread exits the normal way. Only for the command itself (``main()`` reading
    ``sys.argv``): a caller that passes ``argv`` (a test, a script) gets the ``SystemExit``."""
    if threading.current_thread() is not threading.main_thread():
        return
    if not any(t is not threading.main_thread() for t in threading.enumerate()):
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _run(args) -> int:
    """Run the command of ``args`` with the backend selected (``doctor`` selects its own)."""
    with warnings.catch_warnings():
        # NumPy's RuntimeWarnings (0/0 on empty masks, ...) are not the user's business;
        # results are checked for NaN/inf where they are made.
        warnings.simplefilter("ignore", RuntimeWarning)
        # a correction the library made to the input (values clamped): one line, once
        warnings.simplefilter("always", InputWarning)
        shown: set[str] = set()

        def show(message, category, *_args, **_kwargs):
            text = one_line(message) if isinstance(message, Warning) else str(message)
            if issubclass(category, InputWarning) and text not in shown:
                shown.add(text)
                print(f"raster-oracle: warning: {text}", file=sys.stderr)
            elif not issubclass(category, InputWarning):
                sys.stderr.write(warnings.formatwarning(message, category, *_args[:2]))

        warnings.showwarning = show
        if args.command != "doctor":
            from ..certify import certified_select

            # a backend is used only after its self-check passed on this machine; a stop
            # while its libraries load ends the process at once (see .stops)
            with _deferred_stops():
                certified_select(args.backend, trust=args.trust_backend)
        return COMMANDS[args.command](args)


def main(argv: list[str] | None = None) -> int:
    """Run ``raster-oracle`` with the arguments ``argv`` (default: ``sys.argv[1:]``); returns
    the exit code."""
    from ..reference.cache import remove_scratch, scratch_mark, sweep_stale_scratch

    try:
        args = build_parser().parse_args(argv)
    except CliError as exc:
        print(f"raster-oracle: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    mark = scratch_mark()
    stops = Stops(cleanup=lambda: remove_scratch(mark))
    stops.install()
    _stops[0] = stops
    stopped = None
    try:
        sweep_stale_scratch()
        return _run(args)
    except SystemExit as exc:  # SIGTERM (_terminate): what is below has unwound
        stopped = exc.code if exc.code in (130, 143) else None
        raise
    except input_errors() as exc:
        print(f"raster-oracle: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head`: not an error
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("raster-oracle: interrupted", file=sys.stderr)
        stopped = 130
        return 130
    finally:
        remove_scratch(mark)
        _stops[0] = None
        stops.remove()
        if stopped is not None and argv is None:  # the command itself, not an in-process call
            _exit_now(stopped)
