"""``raster-oracle bench scale``: content of real size (issue 35).

For each blade count ``n`` of the built-in ``meadow:n=N`` (one child process per ``n``, so
that peak memory is that size's own): wall and CPU seconds and peak resident memory of each
phase (loading, the reference's tracing without ``coverage_exact``, the Monte Carlo coverage
pass alone, ``coverage_exact`` under its budget, each model, the metrics of ``score``), and
each phase's ratio to the reference's tracing at the same ``n``.

Peak memory of a phase: the largest resident set size sampled every 20 ms while it runs
(it includes what earlier phases of the same child still hold: the loaded scene).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import contextmanager

__all__ = ["SCALE_MODELS", "SCALE_SIZES", "bench_scale", "failed_sizes", "scale_lines"]

#: Blade counts (``meadow:n=N``) of ``bench scale`` by default.
SCALE_SIZES = (10_000, 100_000, 1_000_000)
#: The models timed: those of the issue's table.
SCALE_MODELS = ("fxaa", "shadow-map", "smaa", "sdsm", "izb", "agaa", "msaa")
#: Frames of the ``taa`` row (``--only taa``): the sequence's time and its time per frame.
TAA_FRAMES = 8


@contextmanager
def _measure(phases: dict, name: str):
    """Time the block as phase ``name`` (wall, CPU) and sample its peak resident memory."""
    import psutil

    proc = psutil.Process()
    peak = [proc.memory_info().rss]
    stop = threading.Event()

    def sample():
        while not stop.wait(0.02):
            peak[0] = max(peak[0], proc.memory_info().rss)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        stop.set()
        sampler.join()
        peak[0] = max(peak[0], proc.memory_info().rss)
        phases[name] = {"seconds": wall, "cpu_seconds": cpu, "peak_gb": peak[0] / 2**30}


def _one(n: int, width: int, height: int, spp: int, models: tuple, budget: float) -> dict:
    """Every phase of ``meadow:n=n`` in this process."""
    import numpy as np

    from ... import raster_models, scenes
    from ..reference.cache import ReferenceCache
    from ..reference.coverage import exact_channels
    from ..reference.render import ALL_CHANNELS, ReferenceSettings, render_reference
    from ..reference.store import get_reference
    from ..scoring.options import ScoreOptions
    from ..scoring.request import ScoreRequest
    from ..scoring.score import REFERENCE_GROUPS, score

    phases: dict = {}
    with _measure(phases, "loading"):
        loaded = scenes.load(f"meadow:n={n}", width=width, height=height)
    groups = tuple(g for g in ALL_CHANNELS if g != "coverage_exact")
    with _measure(phases, "tracing"):
        channels, stats = render_reference(
            loaded, ReferenceSettings(spp=spp, channels=groups), quiet=True
        )
    with _measure(phases, "coverage_mc"):
        render_reference(loaded, ReferenceSettings(spp=spp, channels=("coverage",)), quiet=True)
    with _measure(phases, "coverage_exact"):
        _, record = exact_channels(loaded, None, channels, budget=budget)
    exact = {k: record.get(k) for k in ("decision", "estimate", "method", "valid_fraction")}
    outputs = {}
    for technique in models:
        if technique == "taa":  # a sequence: frames 0..7 of a sub-pixel pan, timed per frame
            with _measure(phases, "taa"):
                last = loaded.with_frame(TAA_FRAMES - 1, path="subpixel-pan", n_frames=TAA_FRAMES)
                raster_models.run("taa", last)
            phases["taa per frame"] = {
                **phases["taa"],
                "seconds": phases["taa"]["seconds"] / TAA_FRAMES,
                "cpu_seconds": phases["taa"]["cpu_seconds"] / TAA_FRAMES,
            }
            continue
        with _measure(phases, technique):
            outputs[technique] = raster_models.run(technique, loaded).outputs
    colour = next((outputs[t]["color"] for t in models if "color" in outputs[t]), None)
    if colour is not None:
        with tempfile.TemporaryDirectory() as tmp:
            cache = ReferenceCache(tmp)
            for seed in (0, 1):  # the reference and the noise floor's, cached beforehand
                groups = REFERENCE_GROUPS["color"]
                settings = ReferenceSettings(spp=spp, seed=seed, channels=groups)
                get_reference(loaded, settings, cache=cache, quiet=True)
            with _measure(phases, "metrics"):
                image = np.asarray(colour, np.float32)
                score(
                    ScoreRequest(
                        loaded,
                        "color",
                        lambda _s, _k: (image, {}),
                        options=ScoreOptions(spp=spp),
                        cache=cache,
                    )
                )
    trace = phases["tracing"]["seconds"]
    for rec in phases.values():
        rec["ratio_to_tracing"] = rec["seconds"] / trace if trace > 0 else None
    return {
        "scene": loaded.name,
        "triangles": int(n) + 2,
        "phases": phases,
        "coverage_exact": exact,
        "exact_over_mc": phases["coverage_exact"]["seconds"] / phases["coverage_mc"]["seconds"],
        "reference_wall_seconds": stats.get("wall_seconds"),
    }


def bench_scale(
    *,
    sizes=SCALE_SIZES,
    width: int = 640,
    height: int = 360,
    spp: int = 16,
    models=SCALE_MODELS,
    budget: float | None = None,
    quiet: bool = True,
) -> dict:
    """The figures of every size, each measured in its own child process."""
    from ...scenes import backend
    from ..reference.render import EXACT_BUDGET_S

    budget = EXACT_BUDGET_S if budget is None else float(budget)
    variant = backend.active().variant
    out = {"resolution": [width, height], "spp": spp, "exact_budget": budget, "sizes": {}}
    for n in sizes:
        args = json.dumps([int(n), width, height, spp, list(models), budget, variant])
        code = f"import json,sys; from {__name__} import _child; _child({args!r})"
        returncode, stdout, stderr = _run_child([sys.executable, "-c", code])
        if returncode != 0:
            tail = (stderr.strip().splitlines() or ["?"])[-1]
            out["sizes"][str(n)] = {"error": f"exit {returncode}: {tail}"}
        else:
            out["sizes"][str(n)] = json.loads(stdout.strip().splitlines()[-1])
        if not quiet:
            one = {**out, "sizes": {str(n): out["sizes"][str(n)]}}
            print("\n".join(scale_lines(one)), file=sys.stderr)
    return out


def _die_with_parent() -> None:  # pragma: no cover - runs in the child before exec
    """Linux: the child gets SIGKILL when its parent dies (even by ``kill -9``)."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, 9)  # PR_SET_PDEATHSIG, SIGKILL
    except (OSError, AttributeError):
        pass


