"""Reading untrusted files and writing untrusted text: one set of checks for every layer.

Every file the tool reads (glTF/GLB and their buffers, manifests, camera files, run folders,
cached verdicts, stores) may come from another hand: a FIFO that never ends, a device that
never stops, a link out of its folder, a field of the wrong type, a NaN. The helpers here
turn each into one line naming the file and the field (:class:`UntrustedError`, a
``ValueError``; pass ``error=`` to raise a layer's own error class instead), and escape user
text for Markdown, HTML, XML and the terminal. Pure: the standard library only (no NumPy,
nothing of the project, never Mitsuba).

Limits (:data:`LIMITS`) are stated once here; each reader passes the one that applies.
"""

from __future__ import annotations

import html
import json
import math
import os
import re
import stat
from pathlib import Path

__all__ = [
    "LIMITS",
    "NAME_MAX",
    "PATH_MAX",
    "UntrustedError",
    "check_finite",
    "check_int",
    "check_number",
    "check_path",
    "contained",
    "escape_html",
    "escape_markdown",
    "json_depth",
    "path_problem",
    "read_bounded",
    "read_json",
    "read_text",
    "regular_file",
    "safe_component",
    "terminal",
    "xml_text",
]

#: Resource limits of untrusted input (bytes, counts). Beyond one: refused, naming it.
LIMITS = {
    "json_bytes": 64 << 20,  # a camera file, a metrics.json, a verdict, a record
    "manifest_bytes": 4 << 20,  # a CI manifest (TOML)
    "gltf_bytes": 512 << 20,  # a .gltf/.glb and each external buffer or image it names
    "scene_bytes": 512 << 20,  # a Mitsuba XML scene and each file it names (meshes, textures)
    "nesting": 64,  # JSON/TOML arrays and tables nested deeper: refused
}


class UntrustedError(ValueError):
    """Untrusted input refused (one line naming the file and the field)."""


def _fail(error, text: str):
    raise (error or UntrustedError)(terminal(text))


def regular_file(path, *, what: str = "file", error=None) -> os.stat_result:
    """``path``'s status when it is a regular file (links followed); one line otherwise (a
    folder, a FIFO, a device, a socket, missing)."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        _fail(error, f"{what} {path}: cannot read it (not found)")
    except OSError as exc:
        _fail(error, f"{what} {path}: cannot be read ({type(exc).__name__})")
    if not stat.S_ISREG(st.st_mode):
        kind = _kind(st.st_mode)
        _fail(error, f"{what} {path} is {kind}, not a regular file")
    return st


def _kind(mode: int) -> str:
    for test, name in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def read_bounded(path, *, limit: int, what: str = "file", error=None) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them: a folder, FIFO,
    device or socket, or a file longer than ``limit``, is one line (never a hang: the file
    is opened non-blocking and checked again once open)."""
    regular_file(path, what=what, error=error)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        _fail(error, f"{what} {path}: cannot be read ({type(exc).__name__})")
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped between the stat and the open
            _fail(error, f"{what} {path} is {_kind(st.st_mode)}, not a regular file")
        if st.st_size > limit:
            _fail(error, f"{what} {path} is {st.st_size} bytes, over the limit of {limit}")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:
                _fail(error, f"{what} {path} is over the limit of {limit} bytes")
        return b"".join(chunks)
    except OSError as exc:
        _fail(error, f"{what} {path}: cannot be read ({type(exc).__name__})")
    finally:
        os.close(fd)


def read_text(path, *, limit: int, what: str = "file", error=None) -> str:
    """:func:`read_bounded` decoded as UTF-8 (one line when it is not)."""
    data = read_bounded(path, limit=limit, what=what, error=error)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        _fail(error, f"{what} {path} is not UTF-8 text (byte {exc.start})")


