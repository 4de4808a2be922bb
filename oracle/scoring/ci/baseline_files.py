"""The files of a baseline folder, handled as untrusted: nothing followed out, nothing lost.

:func:`install` puts a platform's new baseline files in place: it holds the platform
folder's lock (``.accept.lock``; concurrent accepts into one folder take turns, each leaving
its trace), claims the next free ``previous/NNN`` with an atomic ``mkdir`` (numbered after
every numbered entry), writes the new files aside (``.incoming-*``), then renames the current
files into ``previous/NNN`` and the new ones into place. Links inside the baseline folder (the
platform folder, ``previous``, the current files, the lock) are never followed: refused with
one line (:class:`GateError`), as are a platform folder that is a file and a ``previous``
that is no folder. :func:`read_run_record` reads a run's ``metrics.json`` as untrusted input.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path

from ....scenes.base.files import atomic_write_bytes, signals_held
from ....scenes.base.untrusted import LIMITS, loads_json, read_bounded
from .checks import GateError

__all__ = ["LOCK", "install", "platform_folder", "read_run_record"]

#: The lock file of a platform folder.
LOCK = ".accept.lock"


def read_run_record(path: Path, *, what: str = "baseline accept: run record"):
    """A run's ``metrics.json`` (a bounded regular file of strict JSON): the record and its
    bytes (the bytes read once: what is checked is what is copied)."""
    data = read_bounded(path, limit=LIMITS["json_bytes"], what=what, error=GateError)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise GateError(f"{what} {path} is not UTF-8 text") from None
    return loads_json(text, what=f"{what} {path}", error=GateError), data


def _exists(path: Path, *, folder: bool) -> bool:
    """Whether ``path`` exists, as a real folder (``folder``) or regular file, never a link;
    :class:`GateError` for a link or the other kind."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return False
    if stat.S_ISLNK(st.st_mode):
        raise GateError(f"baseline accept: {path} is a link (never followed out of the folder)")
    want, kind = (stat.S_ISDIR, "a folder") if folder else (stat.S_ISREG, "a regular file")
    if not want(st.st_mode):
        raise GateError(f"baseline accept: {path} exists and is not {kind}")
    return True


def platform_folder(into: Path, platform: str) -> Path:
    """``into/platform``, made if missing; a link or a file there is refused."""
    folder = Path(into) / platform
    Path(into).mkdir(parents=True, exist_ok=True)
    if not _exists(folder, folder=True):
        with contextlib.suppress(FileExistsError):
            folder.mkdir()
        _exists(folder, folder=True)
    return folder


@contextlib.contextmanager
def _locked(folder: Path):
    """Hold ``folder/.accept.lock`` exclusively (POSIX); a no-op where locks do not exist."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    lock = folder / LOCK
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(lock, flags, 0o666)
    except OSError as exc:
        raise GateError(
            f"baseline accept: cannot take the lock {lock} ({type(exc).__name__}; a link or "
            "an odd file there is never followed)"
        ) from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise GateError(f"baseline accept: {lock} is not a regular file")
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _claim_previous(folder: Path) -> Path:
    """Make and return the next free ``previous/NNN`` (numbered after every numbered entry,
    claimed with an atomic ``mkdir``)."""
    previous = folder / "previous"
    if not _exists(previous, folder=True):
        previous.mkdir()
    taken = [int(p.name) for p in previous.iterdir() if p.name.isdigit()]
    n = max(taken, default=0) + 1
    while True:
        target = previous / f"{n:03d}"
        try:
            target.mkdir()
            return target
        except FileExistsError:
            n += 1


def _sweep_killed(folder: Path) -> None:
    """What an accept killed outright (``kill -9``) left, removed under the lock (so no
    accept is running): its ``.incoming-*`` folders (real folders, links never followed) and
    its claimed ``previous/NNN`` folders that stayed empty."""
    for entry in folder.iterdir():
        if entry.name.startswith(".incoming-") and _real_folder(entry):
            shutil.rmtree(entry, ignore_errors=True)
    previous = folder / "previous"
    if not _real_folder(previous):
        return
    for entry in previous.iterdir():
        if entry.name.isdigit() and _real_folder(entry) and not any(entry.iterdir()):
            entry.rmdir()


def _real_folder(path: Path) -> bool:
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def install(folder: Path, names: tuple[str, ...], make: Callable[[str | None], dict]) -> None:
    """Put new files ``names`` in ``folder`` keeping the current ones (see the module
    docstring); ``make(previous)`` gives the new files' bytes by name, ``previous`` the
    ``previous/NNN`` the current files move to (None: there are none)."""
    with _locked(folder):
        _sweep_killed(folder)
        current = [n for n in names if _exists(folder / n, folder=False)]
        target = _claim_previous(folder) if current else None
        incoming = Path(tempfile.mkdtemp(prefix=".incoming-", dir=folder))
        try:
            files = make(None if target is None else target.relative_to(folder).as_posix())
            for name in names:
                atomic_write_bytes(incoming / name, files[name])
            with signals_held():  # a stop waits for the renames: both sets whole
                for name in current:
                    os.replace(folder / name, target / name)
                for name in names:  # in the order given: a reader never sees a new note alone
                    os.replace(incoming / name, folder / name)
        except BaseException:
            if target is not None and not any(target.iterdir()):
                target.rmdir()
            raise
        finally:
            shutil.rmtree(incoming, ignore_errors=True)
