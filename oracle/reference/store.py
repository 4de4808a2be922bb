"""References on demand: render, or serve from the cache, and publish into a folder."""

from __future__ import annotations

import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

from ...scenes import backend
from ...scenes.backend import provenance
from ...scenes.base.files import atomic_copy, atomic_write_json
from ...scenes.base.records import package_versions
from ...scenes.base.untrusted import read_json, terminal
from .cache import ORACLE_VERSION, ReferenceCache, reference_key, scratch_dir
from .exr import read_exr, write_exr
from .render import ReferenceSettings, render_reference

__all__ = ["Reference", "get_reference", "publish", "reproducible"]


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
    machine = provenance()  # the device and the backend's self-check verdict
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
        "sampling": "stratified jittered grid, 6-round TEA hash per (pixel, sample, seed)",
        "variant": info.variant,
        "libllvm": info.libllvm,
        "device": machine["device"],
        "self_check": machine["self_check"],
        "versions": package_versions(),
        "oracle_version": ORACLE_VERSION,
        "cache_key": key,
        "camera": loaded.camera.to_json(),
        **stats,
    }
    write_exr(folder / "reference.exr", channels)
    atomic_write_json(folder / "reference.json", meta)
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
    expect = (loaded.width, loaded.height)
    if cache is not None:
        folder, status = cache.lookup(key, expect=expect)
        if folder is not None:
            meta = read_json(folder / "reference.json", what="cached reference record")
            return Reference(folder, meta, status)
        if status == "unusable":
            _warn_skipped(cache, key)
            cache, status = None, "skipped"
    # A scratch folder (deleted by remove_scratch when the CLI command ends), or at once when
    # the render fails or the reference goes into the cache.
    tmp = scratch_dir()
    try:
        meta = _render_into(tmp, loaded, settings, quiet=quiet, key=key)
        if cache is not None and not reproducible(meta):
            return Reference(tmp, meta, "not cached (exact coverage cut by the budget)")
        folder = None if cache is None else cache.store(key, tmp, expect=expect)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if folder is None:
        if cache is not None:
            _warn_skipped(cache, key)
            status = "skipped"
        return Reference(tmp, meta, status)
    shutil.rmtree(tmp, ignore_errors=True)
    return Reference(folder, meta, status)


_warned: set[str] = set()


def _warn_skipped(cache: ReferenceCache, key: str) -> None:
    """One line on stderr (once per cache folder) saying why the cache is not used."""
    problem = cache.usable() or (
        f"cache entry {cache.entry(key)} cannot be read or replaced (not the cache's files)"
    )
    if os.fspath(cache.root) not in _warned:
        _warned.add(os.fspath(cache.root))
        print(f"raster-oracle: warning: {terminal(problem)}; not cached", file=sys.stderr)


def reproducible(meta: dict) -> bool:
    """Whether a rendered reference is what its cache key promises whenever it is rendered:
    not when its exact coverage was stopped at the deadline, or refused because earlier
    views of the command had spent part of the budget (a later command, with the whole
    budget, may compute it)."""
    exact = meta.get("coverage_exact") or {}
    decision = str(exact.get("decision", ""))
    if decision.startswith("over budget after"):
        return False
    return not (decision.startswith("skipped") and "budget_left_seconds" in exact)


def publish(ref: Reference, out_dir: Path) -> None:
    """Copy ``reference.exr``/``reference.json`` into ``out_dir``, each file atomically."""
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_copy(ref.exr, out_dir / "reference.exr")
    meta = dict(ref.meta)
    meta["cache_status"] = ref.cache_status
    atomic_write_json(out_dir / "reference.json", meta)
