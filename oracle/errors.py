"""Errors of the oracle: one base class for bad input and one way to print an exception.

Library code raises; only the command line turns an exception into a message and an exit
code (``InputError`` and the other packages' input errors: one line on stderr, exit 2).
"""

from __future__ import annotations

__all__ = ["InputError", "InputWarning", "one_line"]


class InputError(ValueError):
    """Bad input from the user: an option, a file, a spec, a request the library refuses.

    Every input error of the oracle derives from it (``ScoreError``, ``SpecError``, ...).
    """


class InputWarning(UserWarning):
    """Input the library accepted after a stated correction (values just outside their
    range, clamped): the command line prints each once as ``raster-oracle: warning: ...``."""


def one_line(exc: BaseException, *, with_type: bool = False) -> str:
    """The message of ``exc`` on one line: control characters (newlines in file names, terminal
    escapes, DEL, C1) are escaped as Python writes them (``\\n``, ``\\x1b``), tabs kept.

    Parameters
    ----------
    with_type : prefix the exception's class name (``"ValueError: ..."``), for records of
        failures whose type is not otherwise known (a sweep case, a report section).
    """
    from ..scenes.base.untrusted import terminal

    text = f"{type(exc).__name__}: {exc}" if with_type else str(exc)
    return terminal(text)  # C0, DEL and C1 controls written out (an escape cannot recolour)
