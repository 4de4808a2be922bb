"""The main job (``raster-oracle main``, ``bin/main.sh``): the built-in default sweep, then the
extremes and the claims, and one report.

1. The sweep of ``oracle/specs/default.toml`` (package data): every registered technique on
   the built-in scenes at 640x360, a few settings each, run on a local Dask cluster into
   ``OUT/sweep.db`` (resumable: a second run skips finished cases).
2. The claims and the extremes matrix (:mod:`oracle.studies.claims.run`,
   :mod:`oracle.studies.extremes.run`, in their quick form), writing ``OUT/claims.json``
   and ``OUT/extremes.json`` (+ their pages), the anti-aliasing memory table
   (:mod:`oracle.studies.aa_memory`), the SMAA ranking from the sweep's rows
   (:mod:`oracle.studies.aa_ranking`) and the soft-shadow study (:mod:`oracle.studies.
   soft_shadows`, quick: PCSS against fixed-width PCF on the area-light truth, contact
   hardening, moment-map light bleeding): :func:`run_sections`.
3. ``OUT/report.html`` (+ ``report.json``, which holds every section record of the page):
   Pareto fronts, parameter sensitivity, best at equal cost, the claims, the extremes, the
   memory table and every case.

At the end it prints its own time by phase (:func:`timing_record`) and records it in
``OUT/timing.json`` and under ``timing`` in ``report.json``.
"""

from __future__ import annotations

import importlib.resources
import json
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

from ...reports.sections import (
    aa_memory_section,
    aa_ranking_section,
    alpha_foliage_section,
    claims_section,
    extremes_section,
    failed_section,
    soft_shadows_section,
)
from ...scenes.base.files import atomic_write_bytes, atomic_write_json
from ..errors import one_line
from ..phases import Phases, maybe_phase
from ..studies.aa_memory import memory_report
from ..studies.aa_ranking import aa_ranking
from ..studies.alpha_coverage import run_alpha_foliage
from ..studies.claims.run import run_claims
from ..studies.extremes.run import run_extremes
from ..studies.soft_shadows import run_soft_shadows
from .store import SweepStore

__all__ = ["DEFAULT_SPEC", "SECTIONS", "default_spec", "run_main", "run_sections", "timing_record"]

#: The main job's sweep spec (package data).
DEFAULT_SPEC = "specs/default.toml"


