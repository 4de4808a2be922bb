"""Names and paths derived from user text (manifest keys, case names, file patterns): every
output folder stays one folder name under ``--out``, every candidate file stays inside ROOT,
every file pattern holds ``{frame}`` alone. Each check raises the caller's ``error`` class
with one line naming the text.
"""

from __future__ import annotations

import re
import string
from pathlib import Path

__all__ = [
    "MAX_FRAME_WIDTH",
    "RESERVED",
    "case_folder",
    "check_frame_pattern",
    "check_out_name",
    "relative_file",
]

#: Widest ``{frame:0Nd}`` of a file pattern.
MAX_FRAME_WIDTH = 12
#: Names a run writes at the top of ``--out`` (a scene key cannot be one of them).
RESERVED = ("metrics.json", "report.html", "report.json", "summary.md", "junit.xml")
_NOT_IN_NAME = re.compile(r"[/\\\x00-\x1f\x7f-\x9f]")
_FRAME_SPEC = re.compile(r"0?[1-9]?[0-9]?d?")


def check_out_name(name, where: str, *, error) -> str:
    """A scene or channel key that names a folder under ``--out``: one folder name (no
    separator, NUL or control character; not ``.``, ``..`` nor one of :data:`RESERVED`, in
    any case; at most 128 characters)."""
    bad = not isinstance(name, str) or name in ("", ".", "..") or len(name) > 128
    if bad or _NOT_IN_NAME.search(name):
        raise error(
            f"{where}: key {name!r} names a folder under --out: one folder name of at most "
            "128 characters, no '/', '\\', NUL or control characters, not '.' or '..'"
        )
    if name.lower() in RESERVED:
        raise error(f"{where}: key {name!r} is a file the run writes itself")
    return name


def check_frame_pattern(pattern: str, where: str, *, error) -> str:
    """A candidate file pattern: its only replacement field is ``{frame}`` (with at most a
    zero-padded integer width of :data:`MAX_FRAME_WIDTH`); ``{{``/``}}`` are literal braces."""
    try:
        fields = list(string.Formatter().parse(pattern))
    except ValueError as exc:
        raise error(f"{where}: pattern {pattern!r} is not valid ({exc})") from None
    for _, name, spec, conversion in fields:
        if name is None:
            continue
        if name != "frame" or conversion is not None or "{" in (spec or ""):
            name += f"!{conversion}" if conversion else ""
            raise error(
                f"{where}: pattern {pattern!r} is not valid: its only field may be {{frame}}"
                f", not {{{name}}} (write a literal brace as {{{{ or }}}})"
            )
        m = _FRAME_SPEC.fullmatch(spec or "")
        width = int(re.sub(r"\D", "", spec) or 0) if m else MAX_FRAME_WIDTH + 1
        if not m or width > MAX_FRAME_WIDTH:
            raise error(
                f"{where}: pattern {pattern!r} is not valid: use {{frame}} or {{frame:0Nd}} "
                f"(N <= {MAX_FRAME_WIDTH}), not {{frame:{spec}}}"
            )
    return pattern


def relative_file(text: str, where: str, *, error) -> str:
    """``file``: a path relative to ROOT that stays inside it (lexically)."""
    bad = _NOT_IN_NAME.search(text.replace("/", "")) or text.startswith(("/", "~"))
    if bad or ".." in Path(text).parts:
        raise error(
            f"{where}: {text!r} must be a relative path inside ROOT (no leading '/' or '~', "
            "no '..', no backslash or control character)"
        )
    return check_frame_pattern(text, where, error=error)


def case_folder(out, name: str, *, error) -> Path:
    """The folder of a score-folder case ``name`` (``scene`` or ``scene/channel``) under
    ``out``: each part one folder name (:func:`check_out_name`), so no case writes outside
    ``out`` or over the run's own files."""
    parts = str(name).split("/")
    if len(parts) > 2:
        raise error(f"score-folder: case {name!r} has more than scene/channel")
    for part in parts:
        check_out_name(part, f"score-folder case {name!r}", error=error)
    return Path(out).joinpath(*parts)