def json_depth(value, limit: int) -> int:
    """Nesting depth of a parsed JSON/TOML value, counted up to ``limit + 1`` (iterative)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, depth)
            if deepest > limit:
                return deepest
            children = item.values() if isinstance(item, dict) else item
            stack.extend((c, depth + 1) for c in children if isinstance(c, dict | list))
    return deepest


def _no_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):  # 1e400 overflows to inf
        raise ValueError(f"{text[:40]} is beyond a float's range")
    return value


def loads_json(text: str, *, what: str, nesting: int = LIMITS["nesting"], error=None):
    """Parse JSON text strictly: no NaN/Infinity, no number beyond a float's range (``1e400``),
    nesting at most ``nesting`` deep."""
    try:
        value = json.loads(text, parse_constant=_no_constant, parse_float=_finite_float)
    except RecursionError:
        _fail(error, f"{what}: nested deeper than {nesting} levels")
    except ValueError as exc:
        _fail(error, f"{what} is not JSON ({exc})")
    if json_depth(value, nesting) > nesting:
        _fail(error, f"{what}: nested deeper than {nesting} levels")
    return value


def read_json(path, *, limit: int = LIMITS["json_bytes"], what: str = "file", error=None):
    """A bounded regular file parsed as strict JSON (see :func:`loads_json`)."""
    text = read_text(path, limit=limit, what=what, error=error)
    return loads_json(text, what=f"{what} {path}", error=error)


_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def contained(base, relative: str, *, what: str, error=None) -> Path:
    """The path ``relative`` names inside the folder ``base``: refused when it is absolute,
    has a scheme (``file:``, ``http:``), a drive, a ``..`` part or a NUL, or when it (or a
    link on its way) resolves outside ``base``."""
    if not isinstance(relative, str) or not relative:
        _fail(error, f"{what}: expected a relative path, got {relative!r}")
    if "\x00" in relative or "\\" in relative:
        _fail(error, f"{what}: {relative[:60]!r} holds a NUL or a backslash")
    if relative.startswith(("/", "~")) or _SCHEME.match(relative):
        _fail(error, f"{what}: {relative[:60]!r} is not a path relative to {base}")
    if ".." in Path(relative).parts:
        _fail(error, f"{what}: {relative[:60]!r} climbs out of its folder ('..')")
    root = Path(base).resolve()
    target = (root / relative).resolve()
    if target != root and root not in target.parents:
        _fail(error, f"{what}: {relative[:60]!r} leads outside {root} (a link out)")
    return target


_COMPONENT = re.compile(r"[^A-Za-z0-9._-]")


#: Longest file-name component and whole path, in bytes (Linux's NAME_MAX and PATH_MAX - 1).
NAME_MAX, PATH_MAX = 255, 4095


def path_problem(path) -> str | None:
    """Why ``path`` cannot name a file on this system (a NUL, a component over
    :data:`NAME_MAX` bytes, the whole over :data:`PATH_MAX`), or None. Names that are not
    UTF-8 are measured as the bytes they stand for."""
    data = os.fsencode(path)
    if b"\0" in data:
        return "it holds a NUL character"
    if len(data) > PATH_MAX:
        return f"it is {len(data)} bytes long, over the {PATH_MAX} a path may have"
    longest = max((len(part) for part in data.split(b"/")), default=0)
    if longest > NAME_MAX:
        return f"a component of it is {longest} bytes long, over the {NAME_MAX} a name may have"
    return None


def check_path(path, *, what: str, error=None) -> None:
    """One line when ``path`` cannot name a file (:func:`path_problem`)."""
    problem = path_problem(path)
    if problem is not None:
        shown = os.fsdecode(os.fsencode(path))
        _fail(error, f"{what} {shown[:80]!r}{'...' if len(shown) > 80 else ''}: {problem}")


def safe_component(text: str, *, what: str, error=None) -> str:
    """A single path component derived from user text: refused when empty, ``.``/``..``,
    or holding a separator, a NUL or a control character; other characters outside
    ``[A-Za-z0-9._-]`` become ``_``."""
    if not isinstance(text, str) or text in ("", ".", ".."):
        _fail(error, f"{what}: {text!r} cannot name a file or folder")
    if any(c in text for c in "/\\\x00") or any(ord(c) < 32 or ord(c) == 127 for c in text):
        _fail(error, f"{what}: {text[:60]!r} holds a path separator or a control character")
    return _COMPONENT.sub("_", text)


def check_number(value, *, what: str, lo=None, hi=None, error=None) -> float:
    """``value`` as a finite float within ``[lo, hi]`` (booleans and strings refused)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        _fail(error, f"{what}: expected a number, got {type(value).__name__}")
    try:
        number = float(value)
    except OverflowError:
        _fail(error, f"{what}: {value} is out of range")
    if not math.isfinite(number):
        _fail(error, f"{what}: expected a finite number, got {number}")
    if lo is not None and number < lo:
        _fail(error, f"{what}: {number:g} is below {lo:g}")
    if hi is not None and number > hi:
        _fail(error, f"{what}: {number:g} is above {hi:g}")
    return number


def check_int(value, *, what: str, lo=None, hi=None, error=None) -> int:
    """``value`` as an int within ``[lo, hi]`` (booleans, floats and strings refused)."""
    if isinstance(value, bool) or not isinstance(value, int):
        _fail(error, f"{what}: expected an integer, got {type(value).__name__}")
    if lo is not None and value < lo:
        _fail(error, f"{what}: {value} is below {lo}")
    if hi is not None and value > hi:
        _fail(error, f"{what}: {value} is above {hi}")
    return value


def check_finite(values, *, what: str, bound: float = 1e30, error=None) -> list[float]:
    """A flat sequence of finite numbers of magnitude at most ``bound``."""
    if not isinstance(values, list | tuple):
        _fail(error, f"{what}: expected a list of numbers, got {type(values).__name__}")
    return [check_number(v, what=what, lo=-bound, hi=bound, error=error) for v in values]


# --- escaping --------------------------------------------------------------------------------


def terminal(text) -> str:
    """``text`` on one line for the terminal: control characters (newlines, escapes, NUL,
    DEL, C1) written as Python writes them (``\\n``, ``\\x1b``); tabs kept."""
    return "".join(
        c
        if (c >= " " and c != "\x7f" and not "\x80" <= c <= "\x9f") or c == "\t"
        else repr(c)[1:-1]
        for c in str(text)
    )


def escape_html(text) -> str:
    """``text`` safe inside HTML content or a quoted attribute (``& < > " '`` escaped;
    control characters written out as by :func:`terminal`)."""
    return html.escape(terminal(text), quote=True)


_MD_SPECIAL = re.compile(r"([\\`*_{}\[\]()#+\-.!|<>&~])")


def escape_markdown(text) -> str:
    """``text`` safe in Markdown (GitHub's included): one line, every Markdown special
    backslash-escaped and ``< > &`` as HTML entities, so no link, image, HTML tag, code span
    or table cell boundary can come from it."""
    flat = terminal(text)
    out = _MD_SPECIAL.sub(lambda m: "\\" + m.group(1), flat)
    return out.replace("\\<", "&lt;").replace("\\>", "&gt;").replace("\\&", "&amp;")


def xml_text(text) -> str:
    """``text`` with only the characters XML 1.0 allows (tab, newline, carriage return and
    ``U+0020``-``U+D7FF``, ``U+E000``-``U+FFFD``, ``U+10000``-): others written as
    ``\\xNN``. Escaping ``& < >`` is left to the XML writer."""
    return "".join(
        c
        if c in "\t\n\r" or " " <= c <= "\ud7ff" or "\ue000" <= c <= "\ufffd" or c >= "\U00010000"
        else repr(c)[1:-1]
        for c in str(text)
    )