def _run_child(argv: list[str]) -> tuple[int, str, str]:
    """Run a size's child: ``(exit status, stdout, stderr)``. The child dies with this
    process: killed when this one is stopped (SIGTERM, SIGINT unwind here) and, on Linux,
    by the kernel when this one is killed outright."""
    proc = subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None,
    )
    try:
        stdout, stderr = proc.communicate()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, stdout, stderr


def failed_sizes(figures: dict) -> list[str]:
    """The sizes of ``figures`` whose child failed."""
    return [n for n, rec in figures["sizes"].items() if "error" in rec]


def _child(args: str) -> None:
    """Entry point of a size's child process: its figures as one JSON line."""
    n, width, height, spp, models, budget, variant = json.loads(args)
    from ...scenes import backend

    backend.select(variant)  # the parent's, already certified
    figures = _one(n, width, height, spp, tuple(models), budget)
    print(json.dumps(figures))


def scale_lines(figures: dict) -> list[str]:
    """A table per size: phase, seconds, CPU seconds, peak GB, ratio to the tracing."""
    lines = []
    for n, rec in figures["sizes"].items():
        if "error" in rec:
            lines.append(f"meadow:n={n}: {rec['error']}")
            continue
        ex = rec["coverage_exact"]
        lines.append(
            f"meadow:n={n} ({figures['resolution'][0]}x{figures['resolution'][1]}, "
            f"{figures['spp']} spp): coverage_exact {ex.get('decision')}, "
            f"{rec['exact_over_mc']:.1f}x the Monte Carlo coverage pass"
        )
        lines.append(f"  {'phase':<16}{'wall s':>9}{'cpu s':>9}{'peak GB':>9}{'/tracing':>10}")
        for name, p in rec["phases"].items():
            lines.append(
                f"  {name:<16}{p['seconds']:9.2f}{p['cpu_seconds']:9.2f}{p['peak_gb']:9.2f}"
                f"{p['ratio_to_tracing']:10.2f}"
            )
    return lines
