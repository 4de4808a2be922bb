"""Content-addressed cache of references.

The key is the SHA-256 of the scene content hash (XML and the files it references, or the
built-in dictionary), the light, camera frame, resolution, every :class:`ReferenceSettings`
field (spp, seed, channels, adaptive settings), the Mitsuba variant and :data:`ORACLE_VERSION`.
An entry is a folder ``<root>/<key[:2]>/<key>/`` holding ``reference.exr``,
``reference.json`` and ``checksums.json``; it is written under a temporary name and renamed
into place, so readers never see a partial entry. An entry whose checksums do not match is
reported as corrupted, removed and rendered again.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["ORACLE_VERSION", "ReferenceCache", "default_cache_dir", "reference_key"]

#: Bump when the meaning of a reference channel changes: old cache entries become misses.
ORACLE_VERSION = "1"
FILES = ("reference.exr", "reference.json")


def default_cache_dir() -> Path:
    env = os.environ.get("RASTER_ORACLE_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "raster-oracle"


def reference_key(loaded, settings, variant: str) -> str:
    record = {
        "scene": loaded.content_hash,
        "light": loaded.light_index,
        "camera_path": loaded.camera_path,
        "frame": loaded.frame,
        "n_frames": loaded.n_frames,
        "camera": [[round(float(v), 12) for v in row] for row in loaded.camera.to_world],
        "resolution": [loaded.width, loaded.height],
        "settings": settings.key_record(),
        "variant": variant,
        "oracle_version": ORACLE_VERSION,
    }
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


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
        if not folder.is_dir():
            return None, "miss"
        try:
            sums = json.loads((folder / "checksums.json").read_text())
            ok = all(_sha256(folder / name) == sums[name] for name in FILES)
        except (OSError, ValueError, KeyError):
            ok = False
        if ok:
            return folder, "hit"
        shutil.rmtree(folder, ignore_errors=True)
        return None, "corrupted"

    def store(self, key: str, source_dir: Path) -> Path:
        """Copy ``reference.exr`` and ``reference.json`` from ``source_dir`` into the cache."""
        folder = self.entry(key)
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{key[:8]}.", dir=folder.parent))
        try:
            for name in FILES:
                shutil.copyfile(source_dir / name, tmp / name)
            sums = {name: _sha256(tmp / name) for name in FILES}
            (tmp / "checksums.json").write_text(json.dumps(sums))
            if folder.exists():
                shutil.rmtree(folder, ignore_errors=True)
            os.replace(tmp, folder)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return folder
