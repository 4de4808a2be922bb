"""A backend is trusted only after its self-check passed on this machine.

The verdict of :func:`.battery.run_battery` is cached under the cache folder
(``<cache>/self-check/<variant>-<key>.json``), keyed by the variant, the device (GPU name
and driver, or CPU model and cores), libLLVM and the package versions, and the battery's
own version: any change runs the battery again. :func:`certified_select` is what the
command line calls before every command:

- ``auto`` tries the variants :func:`scenes.backend.auto_variants` offers, best first; one
  that fails its battery is left for the next with one warning line naming the failed
  checks (a failing ``cuda_ad_rgb`` falls back to ``llvm_ad_rgb``);
- an explicitly requested variant that fails is refused (:class:`BackendRefused`, exit 2,
  the checks named) unless ``trust`` (``--trust-backend``, or the environment variable
  ``RASTER_ORACLE_TRUST_BACKEND=1`` for scripts that cannot change their command lines);
- the verdict in force is recorded by :func:`scenes.backend.set_self_check` for every
  result's provenance.

A cached verdict is untrusted input (:func:`valid_verdict`): a file that is no regular file
(a folder, a FIFO), not strict JSON, of another key, or malformed or inconsistent (``passed``
not a boolean, ``failed`` not a list of names, ``passed`` true with checks failed, ``failed``
not the checks that did not pass) is discarded and the battery run again. A verdict that
cannot be cached (the path a folder, ``self-check`` a file) is used for this run with one
warning line.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from pathlib import Path

from ...scenes import backend
from ...scenes.base.files import atomic_write_json
from ...scenes.base.records import package_versions
from ...scenes.base.untrusted import UntrustedError, read_json
from ..errors import InputError
from ..reference.cache import default_cache_dir

__all__ = [
    "BATTERY_VERSION",
    "BackendRefused",
    "certified_select",
    "cached_verdict",
    "machine_key",
    "run_check",
    "summary",
    "valid_verdict",
    "verdict_path",
]

#: Version of the battery (its checks and bounds): part of every verdict's key.
BATTERY_VERSION = 3


class BackendRefused(InputError):
    """A backend failed its self-check on this machine and was not trusted."""


def machine_key(variant: str) -> dict:
    """Everything a verdict depends on: variant, device, libLLVM, package versions and
    :data:`BATTERY_VERSION`."""
    return {
        "variant": variant,
        "device": backend.device_info(variant),
        "libllvm": backend.find_libllvm() if variant.startswith("llvm") else None,
        "versions": package_versions(),
        "battery": BATTERY_VERSION,
    }


def _digest(key: dict) -> str:
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]


def verdict_path(key: dict, cache_dir: Path | None = None) -> Path:
    """Where the verdict of ``key`` (:func:`machine_key`) is cached."""
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return folder / "self-check" / f"{key['variant']}-{_digest(key)}.json"


def cached_verdict(variant: str, *, cache_dir: Path | None = None) -> dict | None:
    """The cached verdict of ``variant`` on this machine, or None (none, unreadable, or made
    for another device, driver or version)."""
    key = machine_key(variant)
    path = verdict_path(key, cache_dir)
    try:
        if not os.path.lexists(path):
            return None
        verdict = read_json(path, limit=1 << 20, what="cached verdict")
    except (UntrustedError, OSError):
        return None
    return verdict if valid_verdict(verdict, key) else None


def _names(value) -> bool:
    return isinstance(value, list) and all(isinstance(n, str) for n in value)


def valid_verdict(verdict, key: dict) -> bool:
    """Whether ``verdict`` is a well-formed, self-consistent verdict of ``key``: ``passed`` a
    boolean, ``failed`` a list of check names empty exactly when passed, ``checks`` (when
    given) a list of ``{"name": str, "passed": bool}`` whose failures are ``failed``,
    ``checked_at`` a string or null."""
    if not isinstance(verdict, dict) or verdict.get("key") != key:
        return False
    passed, failed = verdict.get("passed"), verdict.get("failed")
    if not isinstance(passed, bool) or not _names(failed) or passed != (not failed):
        return False
    if not isinstance(verdict.get("checked_at"), str | type(None)):
        return False
    checks = verdict.get("checks")
    if checks is None:
        return True
    if not isinstance(checks, list) or not all(
        isinstance(c, dict) and isinstance(c.get("name"), str) and isinstance(c.get("passed"), bool)
        for c in checks
    ):
        return False
    return [c["name"] for c in checks if not c["passed"]] == failed


def summary(verdict: dict, *, status: str | None = None) -> dict:
    """The part of a verdict every result's provenance records: ``status`` (``passed``,
    ``failed``, or ``trusted``), ``failed`` (check names), ``checked_at`` and ``key``."""
    return {
        "status": status or ("passed" if verdict["passed"] else "failed"),
        "variant": verdict["key"]["variant"],
        "failed": list(verdict["failed"]),
        "checked_at": verdict.get("checked_at"),
        "key": _digest(verdict["key"]),
    }


def run_check(*, cache_dir: Path | None = None, on_check=None, store: bool = True) -> dict:
    """Run the battery on the active backend, cache the verdict (unless not ``store``) and
    put it in force; returns the verdict (``key``, ``passed``, ``failed``, ``checks``)."""
    from .battery import run_battery

    variant = backend.active().variant
    key = machine_key(variant)
    t0 = time.perf_counter()
    checks = run_battery(on_check=on_check)
    verdict = {
        "key": key,
        "passed": all(c.passed for c in checks),
        "failed": [c.name for c in checks if not c.passed],
        "checks": [c.to_json() for c in checks],
        "seconds": round(time.perf_counter() - t0, 2),
        "checked_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    if store:
        path = verdict_path(key, cache_dir)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_json(path, verdict)
        except OSError as exc:
            print(
                f"raster-oracle: warning: the self-check verdict cannot be cached at {path} "
                f"({type(exc).__name__}); it holds for this run only",
                file=sys.stderr,
            )
    backend.set_self_check(summary(verdict))
    return verdict


def _verdict_of_active(cache_dir, announce) -> dict:
    """The verdict summary of the active backend: in force in this process, else cached,
    else from a fresh run of the battery (announced on stderr: it takes a while)."""
    variant = backend.active().variant
    held = backend.self_check()
    if held is not None and held.get("variant") == variant and held["status"] != "trusted":
        return held
    verdict = cached_verdict(variant, cache_dir=cache_dir)
    if verdict is None:
        if announce:
            print(
                f"raster-oracle: checking backend {variant} on this machine "
                "(once; the verdict is cached)",
                file=sys.stderr,
            )
        verdict = run_check(cache_dir=cache_dir)
    backend.set_self_check(summary(verdict))
    return backend.self_check()


def _trusted(cache_dir) -> None:
    variant = backend.active().variant
    verdict = cached_verdict(variant, cache_dir=cache_dir)
    if verdict is None:
        backend.set_self_check(
            {"status": "trusted", "variant": variant, "failed": [], "checked_at": None}
        )
    else:
        backend.set_self_check(summary(verdict, status="trusted"))


def certified_select(
    requested: str | None = None,
    *,
    trust: bool = False,
    cache_dir: Path | None = None,
    announce: bool = True,
    env: dict | None = None,
):
    """Select a backend that passed its self-check here (see the module docstring).

    Returns the :class:`scenes.backend.BackendInfo` in use.

    Raises
    ------
    BackendRefused
        The requested backend (or, for ``auto``, every candidate) failed its self-check and
        ``trust`` is false; the message names the failed checks.
    scenes.backend.BackendError
        The requested backend cannot run at all.
    """
    env = os.environ if env is None else env
    requested = requested or env.get("RASTER_ORACLE_BACKEND") or "auto"
    trust = trust or env.get("RASTER_ORACLE_TRUST_BACKEND") == "1"
    if requested != "auto":
        info = backend.select(requested, env=env)
        if trust:
            _trusted(cache_dir)
            return info
        held = _verdict_of_active(cache_dir, announce)
        if held["status"] != "passed":
            raise BackendRefused(
                f"backend {info.variant} failed its self-check on this machine "
                f"({', '.join(held['failed'])}); `raster-oracle doctor --check` shows the "
                "figures, --trust-backend uses it anyway"
            )
        return info
    failures = []
    for variant, _reason in backend.auto_variants(env=env):  # at most three
        info = backend.select(variant, env=env, replace=True)
        if trust:
            _trusted(cache_dir)
            return info
        held = _verdict_of_active(cache_dir, announce)
        if held["status"] == "passed":
            if failures:
                failed = "; ".join(f"{v}: {', '.join(names)}" for v, names in failures)
                print(
                    f"raster-oracle: warning: self-check failed on this machine ({failed}); "
                    f"using {variant}",
                    file=sys.stderr,
                )
            return info
        failures.append((variant, held["failed"]))
    failed = "; ".join(f"{v} ({', '.join(names)})" for v, names in failures)
    raise BackendRefused(
        f"no backend passed its self-check on this machine: {failed}; "
        "`raster-oracle doctor --check` shows the figures, --trust-backend uses one anyway"
    )
