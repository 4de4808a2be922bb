"""Content-addressed cache of references.

The key is the SHA-256 of the scene content hash (XML and the files it references, or the
built-in dictionary), the light, camera frame, resolution, every :class:`ReferenceSettings`
field (spp, seed, channels, adaptive settings), the Mitsuba variant and :data:`ORACLE_VERSION`.
An entry is a folder ``<root>/<key[:2]>/<key>/`` holding ``reference.exr``,
``reference.json`` and ``checksums.json``; it is written under a temporary name and renamed
into place, so readers never see a partial entry, and a valid entry is never removed or
replaced (a reader may be copying from it; a second writer of the same key keeps it). An
entry whose checksums do not match is reported as corrupted, removed and rendered again; so
is an entry that is not a folder (a file, a broken link), one whose record is not an object
naming its key, and one whose record or image has another size than asked for. The cache
touches only what it wrote (issue 48): its folder carries the marker :data:`MARKER`, no link
is followed, and a folder is removed only when it holds nothing but an entry's own files.
A writer's temporary folder is named
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
import stat
import tempfile
import time
from pathlib import Path

from ...scenes.base.files import atomic_write_bytes
from ...scenes.base.untrusted import read_json

__all__ = [
    "CACHE_ENV",
    "MARKER",
    "ORACLE_VERSION",
    "ReferenceCache",
    "default_cache_dir",
    "reference_key",
    "exr_size",
    "remove_own",
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
#: Every file an entry (or a temporary entry folder) may hold.
OWN_FILES = (*FILES, "checksums.json")

#: The folder of the backends' self-check verdicts in the cache folder (:mod:`oracle.certify`).
SELF_CHECK = "self-check"

#: The file that marks a folder as the cache's own; without it nothing there is touched.
MARKER = ".raster-oracle-cache"
MARKER_TEXT = b"raster-oracle reference cache: entries <key[:2]>/<key>/\n"

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
_TEMP_PREFIX = re.compile(r"\.[0-9a-f]{8}\.")
_SHARD = re.compile(r"[0-9a-f]{2}")
_KEY = re.compile(r"[0-9a-f]{64}")

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
    """A folder of cached references keyed by :func:`reference_key`.

    The folder is the cache's only when it holds the marker file :data:`MARKER` (written when
    the folder is made, or found empty, or holds nothing but shard folders of entries): a
    folder holding anything else (a project, notes, links) is never written to nor cleaned,
    and the cache is skipped with one line (:meth:`usable`). Inside its folder the cache
    touches only paths of its own naming (shards ``[0-9a-f]{2}``, entries ``[0-9a-f]{64}``,
    temporary ``.<key[:8]>.*``), never follows a link, and removes a folder only when it holds
    nothing but the entry's own files (:func:`remove_own`).
    """

    def __init__(self, root: str | os.PathLike | None = None):
        self.root = Path(root) if root is not None else default_cache_dir()
        self._problem: str | None = None
        self._checked = False

    def entry(self, key: str) -> Path:
        return self.root / key[:2] / key

    def usable(self) -> str | None:
        """None when the cache folder is the cache's own and writable (made and marked if
        needed); else one line saying why the cache is skipped. Checked once."""
        if not self._checked:
            self._problem = _claim(self.root)
            self._checked = True
        return self._problem

    def _shard(self, key: str) -> Path | None:
        """The key's shard folder when it is a real folder (not a link); None when absent;
        a file or link there is removed (the path is the cache's)."""
        shard = self.root / key[:2]
        try:
            st = os.lstat(shard)
        except FileNotFoundError:
            return None
        if stat.S_ISDIR(st.st_mode):
            return shard
        shard.unlink()  # a file or a link where the shard folder belongs: never followed
        return None

    def lookup(self, key: str, *, expect: tuple[int, int] | None = None) -> tuple[Path | None, str]:
        """``(folder, status)``: status is ``hit``, ``miss``, ``corrupted`` (entry removed and
        to be rendered again) or ``unusable`` (an entry that cannot be read or removed: the
        reference is rendered and not stored). ``expect`` is the ``(width, height)`` the
        entry's image and record must have."""
        if self.usable() is not None:
            return None, "unusable"
        if not _KEY.fullmatch(key) or self._shard(key) is None:
            return None, "miss"
        folder = self.entry(key)
        try:
            st = os.lstat(folder)
        except FileNotFoundError:
            return None, "miss"
        if stat.S_ISDIR(st.st_mode):
            try:
                if _entry_valid(folder, key, expect):
                    return folder, "hit"
            except PermissionError:
                return None, "unusable"
        return (None, "corrupted") if remove_own(folder) else (None, "unusable")

    def store(self, key: str, source_dir: Path, *, expect=None) -> Path | None:
        """Copy ``reference.exr`` and ``reference.json`` from ``source_dir`` into the cache;
        returns the entry, or None when the entry's place holds what is not the cache's.

        A valid entry already there (another process stored the same key meanwhile) is kept
        as it is, never removed or replaced, since a reader may be copying from it: the
        entry is content-addressed, so both hold the same reference. Only a corrupted entry
        is replaced. Temporary folders of killed writers, in any shard, are swept
        (:func:`sweep_stale_temps`).
        """
        if self.usable() is not None or not _KEY.fullmatch(key):
            return None
        folder = self.entry(key)
        if self._shard(key) is None:
            folder.parent.mkdir(exist_ok=True)
        sweep_stale_temps(self.root)
        found, status = self.lookup(key, expect=expect)
        if status == "hit":
            return found
        if status == "unusable":
            return None
        tmp = Path(tempfile.mkdtemp(prefix=temp_prefix(key), dir=folder.parent))
        try:
            for name in FILES:
                shutil.copyfile(source_dir / name, tmp / name)
            sums = {name: _sha256(tmp / name) for name in FILES}
            (tmp / "checksums.json").write_text(json.dumps(sums))
            try:
                os.rename(tmp, folder)  # fails when a folder appeared there meanwhile
            except OSError:
                if self.lookup(key, expect=expect)[1] != "hit":
                    raise
                remove_own(tmp)  # another writer won: keep its entry
        except BaseException:
            remove_own(tmp)
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
    for tmp in _own_temps(Path(root)):
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
        if (old or dead) and remove_own(tmp):
            removed += 1
    return removed


def _own_temps(root: Path) -> list[Path]:
    """The temporary entry folders of the cache ``root``: real folders (never links) named
    ``.<8 hex>.*`` in real shard folders named ``[0-9a-f]{2}``."""
    found = []
    for shard in _listdir(root):
        if not _SHARD.fullmatch(shard) or not _real_dir(root / shard):
            continue
        for name in _listdir(root / shard):
            if _TEMP_PREFIX.match(name) and _real_dir(root / shard / name):
                found.append(root / shard / name)
    return found


def _listdir(folder: Path) -> list[str]:
    try:
        return sorted(os.listdir(folder))
    except OSError:
        return []


def _real_dir(path: Path) -> bool:
    """A folder itself, not a link to one."""
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def remove_own(path: Path) -> bool:
    """Remove ``path`` when it is provably the cache's: a file or a link at a path of the
    cache's naming (unlinked, never followed), or a real folder holding nothing but an entry's
    own files (:data:`OWN_FILES`, none of them a folder). Returns whether it is gone; a folder
    holding anything else is left whole."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return True
    except OSError:
        return False
    try:
        if not stat.S_ISDIR(st.st_mode):
            os.unlink(path)
            return True
        names = os.listdir(path)
        if any(n not in OWN_FILES or _real_dir(path / n) for n in names):
            return False
        for name in names:
            os.unlink(path / name)
        os.rmdir(path)
    except OSError:
        return False
    return True


def _is_cache_layout(root: Path) -> bool:
    """Everything in ``root`` is the cache's own: the self-check verdicts' folder and shard
    folders (not links) named ``[0-9a-f]{2}`` holding only entry folders (``[0-9a-f]{64}``)
    and temporary folders, each holding only an entry's own files. A cache made before the
    marker existed is one."""
    for shard in _listdir(root):
        if shard == SELF_CHECK and _real_dir(root / shard):
            # the backends' self-check verdicts (oracle.certify.verdict): regular files only
            if any(
                _real_dir(root / shard / n) or os.path.islink(root / shard / n)
                for n in _listdir(root / shard)
            ):
                return False
            continue
        if not _SHARD.fullmatch(shard) or not _real_dir(root / shard):
            return False
        for name in _listdir(root / shard):
            entry = root / shard / name
            if not (_KEY.fullmatch(name) or _TEMP_PREFIX.match(name)) or not _real_dir(entry):
                return False
            if any(n not in OWN_FILES or _real_dir(entry / n) for n in _listdir(entry)):
                return False
    return True


def _claim(root: Path) -> str | None:
    """Make ``root`` the cache's (create it, write the marker) unless it holds foreign files
    or cannot be written; None when usable, else why not (one line)."""
    marker = root / MARKER
    try:
        root.mkdir(parents=True, exist_ok=True)
        if not root.is_dir():
            return f"cache folder {root} is not a folder"
        if os.path.lexists(marker):
            if not _is_regular(marker) or marker.read_bytes() != MARKER_TEXT:
                return f"cache folder {root}: {MARKER} is not the cache's marker"
        elif not _is_cache_layout(root):
            return (
                f"cache folder {root} holds files that are not the cache's (no {MARKER} "
                "marker); choose an empty folder with --cache-dir or $RASTER_ORACLE_CACHE"
            )
        if not os.access(root, os.R_OK | os.W_OK | os.X_OK):
            return f"cache folder {root} is not writable"
        if not os.path.lexists(marker):
            atomic_write_bytes(marker, MARKER_TEXT)
    except OSError as exc:
        return f"cache folder {root} cannot be used ({exc.strerror or type(exc).__name__})"
    return None


def _entry_valid(folder: Path, key: str, expect: tuple[int, int] | None) -> bool:
    """The entry's files match its checksums, its record is an object naming ``key`` and the
    image and record have the size ``expect`` (when given). A PermissionError propagates."""
    try:
        sums = read_json(folder / "checksums.json", limit=1 << 16, what="cache checksums")
        if not isinstance(sums, dict):
            return False
        for name in FILES:
            if not _is_regular(folder / name) or _sha256(folder / name) != sums.get(name):
                return False
        meta = read_json(folder / "reference.json", what="cached reference record")
    except PermissionError:
        raise
    except (OSError, ValueError):
        return False
    if not isinstance(meta, dict) or meta.get("cache_key", key) != key:
        return False
    if expect is None:
        return True
    return meta.get("resolution") == list(expect) and exr_size(folder / "reference.exr") == expect


def exr_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` of an EXR's data window read from its header, or None when the
    header cannot be read (not an EXR, truncated, no ``dataWindow``)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return None
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    pos = 8
    while pos < len(head) and head[pos] != 0:
        name_end = head.find(b"\0", pos)
        type_end = head.find(b"\0", name_end + 1)
        if name_end < 0 or type_end < 0 or type_end + 4 > len(head):
            return None
        size = int.from_bytes(head[type_end + 1 : type_end + 5], "little")
        value = head[type_end + 5 : type_end + 5 + size]
        if head[pos:name_end] == b"dataWindow" and len(value) == 16:
            x0, y0, x1, y1 = (
                int.from_bytes(value[i : i + 4], "little", signed=True) for i in range(0, 16, 4)
            )
            return x1 - x0 + 1, y1 - y0 + 1
        pos = type_end + 5 + size
    return None
