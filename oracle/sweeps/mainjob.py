"""The main job (``raster-oracle main``, ``bin/main.sh``): the built-in default sweep, then the
extremes and the claims, and one report.

1. The sweep of ``oracle/specs/default.toml`` (package data): every registered technique on
   the built-in scenes at 640x360, a few settings each, run on a local Dask cluster into
   ``OUT/sweep.db`` (resumable: a second run skips finished cases).
2. The extremes matrix and the claims (:mod:`oracle.studies.extremes.run`,
   :mod:`oracle.studies.claims.run`, in their quick form), writing ``OUT/extremes.json``
   and ``OUT/claims.json``, and the anti-aliasing memory table
   (:mod:`oracle.studies.aa_memory`).
3. ``OUT/report.html`` (+ ``report.json``): Pareto fronts, parameter sensitivity, best at
   equal cost, the claims, the extremes, the memory table and every case.
"""

from __future__ import annotations

import importlib
import importlib.resources
import tomllib
from pathlib import Path

__all__ = ["DEFAULT_SPEC", "SECTIONS", "default_spec", "run_main"]

#: The main job's sweep spec (package data).
DEFAULT_SPEC = "specs/default.toml"

#: Report sections after the sweep: ``(id, title, run module, run function, render module,
#: render function)``. Each is run when its modules import (they are optional: written by
#: other parts of the project); a section that fails is reported in the page, not fatal.
SECTIONS = (
    (
        "claims",
        "Claims",
        "oracle.studies.claims.run",
        "run_claims",
        "reports.sections.claims",
        "render_claims",
    ),
    (
        "extremes",
        "Numerical stability at the extremes",
        "oracle.studies.extremes.run",
        "run_extremes",
        "reports.sections.extremes",
        "render_extremes",
    ),
)


def default_spec() -> dict:
    """The parsed default spec (a fresh dict each call)."""
    text = importlib.resources.files("oracle").joinpath(DEFAULT_SPEC).read_text("utf-8")
    return tomllib.loads(text)


def _restrict(data: dict, names, spp: int | None, size) -> dict:
    """The spec restricted to ``names`` (None: all its scenes), with ``spp``/``size`` set."""
    from .spec import SpecError

    if spp is not None:
        data.setdefault("defaults", {})["spp"] = int(spp)
    if size is not None:
        data.setdefault("defaults", {}).update(width=int(size[0]), height=int(size[1]))
    if names is None:
        return data
    wanted = set(names)
    kept = []
    for table in data.get("case", []):
        scenes = [s for s in table.get("scenes", []) if s in wanted]
        if scenes:
            kept.append({**table, "scenes": scenes})
    if not kept:
        raise SpecError(f"no case of the default sweep runs on {', '.join(names)}")
    data["case"] = kept
    return data


def _one_line(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def _load_section(entry):
    """``(run, render)`` of a section, or None when its modules or functions are absent."""
    _, _, run_mod, run_fn, render_mod, render_fn = entry
    try:
        run = getattr(importlib.import_module(run_mod), run_fn)
        render = getattr(importlib.import_module(render_mod), render_fn)
    except (ImportError, AttributeError):
        return None
    return run, render


def _section(entry, out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict | None:
    """Run one optional section; its report record, or None when its modules are absent."""
    sid, title = entry[:2]
    found = _load_section(entry)
    if found is None:
        return None
    run, render = found
    try:
        data = run(out, cache=cache, quiet=quiet, echo=echo, quick=quick)
        html = render(data)
    except Exception as exc:  # the report still comes out; the failure is in it
        echo(f"{sid}: failed: {_one_line(exc)}")
        return {"id": sid, "title": title, "html": _failed_html(exc), "failed": True}
    return {"id": sid, "title": title, "html": html, "failed": False}


def _failed_html(exc: BaseException) -> str:
    from markupsafe import escape

    return f'<p class="note">This section failed: <code>{escape(_one_line(exc))}</code></p>'


def _memory_section(*, echo) -> dict | None:
    try:
        from reports.sections.aa_memory import render_aa_memory

        from ..studies.aa_memory import memory_report
    except ImportError:
        return None
    try:
        html = render_aa_memory(memory_report())
    except Exception as exc:
        echo(f"aa-memory: failed: {_one_line(exc)}")
        return {
            "id": "aa-memory",
            "title": "Anti-aliasing memory",
            "html": _failed_html(exc),
            "failed": True,
        }
    return {"id": "aa-memory", "title": "Anti-aliasing memory", "html": html, "failed": False}


def run_main(
    names,
    out: Path,
    *,
    spp: int | None = None,
    cache,
    quiet: bool,
    echo=print,
    workers: int | None = None,
    size: tuple[int, int] | None = None,
    quick: bool = True,
) -> tuple[Path, list[str]]:
    """Run the main job into ``out``; returns the report's path and the failed sections.

    Parameters
    ----------
    names : scenes to keep (None: every scene of the default spec).
    spp : reference samples per pixel (None: the spec's, 64).
    workers : Dask workers (None: one per core; 0: in this process).
    size : ``(width, height)`` instead of the spec's 640x360.
    quick : the extremes' and claims' quick form (the main job's time budget).
    """
    from .report import sweep_report
    from .run import run_sweep
    from .spec import expand_spec

    out = Path(out)
    data = _restrict(default_spec(), names, spp, size)
    expansion = expand_spec(data, skip_unregistered=True)
    out.mkdir(parents=True, exist_ok=True)
    db = out / "sweep.db"
    for note in expansion.skipped:
        echo(f"not applicable: {note}")
    summary = run_sweep(
        expansion, db, cache_root=cache.root, workers=workers, quiet=quiet, echo=echo
    )
    echo(
        f"sweep {expansion.name}: {summary['cases']} cases ({summary['skipped_done']} already "
        f"done, {summary['done']} done, {summary['failed']} failed) in "
        f"{summary['wall_seconds']:.1f} s: {db}"
    )
    sections, failed = [], [f"{summary['failed']} sweep case(s)"] if summary["failed"] else []
    for entry in SECTIONS:
        rec = _section(entry, out, cache=cache, quiet=quiet, echo=echo, quick=quick)
        if rec is None:
            echo(f"{entry[0]}: not available ({entry[2]} is not installed)")
            continue
        sections.append(rec)
        if rec["failed"]:
            failed.append(entry[0])
    memory = _memory_section(echo=echo)
    if memory is not None:
        sections.append(memory)
    report = out / "report.html"
    sweep_report(
        db,
        report,
        sweep=expansion.name,
        title="raster-oracle: the default sweep, claims and extremes",
        extra_sections=sections,
    )
    return report, failed
