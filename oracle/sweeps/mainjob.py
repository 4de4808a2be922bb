"""The main job (``raster-oracle main``, ``bin/main.sh``): the built-in default sweep with the
extremes, the claims and the other studies run on its workers beside its cases, and one report.

1. The sweep of ``oracle/specs/default.toml`` (package data): every registered technique on
   the built-in scenes at 640x360, a few settings each, run on a local Dask cluster into
   ``OUT/sweep.db`` (resumable: a second run skips finished cases).
2. The claims and the extremes matrix (:mod:`oracle.studies.claims.run`,
   :mod:`oracle.studies.extremes.run`, in their quick form), writing ``OUT/claims.json``
   and ``OUT/extremes.json`` (+ their pages), the anti-aliasing memory table
   (:mod:`oracle.studies.aa_memory`), the SMAA ranking from the sweep's rows
   (:mod:`oracle.studies.aa_ranking`) and the soft-shadow study (:mod:`oracle.studies.
   soft_shadows`, quick: PCSS against fixed-width PCF on the area-light truth, contact
   hardening, moment-map light bleeding) and the alpha-tested foliage study
   (:mod:`oracle.studies.alpha_coverage`): :data:`SECTIONS`. Their parts (a claim, an
   extreme, a whole study) are side tasks of the sweep (:func:`section_tasks`), so they fill
   the workers' idle time instead of running after the sweep on one core;
   :func:`sections_from` merges their records, writes the studies' files and prints their
   lines in page order once the sweep is done.
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
from dataclasses import dataclass
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
from ..studies.claims.run import CLAIMS, claim_line, merge_claims, run_claims
from ..studies.extremes.run import EXTREMES, extreme_line, merge_extremes, run_extremes
from ..studies.output import write_study
from ..studies.soft_shadows import run_soft_shadows
from .run import SideTask
from .store import SweepStore

__all__ = [
    "DEFAULT_SPEC",
    "SECTIONS",
    "Section",
    "default_spec",
    "run_main",
    "section_tasks",
    "sections_from",
    "timing_record",
]

#: The main job's sweep spec (package data).
DEFAULT_SPEC = "specs/default.toml"


@dataclass(frozen=True)
class Section:
    """A section of the main job's report after the sweep, and how its study runs.

    ``parts(quick)`` lists the study's parts, ``(study, kwargs)`` each: a worker of the
    sweep runs ``study(cache=..., **kwargs)`` beside the cases (:class:`oracle.sweeps.run.
    SideTask`), so the sections cost no wall time of their own on a busy cluster; ``merge``
    makes the study's record of its parts' records (in ``parts`` order), ``lines`` what the
    job prints of it, ``file`` ``(name, title)`` of the study's page and JSON beside the
    report (None: none), ``section(data, section_id=, title=)`` its section record.
    ``parts`` None: the study reads the sweep's store, ``local(out)`` runs it after the
    sweep in this process.
    """

    kind: str
    sid: str
    title: str
    section: Callable[..., dict]
    parts: Callable[[bool], list[tuple[Callable[..., dict], dict]]] | None = None
    merge: Callable[[list[dict]], dict] | None = None
    lines: Callable[[dict], list[str]] | None = None
    file: tuple[str, str] | None = None
    local: Callable[[Path], dict] | None = None


def _whole(study: Callable[..., dict]):
    """``parts`` of a study run whole: one part, ``study(out=None, cache=, quick=)``."""

    def parts(quick: bool) -> list[tuple[Callable[..., dict], dict]]:
        return [(study, {"out": None, "quick": quick})]

    return parts


def _claims_parts(quick: bool) -> list[tuple[Callable[..., dict], dict]]:
    return [(run_claims, {"out": None, "quick": quick, "only": [c.id]}) for c in CLAIMS]


def _extremes_parts(quick: bool) -> list[tuple[Callable[..., dict], dict]]:
    return [(run_extremes, {"out": None, "quick": quick, "extremes": [n]}) for n in EXTREMES]


def _claims_lines(data: dict) -> list[str]:
    return [claim_line(row) for row in data["claims"]]


def _extremes_lines(data: dict) -> list[str]:
    cells = data["cells"]
    return [extreme_line(n, [c for c in cells if c["extreme"] == n]) for n in data["extremes"]]


def alpha_foliage_study(*, cache=None, out=None, quick: bool = True) -> dict:
    """The alpha-tested foliage study as a part (it reads no reference cache)."""
    return run_alpha_foliage(out, quick=quick)


def soft_shadows_study(*, cache=None, out=None, quick: bool = True) -> dict:
    """The soft-shadow study as a part."""
    return run_soft_shadows(out, cache=cache, quick=quick)


def aa_memory_study(*, cache=None, out=None, quick: bool = True) -> dict:
    """The anti-aliasing memory table as a part (arithmetic: no cache, no size)."""
    return memory_report()


def _aa_ranking(out: Path) -> dict:
    db, rows = out / "sweep.db", []
    if db.is_file():
        with SweepStore(db, readonly=True) as store:
            rows = store.rows()
    return aa_ranking(rows)


def _split(kind: str, title: str, section, parts, merge, lines, page: str) -> Section:
    """A study measured in parts (one side task each), merged into one record and page."""
    return Section(kind, kind, title, section, parts, merge, lines, file=(kind, page))


def _one(kind: str, title: str, section, study, *, page: bool = False) -> Section:
    """A study run whole as one side task; ``page``: its page and JSON beside the report."""
    file = (kind, title) if page else None
    return Section(kind, kind.replace("_", "-"), title, section, _whole(study), file=file)


#: The report's sections after the sweep, in page order.
SECTIONS: tuple[Section, ...] = (
    _split("claims", "Claims", claims_section, _claims_parts, merge_claims, _claims_lines,
           "raster-oracle claims"),
    _split("extremes", "Numerical stability at the extremes", extremes_section, _extremes_parts,
           merge_extremes, _extremes_lines, "raster-oracle extremes"),
    _one("aa_memory", "Anti-aliasing memory", aa_memory_section, aa_memory_study),
    Section("aa_ranking", "aa-ranking", "Anti-aliasing ranking", aa_ranking_section,
            local=_aa_ranking),
    _one("soft_shadows", "Soft shadows", soft_shadows_section, soft_shadows_study, page=True),
    _one("alpha_foliage", "Alpha-tested foliage", alpha_foliage_section, alpha_foliage_study,
         page=True),
)  # fmt: skip


def section_tasks(sections, *, quick: bool) -> list[SideTask]:
    """The sweep's side tasks that run the parts of ``sections``, named ``"KIND/INDEX"``."""
    tasks = []
    for sec in sections:
        if sec.parts is None:
            continue
        for i, (study, kwargs) in enumerate(sec.parts(quick)):
            tasks.append(SideTask(f"{sec.kind}/{i}", study, kwargs))
    return tasks


