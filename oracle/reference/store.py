"""References on demand: render, or serve from the cache, and publish into a folder."""

from __future__ import annotations

import json
import os
import platform
import shutil
import tempfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from scenes import backend

from .cache import ORACLE_VERSION, ReferenceCache, reference_key, scratch_dir
from .exr import atomic_write_bytes, make_readable, read_exr, write_exr
from .render import ReferenceSettings, render_reference

__all__ = ["Reference", "get_reference", "package_versions", "publish"]

_PACKAGES = (
    "raster-oracle",
    "mitsuba",
    "drjit",
    "numpy",
    "OpenEXR",
    "scikit-image",
    "colour-science",
    "flip-evaluator",
)


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


@dataclass
class Reference:
    """A reference on disk: ``folder/reference.exr`` and ``folder/reference.json``."""

    folder: Path
    meta: dict
    cache_status: str

    @property
    def exr(self) -> Path:
        return self.folder / "reference.exr"

    def channels(self) -> dict:
        return read_exr(self.exr)


def _render_into(
    folder: Path, loaded, settings: ReferenceSettings, *, quiet: bool, key: str
) -> dict:
    channels, stats = render_reference(loaded, settings, quiet=quiet)
    info = backend.active()
    meta = {
        "kind": "reference",
        "scene": loaded.provenance(),
        "description": loaded.description,
        "light": loaded.light.to_json(),
        "resolution": [loaded.width, loaded.height],
        "spp": settings.spp,
        "seed": settings.seed,
        "channels": list(channels),
        "channel_groups": list(settings.channels),
        "adaptive": settings.adaptive,
        "settings": settings.key_record(),
        "filter": "box (uniform over the pixel square)",
        "sampling": "stratified jittered grid, PCG32 per (pixel, sample)",
        "variant": info.variant,
        "libllvm": info.libllvm,
        "versions": package_versions(),
        "oracle_version": ORACLE_VERSION,
        "cache_key": key,
        "camera": loaded.camera.to_json(),
        **stats,
    }
    write_exr(folder / "reference.exr", channels)
    atomic_write_bytes(folder / "reference.json", json.dumps(meta, indent=2).encode())
    return meta


def get_reference(
    loaded, settings: ReferenceSettings, *, cache: ReferenceCache | None = None, quiet: bool = False
) -> Reference:
    """The reference of ``loaded`` with ``settings``: from the cache, else rendered (and cached).

    With ``cache=None`` the reference is rendered into a fresh temporary folder.
    """
    settings = settings.validate()
    key = reference_key(loaded, settings, backend.active().variant)
    status = "disabled"
    if cache is not None:
        folder, status = cache.lookup(key)
        if folder is not None:
            meta = json.loads((folder / "reference.json").read_text())
            return Reference(folder, meta, status)
    # A scratch folder (deleted by remove_scratch when the CLI command ends), or at once when
    # the render fails or the reference goes into the cache.
    tmp = scratch_dir()
    try:
        meta = _render_into(tmp, loaded, settings, quiet=quiet, key=key)
        if cache is None:
            return Reference(tmp, meta, status)
        folder = cache.store(key, tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        if cache is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return Reference(folder, meta, status)


def publish(ref: Reference, out_dir: Path, *, extra: dict | None = None) -> None:
    """Copy ``reference.exr``/``reference.json`` into ``out_dir``, each file atomically."""
    out_dir.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".reference.", suffix=".exr", dir=out_dir)
    os.close(fd)
    try:
        shutil.copyfile(ref.exr, tmp)
        make_readable(tmp)
        os.replace(tmp, out_dir / "reference.exr")
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    meta = dict(ref.meta)
    meta["cache_status"] = ref.cache_status
    meta.update(extra or {})
    atomic_write_bytes(out_dir / "reference.json", json.dumps(meta, indent=2).encode())
