"""Numbers written as text: one strict rule for every scene name, spec, manifest and option.

Python's ``int()`` and ``float()`` take more than a user means: ``1_0`` (digit grouping),
surrounding spaces, ``nan``, ``infinity``, and text of any length (a 5,000-digit integer is
parsed, or refused with a message about Python's own digit limit). Every numeric value the
tool reads as text goes through :func:`parse_int` or :func:`parse_float` instead: plain
decimal digits (a sign and a decimal exponent for numbers), at most :data:`MAX_DIGITS`
characters, bounds checked, one line naming the value when refused. Pure: the standard
library only.
"""

from __future__ import annotations

import math
import re

__all__ = ["MAX_DIGITS", "MAX_FRAMES", "NumberError", "parse_float", "parse_int"]

#: Longest numeric text accepted, sign and exponent included.
MAX_DIGITS = 24

#: Most frames a sequence may have, wherever its length is given (a manifest, ``--frames``).
MAX_FRAMES = 10_000

_INT = re.compile(r"[0-9]+")
_SIGNED_INT = re.compile(r"[+-]?[0-9]+")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


class NumberError(ValueError):
    """Numeric text refused (one line naming the value)."""


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:40] + "...")


def _span(lo, hi) -> str:
    if lo is None and hi is None:
        return ""
    return f" in [{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"


def _bounded(value, what: str, lo, hi, error):
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise (error or NumberError)(f"{what} must be{_span(lo, hi)}, got {value}")
    return value


def parse_int(text: str, *, what: str, lo=None, hi=None, signed: bool = False, error=None) -> int:
    """``text`` as an integer: decimal digits only (a leading ``-``/``+`` when ``signed``), at
    most :data:`MAX_DIGITS` characters, within ``[lo, hi]``; ``error`` is the exception class
    raised (default :class:`NumberError`)."""
    form = _SIGNED_INT if signed else _INT
    if not isinstance(text, str) or len(text) > MAX_DIGITS or not form.fullmatch(text):
        kind = "an integer" if signed else "a whole number (decimal digits only)"
        shown = _shown(text) if isinstance(text, str) else type(text).__name__
        raise (error or NumberError)(
            f"{what} must be {kind}{_span(lo, hi)} of at most {MAX_DIGITS} digits, got {shown}"
        )
    return _bounded(int(text), what, lo, hi, error)


def parse_float(text: str, *, what: str, lo=None, hi=None, error=None) -> float:
    """``text`` as a finite number: an optional sign, decimal digits with an optional point
    and exponent, at most :data:`MAX_DIGITS` characters, within ``[lo, hi]``."""
    if not isinstance(text, str) or len(text) > MAX_DIGITS or not _FLOAT.fullmatch(text):
        shown = _shown(text) if isinstance(text, str) else type(text).__name__
        raise (error or NumberError)(
            f"{what} must be a decimal number of at most {MAX_DIGITS} characters, got {shown}"
        )
    value = float(text)
    if not math.isfinite(value):
        raise (error or NumberError)(f"{what} must be finite, got {_shown(text)}")
    return _bounded(value, what, lo, hi, error)