def sections_from(
    sections, side: dict, out: Path, *, quick: bool, echo=print, phases=None
) -> tuple[list[dict], list[str]]:
    """The section records of ``sections`` from the side tasks' results ``side`` (the sweep
    summary's, :func:`section_tasks` names), writing each study's files into ``out``; the
    ids of those that failed.

    A study a part of which failed is reported, not fatal: its record is a failed section
    (the page shows the error in its place), its id is in the returned list (the main job
    then exits with status 1) and ``echo`` says so. ``phases``: each study's seconds (its
    parts' worker seconds, summed) are added under its kind.
    """
    records, failed = [], []
    for sec in sections:
        try:
            data = _section_data(sec, side, out, quick=quick, echo=echo, phases=phases)
            record = sec.section(data, section_id=sec.sid, title=sec.title)
        except Exception as exc:  # in the page and in the exit status, not fatal
            error = str(exc) if isinstance(exc, SectionError) else one_line(exc, with_type=True)
            record = failed_section(kind=sec.kind, section_id=sec.sid, title=sec.title, error=error)
            echo(f"{sec.sid}: failed: {record['error']}")
            failed.append(sec.sid)
        records.append(record)
    return records, failed


class SectionError(RuntimeError):
    """A part of a section's study failed on a worker (its error, as the worker wrote it)."""


def _section_data(sec: Section, side: dict, out: Path, *, quick, echo, phases) -> dict:
    if sec.parts is None:
        with maybe_phase(phases, sec.kind):
            return sec.local(out)
    results = [side.get(f"{sec.kind}/{i}") for i in range(len(sec.parts(quick)))]
    if phases is not None:
        phases.add(sec.kind, sum(float(r.get("seconds") or 0.0) for r in results if r))
    missing = [i for i, r in enumerate(results) if r is None]
    if missing:
        raise SectionError(f"{len(missing)} part(s) did not run")
    broken = [r["error"] for r in results if r["error"] is not None]
    if broken:
        raise SectionError(broken[0])
    datas = [r["value"] for r in results]
    data = sec.merge(datas) if sec.merge is not None else datas[0]
    for line in sec.lines(data) if sec.lines is not None else ():
        echo(line)
    if sec.file is not None:
        name, title = sec.file
        write_study(out, name=name, data=data, section=sec.section(data), title=title)
    return data


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
        expansion,
        db,
        cache_root=cache.root,
        workers=workers,
        quiet=quiet,
        echo=echo,
        side=section_tasks(SECTIONS, quick=quick),
    )
    echo(
        f"sweep {expansion.name}: {summary['cases']} cases ({summary['skipped_done']} already "
        f"done, {summary['done']} done, {summary['failed']} failed) in "
        f"{summary['wall_seconds']:.1f} s: {db}"
    )
    failed = [f"{summary['failed']} sweep case(s)"] if summary["failed"] else []
    phases.merge(summary["phases"])
    # the sections' parts ran inside the sweep (beside its cases): their seconds are theirs
    side_seconds = sum(float(r.get("seconds") or 0.0) for r in summary["side"].values())
    rest = summary["wall_seconds"] - sum(summary["phases"].values()) - side_seconds
    phases.add("sweep", max(0.0, rest))
    sections, failed_sections = sections_from(
        SECTIONS, summary["side"], out, quick=quick, echo=echo, phases=phases
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
    store), then each study (``claims``, ``extremes``, ``aa_memory``, ``aa_ranking``,
    ``soft_shadows``, ``alpha_foliage``) and ``report`` (writing the page). The sweep's
    phases and the studies' (their parts ran beside the cases) are wall seconds in this
    process when it ran inline (``workers=0``), else seconds summed over the Dask workers
    (they can add up to more than the wall time); ``sweep`` is then what is left of the
    sweep's wall time, if anything.
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