def _claims(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    return run_claims(out, cache=cache, quiet=quiet, echo=echo, quick=quick)


def _extremes(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    return run_extremes(out, cache=cache, quiet=quiet, echo=echo, quick=quick)


def _soft_shadows(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    return run_soft_shadows(out, cache=cache, quiet=quiet, quick=quick)


def _alpha_foliage(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    return run_alpha_foliage(out, quick=quick)


def _aa_memory(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    return memory_report()


def _aa_ranking(out: Path, *, cache, quiet: bool, echo, quick: bool) -> dict:
    db, rows = out / "sweep.db", []
    if db.is_file():
        with SweepStore(db, readonly=True) as store:
            rows = store.rows()
    return aa_ranking(rows)


#: The report's sections after the sweep, in page order: ``(kind, id, title, study,
#: section)``: ``study(out, *, cache, quiet, echo, quick)`` measures and returns the study's
#: record, ``section(data, section_id=, title=)`` makes its section record.
SECTIONS: tuple[tuple[str, str, str, Callable[..., dict], Callable[..., dict]], ...] = (
    ("claims", "claims", "Claims", _claims, claims_section),
    ("extremes", "extremes", "Numerical stability at the extremes", _extremes, extremes_section),
    ("aa_memory", "aa-memory", "Anti-aliasing memory", _aa_memory, aa_memory_section),
    ("aa_ranking", "aa-ranking", "Anti-aliasing ranking", _aa_ranking, aa_ranking_section),
    ("soft_shadows", "soft-shadows", "Soft shadows", _soft_shadows, soft_shadows_section),
    (
        "alpha_foliage",
        "alpha-foliage",
        "Alpha-tested foliage",
        _alpha_foliage,
        alpha_foliage_section,
    ),
)


def default_spec() -> dict:
    """The parsed default spec (a fresh dict each call)."""
    oracle_package = __package__.rpartition(".")[0]
    text = importlib.resources.files(oracle_package).joinpath(DEFAULT_SPEC).read_text("utf-8")
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


def run_sections(
    out: Path, *, cache, quiet: bool, echo=print, quick: bool = True, phases=None
) -> tuple[list[dict], list[str]]:
    """Run the studies of :data:`SECTIONS` into ``out``; their section records, and the ids
    of those that failed.

    A study that raises is reported, not fatal: its record is a failed section (the page
    shows the error in its place), its id is in the returned list (the main job then exits
    with status 1) and ``echo`` says so. Import errors are not caught: the modules are
    imported with this one. ``phases`` (:class:`oracle.phases.Phases`): each study's wall
    seconds are added under its kind.
    """
    sections, failed = [], []
    for kind, sid, title, study, section in SECTIONS:
        try:
            with maybe_phase(phases, kind):
                data = study(out, cache=cache, quiet=quiet, echo=echo, quick=quick)
                record = section(data, section_id=sid, title=title)
        except Exception as exc:  # in the page and in the exit status, not fatal
            record = failed_section(
                kind=kind, section_id=sid, title=title, error=one_line(exc, with_type=True)
            )
            echo(f"{sid}: failed: {record['error']}")
            failed.append(sid)
        sections.append(record)
    return sections, failed


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
    t_start = time.perf_counter()
    phases = Phases()
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
    failed = [f"{summary['failed']} sweep case(s)"] if summary["failed"] else []
    phases.merge(summary["phases"])
    phases.add("sweep", max(0.0, summary["wall_seconds"] - sum(summary["phases"].values())))
    sections, failed_sections = run_sections(
        out, cache=cache, quiet=quiet, echo=echo, quick=quick, phases=phases
    )
    failed += failed_sections
    report = out / "report.html"
    with phases.phase("report"):
        sweep_report(
            db,
            report,
            sweep=expansion.name,
            title="raster-oracle: the default sweep, claims and extremes",
            extra_sections=sections,
        )
    timing = timing_record(phases, time.perf_counter() - t_start, inline=workers == 0)
    timing["score_passes"] = dict(summary.get("passes") or {})
    for line in phases.lines(title="main job by phase", wall=timing["wall_seconds"]):
        echo(line)
    if workers != 0:
        echo(
            "  (references, models, metrics and images are seconds summed over the sweep's "
            "workers, so their shares can add up to more than the wall time)"
        )
    for line in pass_lines(summary.get("passes")):
        echo(line)
    atomic_write_json(out / "timing.json", timing)
    _add_timing(report.with_suffix(".json"), timing)
    return report, failed


def pass_lines(passes: dict | None) -> list[str]:
    """The sweep cases' scoring seconds by score pass (:mod:`oracle.scoring.passes`; the
    ``frames`` pass includes the model runs, whose own seconds are the ``models`` phase),
    largest first: the table that names the pass of a regression."""
    if not passes:
        return []
    table = Phases()
    for name, seconds in sorted(passes.items(), key=lambda kv: -kv[1]):
        table.add(name, seconds)
    return table.lines(title="sweep scoring by pass")


def timing_record(phases: Phases, wall: float, *, inline: bool) -> dict:
    """The main job's time record: its wall seconds and seconds by phase.

    Phases: ``references`` (rendering the sweep's references), ``models`` (the technique
    models' own runs), ``metrics`` (scoring: reading cached references, noise floors,
    metrics), ``images`` (the cases' thumbnails), ``sweep`` (the rest of the sweep: keys,
    store), then each study after it (``claims``, ``extremes``, ``aa_memory``,
    ``aa_ranking``, ``soft_shadows``) and ``report`` (writing the page). The sweep's phases
    are wall seconds in this process when it ran inline (``workers=0``), else seconds summed
    over the Dask workers (they can add up to more than the wall time); ``sweep`` is then
    what is left of the sweep's wall time, if anything.
    """
    return {
        "wall_seconds": float(wall),
        "phases": phases.record(),
        "sweep_phases": "wall seconds in this process" if inline else "worker seconds, summed",
    }


def _add_timing(path: Path, timing: dict) -> None:
    """Add the ``timing`` record to the report's JSON twin (when it was written)."""
    if not path.is_file():
        return
    record = json.loads(path.read_text("utf-8"))
    record["timing"] = timing
    text = json.dumps(record, indent=1, allow_nan=False)  # as reports.sweep writes it
    atomic_write_bytes(path, text.encode("utf-8"))
