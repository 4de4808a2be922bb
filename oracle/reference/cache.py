"""Content-addressed cache of references.

The key is the SHA-256 of the scene content hash (XML and the files it references, or the
built-in dictionary), the light, camera frame, resolution, every :class:`ReferenceSettings`
field (spp, seed, channels, adaptive settings), the Mitsuba variant and :data:`ORACLE_VERSION`.
An entry is a folder ``<root>/<key[:2]>/<key>/`` holding ``reference.exr``,
``reference.json`` and ``checksums.json``; it is written under a temporary name and renamed
into place, so readers never see a partial entry, and a valid entry is never removed or
replaced (a reader may be copying from it; a second writer of the same key keeps it). An
entry whose checksums do not match is reported as corrupted, removed and rendered again; so
is an entry that is not a folder (a file, a broken link). A writer's temporary folder is named
``<shard>/.<key[:8]>.<pid>@<host>.<random>``; the next writer (of any key) removes those of
dead writers on this host at once, and any temporary folder older than
:data:`STALE_TEMP_SECONDS` (another host's, or one named before writers were named).

The cache folder is ``$RASTER_ORACLE_CACHE`` (``$RASTER_ORACLE_CACHE_DIR`` is accepted too),
else ``$XDG_CACHE_HOME/raster-oracle``, else ``~/.cache/raster-oracle``.

References rendered without the cache live in scratch folders ``raster-oracle-ref-<pid>-*`` of
the system temporary folder (:func:`scratch_dir`); :func:`remove_scratch` deletes this
process's folders (the CLI calls it when a command ends, whatever the outcome) and
:func:`sweep_stale_scratch` deletes those left by killed processes (dead PID, older than a day).
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import re
import shutil
import socket
import tempfile
import time
from pathlib import Path

from ...scenes.base.untrusted import read_json

__all__ = [
    "CACHE_ENV",
    "ORACLE_VERSION",
    "ReferenceCache",
    "default_cache_dir",
    "reference_key",
    "remove_scratch",
    "scratch_dir",
    "scratch_mark",
    "sweep_stale_scratch",
    "sweep_stale_temps",
    "temp_prefix",
]

#: Bump when the meaning of a reference channel changes: old cache entries become misses.
#: 2: TEA-hashed sampling streams and binomial stderr floors.
#: 4: the coverage group holds front_coverage (the front-most primitive's coverage) too.
#: 5: jitter from a 6-round 32-bit TEA hash; adaptive sampling refines near features only
#: and samples a scrambled Sobol sequence (issue 18).
#: 6: the coverage_exact group (analytic coverage of triangle scenes, issue 28).
ORACLE_VERSION = "6"
FILES = ("reference.exr", "reference.json")

#: Environment variables naming the cache folder, first set wins (the first is documented).
CACHE_ENV = ("RASTER_ORACLE_CACHE", "RASTER_ORACLE_CACHE_DIR")

#: Prefix of scratch folders in the system temporary folder.
SCRATCH_PREFIX = "raster-oracle-ref-"

#: Age after which a scratch folder of a dead process is swept: one day.
STALE_SECONDS = 86400.0

#: Age after which a hidden temporary entry folder (``<shard>/.<key[:8]>.*``, left by a
#: process killed while storing) is swept whoever wrote it: an hour, far longer than copying
#: two files takes. A dead writer's on this host goes at once (:func:`sweep_stale_temps`).
STALE_TEMP_SECONDS = 3600.0

#: A temporary entry folder's name: key prefix, writer's pid and host, mkdtemp's random part.
_TEMP_NAME = re.compile(r"\.[0-9a-f]{8}\.(\d+)@([A-Za-z0-9-]+)\.")

_scratch: list[Path] = []


def default_cache_dir() -> Path:
    for name in CACHE_ENV:
        env = os.environ.get(name)
        if env:
            return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "raster-oracle"


def reference_key(loaded, settings, variant: str) -> str:
    record = {
        "scene": loaded.content_hash,
        "light": loaded.light_index,
        # The light actually used (a light path moves it from frame to frame).
        "light_used": loaded.light.to_json(),
        "light_path": loaded.light_path,
        "camera_path": loaded.camera_path,
        "frame": loaded.frame,
        "n_frames": loaded.n_frames,
        "camera": [[round(float(v), 12) for v in row] for row in loaded.camera.to_world],
        "resolution": [loaded.width, loaded.height],
        "settings": settings.key_record(),
        "variant": variant,
        "oracle_version": ORACLE_VERSION,
    }
    if getattr(loaded, "camera_file", None):
        # a camera file sets the field of view per frame (the matrix alone does not say it)
        record["fov_x"] = round(float(loaded.camera.fov_x), 12)
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


def scratch_dir() -> Path:
    """A new scratch folder ``raster-oracle-ref-<pid>-*`` that :func:`remove_scratch` deletes."""
    folder = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-"))
    _scratch.append(folder)
    return folder


def scratch_mark() -> int:
    """How many scratch folders this process has made: pass to :func:`remove_scratch`."""
    return len(_scratch)


def remove_scratch(since: int = 0) -> None:
    """Delete the scratch folders this process made after mark ``since`` (default: all)."""
    while len(_scratch) > since:
        shutil.rmtree(_scratch.pop(), ignore_errors=True)


atexit.register(remove_scratch)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # no such process (or no such pid at all)
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def sweep_stale_scratch(*, now: float | None = None, tmp: str | os.PathLike | None = None) -> int:
    """Delete scratch folders of dead processes older than a day; returns how many went."""
    root = Path(tmp if tmp is not None else tempfile.gettempdir())
    now = time.time() if now is None else now
    removed = 0
    try:
        candidates = list(root.glob(f"{SCRATCH_PREFIX}*"))
    except OSError:
        return 0
    for folder in candidates:
        pid_text = folder.name[len(SCRATCH_PREFIX) :].split("-", 1)[0]
        try:
            st = folder.lstat()
        except OSError:
            continue
        if not folder.is_dir() or folder.is_symlink() or st.st_uid != os.getuid():
            continue
        if now - st.st_mtime < STALE_SECONDS:
            continue
        if pid_text.isdigit() and _pid_alive(int(pid_text)):
            continue
        shutil.rmtree(folder, ignore_errors=True)
        removed += 1
    return removed


def _host() -> str:
    """This machine's name as it appears in temporary folder names (letters, digits, -)."""
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:64] or "host"


