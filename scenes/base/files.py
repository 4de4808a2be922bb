"""Files written atomically: a reader never sees a half-written file.

Every file the oracle writes goes to a temporary name in the target folder (same file
system) and is renamed into place with :func:`os.replace`; a failure removes the temporary
file and leaves any previous file untouched. New files get the usual mode (``0666 & ~umask``),
not the ``0600`` of :func:`tempfile.mkstemp`.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from .records import jsonable

__all__ = ["atomic_copy", "atomic_write", "atomic_write_bytes", "atomic_write_json"]


def _make_readable(path: str) -> None:
    """Give a ``mkstemp`` file (mode 0600) the usual mode of a new file (0666 & ~umask)."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


def atomic_write(path: str | os.PathLike, write: Callable[[str], object]) -> None:
    """Make ``path`` by calling ``write(tmp)`` on a temporary file beside it, then renaming.

    Parameters
    ----------
    path : the file to write; its folder must exist.
    write : writes the whole file at the temporary path it is given (an existing empty file).
    """
    path = Path(path)
    # the temporary name keeps the file's extension (libraries that look at it see the same)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent
    )
    os.close(fd)
    try:
        write(tmp)
        _make_readable(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def atomic_write_json(path: str | os.PathLike, record, *, sort_keys: bool = False) -> None:
    """Write ``record`` as indented JSON (through :func:`.records.jsonable`) atomically."""
    text = json.dumps(jsonable(record), indent=2, sort_keys=sort_keys, allow_nan=False)
    atomic_write_bytes(path, text.encode())


def atomic_copy(source: str | os.PathLike, path: str | os.PathLike) -> None:
    """Copy the file ``source`` to ``path`` atomically."""
    atomic_write(path, lambda tmp: shutil.copyfile(source, tmp))
