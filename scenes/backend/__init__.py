"""Mitsuba variant selection and libLLVM discovery.

Dr.Jit's LLVM backend needs libLLVM >= 16: Debian's default LLVM 15 aborts the process
("LLVM ERROR: Cannot select ... fminimum"). This module finds a usable libLLVM, sets
``DRJIT_LIBLLVM_PATH`` *before* Dr.Jit is imported, and picks the Mitsuba variant:

1. ``cuda_ad_rgb`` when a CUDA device works,
2. else ``llvm_ad_rgb`` with a libLLVM >= 16,
3. else ``scalar_rgb`` with a warning that it is slow.

``--backend`` on the command line and the ``RASTER_ORACLE_BACKEND`` environment variable
override the choice. Nothing here imports Mitsuba or Dr.Jit at module import time.

The command line trusts a backend only after its self-check passed on this machine
(``oracle.certify``: ``auto`` falls back from a failing ``cuda_ad_rgb`` to ``llvm_ad_rgb``);
this module keeps the verdict in force (:func:`self_check`) and names the machine
(:func:`device_info`) for every result's provenance.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

from ..base.records import package_versions

__all__ = [
    "BackendError",
    "BackendInfo",
    "cuda_works",
    "INSTALL_HINT",
    "MIN_LLVM_VERSION",
    "VARIANTS",
    "active",
    "auto_variants",
    "device_info",
    "exact_arithmetic",
    "find_libllvm",
    "keep_freed_memory",
    "llvm_version_of",
    "mitsuba",
    "provenance",
    "select",
    "self_check",
    "set_self_check",
]

MIN_LLVM_VERSION = 16
VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
INSTALL_HINT = "apt-get install -y libllvm19"
DEFAULT_LIBRARY_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/opt/homebrew/opt/llvm/lib",
    "/usr/local/opt/llvm/lib",
)
_LLVM_NAME = re.compile(r"^libLLVM(?:-(\d+)(?:[.\d]*)?)?\.(?:so|dylib)(?:\.(\d+)[.\d]*)?$")


class BackendError(RuntimeError):
    """No usable Mitsuba variant, or a variant that was asked for cannot run."""


@dataclass(frozen=True)
class BackendInfo:
    """The backend in use: Mitsuba variant and the libLLVM Dr.Jit loaded (if any)."""

    variant: str
    libllvm: str | None
    reason: str


def llvm_version_of(path: str | os.PathLike) -> int | None:
    """Major LLVM version encoded in a library file name, or None if it is not libLLVM.

    ``libLLVM-19.so`` -> 19, ``libLLVM.so.19.1`` -> 19, ``libLLVM-15.so.1`` -> 15,
    ``libLLVM.so`` -> None (unversioned: unknown).
    """
    m = _LLVM_NAME.match(Path(path).name)
    if not m:
        return None
    major = m.group(1) or m.group(2)
    return int(major) if major else None


def find_libllvm(
    *, search_dirs: tuple[str, ...] | list[str] | None = None, env: dict | None = None
) -> str | None:
    """Path of a libLLVM usable by Dr.Jit, or None.

    ``DRJIT_LIBLLVM_PATH`` in ``env`` wins when it names an existing file. Otherwise the
    newest ``libLLVM*.so*`` of major version >= ``MIN_LLVM_VERSION`` in ``search_dirs``
    (default: the usual system library folders) is returned; among files of the same
    version the shortest name (the canonical one) is preferred.
    """
    env = os.environ if env is None else env
    explicit = env.get("DRJIT_LIBLLVM_PATH")
    if explicit and Path(explicit).is_file():
        return explicit
    dirs = DEFAULT_LIBRARY_DIRS if search_dirs is None else search_dirs
    best: tuple[int, int, str] | None = None
    for folder in dirs:
        p = Path(folder)
        if not p.is_dir():
            continue
        for f in sorted(p.glob("libLLVM*")):
            version = llvm_version_of(f)
            if version is None or version < MIN_LLVM_VERSION or not f.exists():
                continue
            key = (version, -len(f.name), str(f))
            if best is None or key[:2] > best[:2]:
                best = key
    return best[2] if best else None


def cuda_works() -> bool:
    """True when a CUDA driver and at least one device are present."""
    import ctypes

    for name in ("libcuda.so.1", "libcuda.so"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        if lib.cuInit(0) != 0:
            return False
        count = ctypes.c_int(0)
        return lib.cuDeviceGetCount(ctypes.byref(count)) == 0 and count.value > 0
    return False


_ACTIVE: BackendInfo | None = None
#: The self-check verdict of the active backend (None: not checked in this process).
_SELF_CHECK: dict | None = None


def auto_variants(*, env: dict | None = None) -> list[tuple[str, str]]:
    """The variants ``auto`` may use here, best first, with the reason for each:
    ``cuda_ad_rgb`` when a CUDA device works, ``llvm_ad_rgb`` with a libLLVM >= 16, and
    ``scalar_rgb`` only when neither is available."""
    libllvm = find_libllvm(env=env)
    out = []
    if cuda_works():
        out.append(("cuda_ad_rgb", "a CUDA device is present"))
    if libllvm:
        out.append(("llvm_ad_rgb", f"libLLVM found at {libllvm}"))
    if not out:
        out.append(("scalar_rgb", "no CUDA device and no libLLVM >= 16"))
    return out


def select(
    requested: str | None = None, *, env: dict | None = None, replace: bool = False
) -> BackendInfo:
    """Choose the Mitsuba variant and configure Dr.Jit; idempotent.

    Parameters
    ----------
    requested : str, optional
        ``cuda_ad_rgb``, ``llvm_ad_rgb``, ``scalar_rgb`` or ``auto``; default: the
        ``RASTER_ORACLE_BACKEND`` environment variable, else ``auto``.
    replace : bool
        Switch from the active variant to another (the self-check's fallback, before any
        scene is loaded); the self-check verdict in force is dropped.

    Raises
    ------
    BackendError
        When the requested variant cannot run, with the command to install what is missing.
    """
    global _ACTIVE, _SELF_CHECK
    env = os.environ if env is None else env
    requested = requested or env.get("RASTER_ORACLE_BACKEND") or "auto"
    if requested not in (*VARIANTS, "auto"):
        raise BackendError(
            f"unknown backend {requested!r}; expected one of auto, {', '.join(VARIANTS)}"
        )
    if _ACTIVE is not None and replace and requested != _ACTIVE.variant:
        _ACTIVE, _SELF_CHECK = None, None
    if _ACTIVE is not None:
        if requested in ("auto", _ACTIVE.variant):
            return _ACTIVE
        raise BackendError(
            f"backend {_ACTIVE.variant} is already active in this process; cannot switch "
            f"to {requested}"
        )
    libllvm = find_libllvm(env=env)
    if requested == "auto":
        variant, reason = auto_variants(env=env)[0]
        if variant == "scalar_rgb":
            warnings.warn(
                "raster-oracle: no vectorized backend (no CUDA device, no libLLVM >= 16); "
                f"falling back to the slow scalar_rgb variant. Install one: {INSTALL_HINT}",
                RuntimeWarning,
                stacklevel=2,
            )
    else:
        variant, reason = requested, "requested"
        if variant == "llvm_ad_rgb" and not libllvm:
            raise BackendError(
                "backend llvm_ad_rgb needs libLLVM >= 16 and none was found; "
                f"install it with: {INSTALL_HINT}"
            )
        if variant == "cuda_ad_rgb" and not cuda_works():
            raise BackendError("backend cuda_ad_rgb needs a working CUDA device; none found")
    if libllvm:  # before Dr.Jit starts its LLVM backend (a CUDA run may fall back to it)
        os.environ["DRJIT_LIBLLVM_PATH"] = libllvm
    import mitsuba as mi

    try:
        mi.set_variant(variant)
    except (ImportError, AttributeError, RuntimeError) as exc:
        raise BackendError(f"could not activate Mitsuba variant {variant}: {exc}") from exc
    _limit_blas_threads()
    keep_freed_memory()
    exact_arithmetic(variant)
    _ACTIVE = BackendInfo(
        variant=variant, libllvm=libllvm if variant == "llvm_ad_rgb" else None, reason=reason
    )
    return _ACTIVE


def exact_arithmetic(variant: str) -> bool:
    """Dr.Jit's ``FastMath`` flag for ``variant``; returns its new value.

    On CUDA, ``FastMath`` (Dr.Jit's default) compiles float32 division, square root,
    reciprocal and reciprocal square root to PTX's approximate instructions
    (``div.approx.ftz``: up to 2 ulp); on LLVM, division and square root are IEEE either way.
    The models follow NumPy's float32 rules and decide ties on them, so CUDA runs with
    ``FastMath`` off (IEEE-rounded ``div.rn``, ``sqrt.rn``, ``rcp.rn``): AGAA's rgba16f
    clustering disagreed with NumPy on an H200 with it on, and agreed with it off. The
    LLVM backend keeps the default: turning it off there would change only its ``rsqrt``,
    and with it the bytes of every normalized vector.

    What no flag turns off: ``ptxas`` contracts a float multiply followed by an add into one
    fused multiply-add (a different rounding than NumPy's); code whose result must equal a
    NumPy rule bit for bit rounds the product explicitly
    (:func:`.kernels.product_rounder`).
    """
    import drjit as dr

    fast = not variant.startswith("cuda")
    dr.set_flag(dr.JitFlag.FastMath, fast)
    return fast


def _limit_blas_threads() -> None:
    """One BLAS thread: the models' products are ``(N, 3) @ (3, 3)`` and smaller, for which
    OpenBLAS threads only spin against Dr.Jit's own thread pool (measured on 2 cores while a
    render ran: 2M points through a 3x3 matrix took 0.53 s with 2 BLAS threads, 0.035 s
    with 1)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")


#: glibc ``mallopt`` parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Largest value glibc accepts for both: allocations up to 2 GiB come from the heap, and the
#: heap is not trimmed back to the system until 2 GiB of it are free.
_KEEP_BYTES = 2**31 - 1


def keep_freed_memory(env: dict | None = None) -> bool:
    """Keep the memory of freed NumPy arrays in the process (glibc only) instead of handing
    it back to the system after every frame.

    The models and the oracle allocate and free arrays of tens to hundreds of MB per launch;
    by default glibc maps each one afresh and unmaps it when freed, so every frame page-faults
    its memory in again. In the virtual machines this project runs on that cost varies
    several-fold with the host (``msaa`` 8x at 1080p: 0.64-1.62 s from one run to the next,
    0.57-0.71 s with this setting; peak resident memory unchanged, 1.03 GB). Raising glibc's
    mmap and trim thresholds keeps the pages mapped for reuse. ``RASTER_ORACLE_KEEP_HEAP=0``
    turns it off. Returns whether the setting was applied.
    """
    env = os.environ if env is None else env
    if env.get("RASTER_ORACLE_KEEP_HEAP", "1") == "0":
        return False
    import ctypes
    import platform

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    trim = libc.mallopt(_M_TRIM_THRESHOLD, _KEEP_BYTES)
    mmap = libc.mallopt(_M_MMAP_THRESHOLD, _KEEP_BYTES)
    return bool(trim and mmap)


def active() -> BackendInfo:
    """The active backend, selecting the default one on first use."""
    return _ACTIVE or select()


def mitsuba():
    """The ``mitsuba`` module with the selected variant active."""
    active()
    import mitsuba as mi

    return mi


def set_self_check(verdict: dict | None) -> None:
    """Record the self-check verdict of the active backend (a JSON-ready dict: ``status``
    and the failed checks; see ``oracle.certify``), or forget it (None)."""
    global _SELF_CHECK
    _SELF_CHECK = None if verdict is None else dict(verdict)


def self_check() -> dict | None:
    """The self-check verdict in force for the active backend, or None when not checked."""
    return None if _SELF_CHECK is None else dict(_SELF_CHECK)


def _cuda_device() -> dict:
    """Name of CUDA device 0 and the driver's CUDA version, through the driver API."""
    import ctypes

    out: dict = {"kind": "gpu"}
    for name in ("libcuda.so.1", "libcuda.so"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        if lib.cuInit(0) != 0:
            break
        dev, version = ctypes.c_int(0), ctypes.c_int(0)
        buf = ctypes.create_string_buffer(256)
        if lib.cuDeviceGet(ctypes.byref(dev), 0) == 0:
            if lib.cuDeviceGetName(buf, 256, dev) == 0:
                out["name"] = buf.value.decode(errors="replace")
        if lib.cuDriverGetVersion(ctypes.byref(version)) == 0:
            out["cuda_driver"] = f"{version.value // 1000}.{version.value % 1000 // 10}"
        break
    try:
        text = Path("/proc/driver/nvidia/version").read_text()
        m = re.search(r"Kernel Module\s+([\d.]+)", text)
        if m:
            out["driver"] = m.group(1)
    except OSError:
        pass
    return out


def _cpu_name() -> str:
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def device_info(variant: str | None = None) -> dict:
    """The machine a variant runs on: for ``cuda_ad_rgb`` the GPU (``name``, NVIDIA
    ``driver`` and ``cuda_driver`` versions), else the CPU (``name``, ``cores``); default:
    the active variant."""
    variant = variant or active().variant
    if variant.startswith("cuda"):
        return _cuda_device()
    return {"kind": "cpu", "name": _cpu_name(), "cores": os.cpu_count()}


def provenance() -> dict:
    """The backend (Mitsuba variant, libLLVM), the machine it runs on, its self-check
    verdict and the package versions in use: ``{"backend", "libllvm", "device",
    "self_check", "versions"}``. ``device``: ``{"kind": "gpu", "name", "driver",
    "cuda_driver"}`` or ``{"kind": "cpu", "name", "cores"}``; ``self_check``: ``{"status":
    "passed" | "failed" | "trusted" | "not run", "failed": [check names], ...}``."""
    info = active()
    return {
        "backend": info.variant,
        "libllvm": info.libllvm,
        "device": device_info(info.variant),
        "self_check": self_check() or {"status": "not run", "failed": []},
        "versions": package_versions(),
    }