def temp_prefix(key: str, *, pid: int | None = None, host: str | None = None) -> str:
    """Prefix of a temporary entry folder of ``key`` written by process ``pid`` (default:
    this one) of ``host`` (default: this machine); ``mkdtemp`` adds a random part."""
    pid = os.getpid() if pid is None else pid
    return f".{key[:8]}.{pid}@{_host() if host is None else host}."


def _is_regular(path: Path) -> bool:
    """A regular file, not a link (a FIFO planted in an entry would hang the checksum)."""
    return path.is_file() and not path.is_symlink()


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class ReferenceCache:
    """A folder of cached references keyed by :func:`reference_key`."""

    def __init__(self, root: str | os.PathLike | None = None):
        self.root = Path(root) if root is not None else default_cache_dir()

    def entry(self, key: str) -> Path:
        return self.root / key[:2] / key

    def lookup(self, key: str) -> tuple[Path | None, str]:
        """``(folder, status)``: status is ``hit``, ``miss`` or ``corrupted`` (entry removed)."""
        folder = self.entry(key)
        if not os.path.lexists(folder):
            return None, "miss"
        if folder.is_symlink() or not folder.is_dir():
            _remove(folder)
            return None, "corrupted"
        try:
            sums = read_json(folder / "checksums.json", limit=1 << 16, what="cache checksums")
            ok = isinstance(sums, dict) and all(
                _is_regular(folder / name) and _sha256(folder / name) == sums[name]
                for name in FILES
            )
        except (OSError, ValueError, KeyError):
            ok = False
        if ok:
            return folder, "hit"
        _remove(folder)
        return None, "corrupted"

    def store(self, key: str, source_dir: Path) -> Path:
        """Copy ``reference.exr`` and ``reference.json`` from ``source_dir`` into the cache.

        A valid entry already there (another process stored the same key meanwhile) is kept
        as it is, never removed or replaced, since a reader may be copying from it: the
        entry is content-addressed, so both hold the same reference. Only a corrupted entry
        is replaced. Temporary folders of killed writers, in any shard, are swept
        (:func:`sweep_stale_temps`).
        """
        folder = self.entry(key)
        if os.path.lexists(folder.parent) and not folder.parent.is_dir():
            _remove(folder.parent)  # a file where the shard folder belongs: corrupted
        folder.parent.mkdir(parents=True, exist_ok=True)
        sweep_stale_temps(self.root)
        if self.lookup(key)[1] == "hit":
            return folder
        tmp = Path(tempfile.mkdtemp(prefix=temp_prefix(key), dir=folder.parent))
        try:
            for name in FILES:
                shutil.copyfile(source_dir / name, tmp / name)
            sums = {name: _sha256(tmp / name) for name in FILES}
            (tmp / "checksums.json").write_text(json.dumps(sums))
            try:
                os.rename(tmp, folder)  # fails when a folder appeared there meanwhile
            except OSError:
                if self.lookup(key)[1] != "hit":
                    raise
                shutil.rmtree(tmp, ignore_errors=True)  # another writer won: keep its entry
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return folder


def sweep_stale_temps(root: Path, *, now: float | None = None) -> int:
    """Remove the temporary entry folders (``<shard>/.<key[:8]>.*``) that writers killed while
    storing left, in every shard of the cache ``root``: those named after a process of this
    host that is no longer running, whatever their age, and any older than
    :data:`STALE_TEMP_SECONDS` (a writer on another host sharing the folder, a pid reused by
    another process). Returns how many were removed."""
    now = time.time() if now is None else now
    host = _host()
    removed = 0
    for tmp in Path(root).glob("*/.*"):
        try:
            old = now - tmp.lstat().st_mtime > STALE_TEMP_SECONDS
        except OSError:
            continue
        owner = _TEMP_NAME.match(tmp.name)
        dead = (
            owner is not None
            and owner[2] == host
            and int(owner[1]) != os.getpid()
            and not _pid_alive(int(owner[1]))
        )
        if old or dead:
            _remove(tmp)
            removed += 1
    return removed


def _remove(path: Path) -> None:
    """Delete a file, link or folder tree at ``path``; a missing path is fine."""
    if path.is_symlink() or (os.path.lexists(path) and not path.is_dir()):
        path.unlink(missing_ok=True)
    else:
        shutil.rmtree(path, ignore_errors=True)
