"""Where the time goes: wall seconds by named phase, Dr.Jit's kernel history of a call, and
the device a figure was measured on.

- :class:`Phases` sums the wall seconds of named phases (the main job's references, models,
  metrics, claims, extremes, report; the colour reference's trace, reductions, transfers).
  Timing a phase never synchronises by itself; a caller that profiles a Dr.Jit computation
  passes ``sync=True`` (``dr.sync_thread`` at the end of the phase), which the normal path
  never does.
- :func:`kernel_profile` runs a call with Dr.Jit's kernel history on and splits its wall time
  into device work (ray-tracing kernels, other kernels, reductions, copies), compilation and
  the host's share (Python, NumPy, waiting for transfers), with the launches that reused a
  compiled kernel (cache hits) and those that compiled one.
- :func:`device_description` names the machine: the GPU on a CUDA variant, else the CPU model
  and its cores, with the Mitsuba variant and Dr.Jit's thread count.
"""

from __future__ import annotations

import os
import subprocess
import time
from contextlib import contextmanager

__all__ = ["Phases", "device_description", "kernel_profile", "maybe_phase", "summarise_history"]


class Phases:
    """Wall seconds accumulated by phase name, in first-seen order."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def add(self, name: str, seconds: float) -> None:
        """Add ``seconds`` to phase ``name``."""
        self.seconds[name] = self.seconds.get(name, 0.0) + float(seconds)

    def merge(self, seconds: dict | None) -> None:
        """Add every phase of a ``{name: seconds}`` record (another process's, say)."""
        for name, value in (seconds or {}).items():
            self.add(name, value)

    @contextmanager
    def phase(self, name: str, *, sync: bool = False):
        """Time the block as phase ``name``; with ``sync``, wait for Dr.Jit's queued work
        (``dr.sync_thread``) before reading the clock, so asynchronous launches are counted
        in the phase that made them (profiling only: it costs a round trip)."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            if sync:
                import drjit as dr

                dr.sync_thread()
            self.add(name, time.perf_counter() - t0)

    def total(self) -> float:
        return sum(self.seconds.values())

    def record(self) -> dict[str, float]:
        """``{name: seconds}``, a copy."""
        return dict(self.seconds)

    def lines(self, *, title: str, wall: float | None = None) -> list[str]:
        """Printable lines: one per phase with its seconds and share of ``wall`` (default:
        the sum of the phases)."""
        wall = self.total() if wall is None else float(wall)
        out = [f"{title}: {wall:.2f} s"]
        for name, value in self.seconds.items():
            share = 100.0 * value / wall if wall > 0 else 0.0
            out.append(f"  {name:<12} {value:8.2f} s {share:5.1f} %")
        return out


@contextmanager
def maybe_phase(phases: Phases | None, name: str, *, sync: bool = False):
    """:meth:`Phases.phase` when ``phases`` is given, else nothing at all (no clock, no
    synchronisation): the normal path stays as it was."""
    if phases is None:
        yield
        return
    with phases.phase(name, sync=sync):
        yield


def _is_trace(entry: dict) -> bool:
    """Whether a kernel-history entry traces rays: OptiX on CUDA; on LLVM, Dr.Jit marks the
    Embree call in the kernel's IR with a ``Ray trace`` comment."""
    if entry.get("uses_optix"):
        return True
    ir = entry.get("ir")
    return ir is not None and "Ray trace" in ir.getvalue()


def summarise_history(history: list[dict]) -> dict:
    """Device seconds by kind and launch counts of a Dr.Jit kernel history.

    ``trace_seconds``: kernels that trace rays (with whatever else was fused into them, such
    as shading); ``kernel_seconds``: other compiled kernels (per-sample and per-pixel work);
    ``reduction_seconds``: reductions (``block_reduce``, ``count``, ``sum``, ...);
    ``copy_seconds``: copies and other launches; ``compile_seconds``: code generation and
    back-end compilation of the kernels that were not in the cache. ``launches``: compiled
    kernels launched, of which ``cache_hits`` reused a kernel and ``compiled`` did not.
    """
    out = {
        "trace_seconds": 0.0,
        "kernel_seconds": 0.0,
        "reduction_seconds": 0.0,
        "copy_seconds": 0.0,
        "compile_seconds": 0.0,
        "launches": 0,
        "cache_hits": 0,
        "compiled": 0,
    }
    for entry in history:
        kind = str(entry.get("type", "")).rsplit(".", 1)[-1]
        seconds = float(entry.get("execution_time", 0.0)) / 1000.0  # Dr.Jit reports ms
        if kind == "JIT":
            out["launches"] += 1
            if entry.get("cache_hit"):
                out["cache_hits"] += 1
            else:
                out["compiled"] += 1
                compile_ms = entry.get("codegen_time", 0.0) + entry.get("backend_time", 0.0)
                out["compile_seconds"] += float(compile_ms) / 1000.0
            out["trace_seconds" if _is_trace(entry) else "kernel_seconds"] += seconds
        elif "Reduce" in kind or kind in ("Aggregate", "Reduce"):
            out["reduction_seconds"] += seconds
        else:
            out["copy_seconds"] += seconds
    return out


def kernel_profile(fn, *args, **kwargs):
    """Run ``fn(*args, **kwargs)`` with Dr.Jit's kernel history on; ``(result, record)``.

    ``record``: :func:`summarise_history` of its launches, ``wall_seconds`` (synchronised
    before and after) and ``host_seconds``, the wall time not spent in device work or
    compilation: Python, NumPy and waiting for host transfers. On the LLVM backend the
    kernels run on the same cores as the host, so the device and host shares are both CPU
    time. The history flag is restored afterwards; a profiled run may be slower than a plain
    one (each launch is timed), so time figures come from plain runs and only the split from
    this one.
    """
    import drjit as dr

    was_on = dr.flag(dr.JitFlag.KernelHistory)
    dr.sync_thread()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dr.kernel_history()  # drop older entries
    try:
        t0 = time.perf_counter()
        result = fn(*args, **kwargs)
        dr.sync_thread()
        wall = time.perf_counter() - t0
        history = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, was_on)
    record = summarise_history(history)
    device = sum(record[k] for k in ("trace_seconds", "kernel_seconds", "reduction_seconds"))
    device += record["copy_seconds"] + record["compile_seconds"]
    record["wall_seconds"] = wall
    record["host_seconds"] = max(0.0, wall - device)
    return result, record


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine() or "unknown CPU"


def _gpu_name() -> str | None:
    """The first GPU's name from ``nvidia-smi`` (None when it cannot say)."""
    try:
        done = subprocess.run(
            ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    lines = [s.strip() for s in done.stdout.splitlines() if s.strip()]
    return lines[0] if done.returncode == 0 and lines else None


def device_description(variant: str) -> dict:
    """The machine a figure was measured on: ``{"variant", "kind", "name", "cores",
    "drjit_threads"}``; ``kind`` is ``"gpu"`` on a CUDA variant (``name`` the GPU's, or
    ``"CUDA device"`` when ``nvidia-smi`` cannot say), else ``"cpu"`` (``name`` the CPU
    model)."""
    import drjit as dr

    cores = os.cpu_count() or 1
    if "cuda" in variant:
        name, kind = _gpu_name() or "CUDA device", "gpu"
    else:
        name, kind = _cpu_model(), "cpu"
    return {
        "variant": variant,
        "kind": kind,
        "name": name,
        "cores": cores,
        "drjit_threads": int(dr.thread_count()),
    }
