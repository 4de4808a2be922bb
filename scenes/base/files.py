"""Files and folders written atomically: a reader never sees a half-written output.

Every file the oracle writes goes to a temporary name in the target folder (same file
system) and is renamed into place with :func:`os.replace`; a failure removes the temporary
file and leaves any previous file untouched. New files get the usual mode (``0666 & ~umask``),
not the ``0600`` of :func:`tempfile.mkstemp`.

A command's output folder is written the same way (:func:`staged_folder`): everything goes
into a hidden staging folder beside it, moved into place only when the command succeeds,
its record files last, with SIGTERM and SIGINT held back while the moves run; a failure or a
stop leaves the output folder as it was (absent, or the previous run's).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from .records import jsonable

__all__ = [
    "STAGING_MARK",
    "atomic_copy",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_json",
    "moves_in_progress",
    "signals_held",
    "staged_folder",
]


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


#: The file that marks a staging folder as this module's (stale ones are swept by name and mark).
STAGING_MARK = ".raster-oracle-staging"
_STAGING = re.compile(r"\.(.{0,80})\.partial-(\d+)-")


_moving = [0]


def moves_in_progress() -> bool:
    """Whether an output is being moved into place now (a watchdog that would end the
    process on a stop waits for it)."""
    return _moving[0] > 0


@contextmanager
def signals_held():
    """SIGTERM and SIGINT held back (recorded, then delivered to the previous handlers) while
    the block runs, in the main thread; elsewhere nothing is held."""
    import threading

    _moving[0] += 1
    got: list[int] = []
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGTERM, signal.SIGINT):
            previous[signum] = signal.signal(signum, lambda n, _f: got.append(n))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        _moving[0] -= 1
        for signum in got[:1]:
            handler = previous[signum]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def _stale_staging(path: Path) -> None:
    """Remove staging folders beside ``path`` that killed runs (dead pid) left for it."""
    try:
        names = os.listdir(path.parent)
    except OSError:
        return
    for name in names:
        found = _STAGING.match(name)
        if not found or found[1] != path.name[:80] or int(found[2]) == os.getpid():
            continue
        folder = path.parent / name
        if os.path.islink(folder) or not (folder / STAGING_MARK).is_file():
            continue
        try:
            os.kill(int(found[2]), 0)
            continue  # its writer still runs
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except (PermissionError, OverflowError):
            continue


def _commit(stage: Path, path: Path, last: tuple[str, ...], replaces: tuple[str, ...]) -> None:
    """Move the staged output into ``path``: the whole folder renamed when ``path`` does not
    exist; else each entry replaced (a sub-folder whole, the old one moved aside into the
    stage), JSON records after the other files and the names in ``last`` at the end; the
    entries of ``path`` named in ``replaces`` (an earlier run's own) are moved aside first."""
    (stage / STAGING_MARK).unlink()
    if not os.path.lexists(path):
        os.rename(stage, path)
        return
    aside = Path(tempfile.mkdtemp(prefix=".replaced-", dir=stage))
    for name in replaces:
        if "/" not in name and name not in ("", ".", "..") and os.path.lexists(path / name):
            os.rename(path / name, aside / name)
    names = sorted(n for n in os.listdir(stage) if stage / n != aside)
    names.sort(key=lambda n: (n in last, n.endswith(".json")))
    for name in names:
        src, dst = stage / name, path / name
        if os.path.isdir(src) and not os.path.islink(src):
            if os.path.lexists(dst):
                os.rename(dst, aside / name)
            os.rename(src, dst)
        else:
            os.replace(src, dst)


@contextmanager
def staged_folder(
    path: str | os.PathLike, *, last: tuple[str, ...] = (), replaces: tuple[str, ...] = ()
) -> Iterator[Path]:
    """Yield a staging folder to write a command's output into; moved into ``path`` when the
    block ends without an exception (see :func:`_commit`), removed otherwise.

    Parameters
    ----------
    path : the output folder (made with its parents when missing).
    last : names moved last (the record a reader takes as "the run is complete").
    replaces : names in ``path`` that the new output supersedes (an earlier run's entries
        that this run does not write): removed when the output is moved in.
    """
    path = Path(path)
    made = [p for p in path.parents if not os.path.lexists(p)]  # removed again on failure
    path.parent.mkdir(parents=True, exist_ok=True)
    _stale_staging(path)
    stage = Path(
        tempfile.mkdtemp(prefix=f".{path.name[:80]}.partial-{os.getpid()}-", dir=path.parent)
    )
    (stage / STAGING_MARK).write_bytes(b"")
    done = False
    try:
        yield stage
        with signals_held():  # a stop while the moves run waits for them
            _commit(stage, path, last, replaces)
        done = True
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        for folder in [] if done else made:  # deepest first: only the empty ones it made
            try:
                folder.rmdir()
            except OSError:
                break
