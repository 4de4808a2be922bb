"""The library function that scores a folder's cases (:func:`score_folder`; the command line
only builds the cases, from the folder's layout (:mod:`oracle.scoring.inputs.folder_layout`) or
a manifest).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...scenes.base.files import atomic_write_json
from ..errors import InputError
from .ci.checks import FOLDER_SCHEMA
from .options import ScoreOptions
from .result import ScoreError

__all__ = ["FolderCase", "FolderRun", "score_folder"]


@dataclass(frozen=True)
class FolderCase:
    """One case of a folder run, checked and ready: written to ``OUT/<name>/``.

    ``loaded`` (the scene), ``pattern`` (the candidate file or ``{frame}`` pattern),
    ``channel`` and ``layout`` (what to read), ``options`` (:class:`ScoreOptions`),
    ``gates``; or ``error``: why this case cannot be scored (a missing file or layer: a
    JUnit error case while the others are scored)."""

    name: str
    scene: str
    loaded: object = None
    pattern: str | None = None
    channel: str | None = None
    layout: object = None
    options: ScoreOptions = field(default_factory=ScoreOptions)
    gates: tuple = ()
    error: str | None = None
    #: the manifest's baseline metrics and tolerances (``metrics``, ``tolerances``) or None
    baseline: dict | None = None


@dataclass
class FolderRun:
    """What :func:`score_folder` did: one verdict per case and the combined record."""

    verdicts: list = field(default_factory=list)
    record: dict = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        """1 when a case failed a check or could not be scored, else 0."""
        return 1 if any(v.failed or v.errors for v in self.verdicts) else 0


def case_baseline_options(case: FolderCase, given):
    """A case's baseline options: the caller's, else the manifest's, with the case's gated
    metrics where neither names the metrics."""
    from .ci.regression import BaselineOptions

    mine = case.baseline or {}
    if given is None:  # the API without baseline options: the manifest's, else the default
        given = BaselineOptions(mine.get("metrics"), dict(mine.get("tolerances") or {}))
    elif mine:
        tolerances = {**(mine.get("tolerances") or {}), **given.tolerances}
        metrics = given.metrics if given.metrics is not None else mine.get("metrics")
        given = BaselineOptions(metrics, tolerances, given.strict)
    return given.for_gates(case.gates)


def _missing_and_new(cases, baselines, source: str, strict: bool):
    """Cases of the baseline missing from this run and cases new in it: a note each, or
    with ``strict`` a failing check each (and an error verdict for a missing one)."""
    from .ci.checks import Check, Verdict

    names = [c.name for c in cases]
    missing = [k for k in baselines if k not in names]
    new = [n for n in names if n not in baselines]
    extra = []
    for name in missing:
        line = f"{'FAIL' if strict else 'NOTE'} baseline case {name}: in {source}, not in this run"
        v = Verdict(scene=name)
        v.add([Check(f"baseline case {name}", "case", False, line, "baseline")] if strict else ())
        v.add(notes=[] if strict else [line])
        extra.append(v)
    return missing, new, extra


def check_candidates(cases) -> None:
    """Every case's candidate frames read and checked (size, NaN, range, by kind) before the
    first case is scored: a bad value in a later case is one line naming the case, and no
    reference is rendered nor any case scored first (issue 48)."""
    from .inputs.frames import frame_file
    from .inputs.layout import read_candidate

    for case in cases:
        if case.error is not None or case.pattern is None or case.layout is None:
            continue
        shape = (case.loaded.height, case.loaded.width)
        transfer = case.options.transfer or "srgb"
        for k in range(case.options.frames or 1):
            path = frame_file(case.pattern, k)
            try:
                read_candidate(path, case.layout, expected_shape=shape, transfer=transfer)
            except InputError as exc:
                raise type(exc)(f"case {case.name}: {exc}") from None


def score_folder(
    cases,
    *,
    out,
    cache=None,
    baselines: dict | None = None,
    baseline_source: str = "baseline",
    baseline_options=None,
    root: str = "",
    title: str = "engine images",
) -> FolderRun:
    """Score every case into ``out/<name>/``, then write ``out/metrics.json`` (schema
    ``raster-oracle/score-folder/1``: every case's record under ``scenes``, ``failed`` case
    -> failed check names, ``errors`` case -> message, ``baseline`` the missing and new
    cases, ``exit_code``) and ``out/report.html``.

    A case with ``error`` is not scored: its verdict holds the error (JUnit ``<error>``).
    ``baselines``: case name -> a previous run's record of it; ``baseline_options``
    (:class:`oracle.scoring.ci.regression.BaselineOptions`, None: each case's manifest's or the
    default): the metrics compared and their tolerances, and ``strict``: a case of the
    baseline missing from this run, or new in it, fails (else a note names it).
    """
    from .ci.checks import Verdict
    from .combine import combine_reports
    from .inputs.out_names import case_folder
    from .request import ScoreRequest
    from .to_folder import score_to_folder

    out = Path(out)
    for case in cases:  # every case's folder a folder name under out, before anything is written
        case_folder(out, case.name, error=ScoreError)
    check_candidates(cases)
    combined = {"schema": FOLDER_SCHEMA, "root": root, "scenes": {}, "failed": {}, "errors": {}}
    run = FolderRun(record=combined)
    strict = bool(baseline_options is not None and baseline_options.strict)
    scored = []
    for case in cases:
        if case.error is not None:
            verdict = Verdict(scene=case.name).add_error(f"{case.name} scored", case.error)
            combined["errors"][case.name] = case.error
            run.verdicts.append(verdict)
            continue
        baseline = (baselines or {}).get(case.name)
        folder = case_folder(out, case.name, error=ScoreError)
        try:
            request = ScoreRequest.for_files(
                case.loaded,
                case.pattern,
                channel=case.channel,
                layout=case.layout,
                options=case.options,
                cache=cache,
            )
            verdict, record = score_to_folder(
                request,
                out=folder,
                gates=list(case.gates),
                baseline=baseline,
                baseline_source=f"{baseline_source} scene {case.name}",
                name=case.name,
                baseline_options=case_baseline_options(case, baseline_options),
            )
        except InputError as exc:  # a gate, option or file that does not fit this case: named
            raise type(exc)(f"case {case.name}: {exc}") from None
        verdict.scene = case.name
        if baselines is not None and baseline is None:
            from .ci.checks import Check

            line = f"baseline: new case {case.name}, not in {baseline_source}"
            line = f"{'FAIL' if strict else 'NOTE'} {line}"
            if strict:
                verdict.add([Check(f"baseline case {case.name}", "case", False, line, "baseline")])
            else:
                verdict.add(notes=[line])
        run.verdicts.append(verdict)
        record = dict(record, folder=case.name)
        combined["scenes"][case.name] = record
        if verdict.failed:
            combined["failed"][case.name] = list(verdict.failed)
        scored.append(folder)
    if baselines is not None:
        missing, new, extra = _missing_and_new(cases, baselines, baseline_source, strict)
        combined["baseline"] = {"source": baseline_source, "missing": missing, "new": new}
        combined["baseline"]["strict"] = strict
        run.verdicts.extend(extra)
        for v in extra:
            if v.failed:
                combined["failed"][v.scene] = list(v.failed)
    combined["exit_code"] = run.exit_code
    combined["platform"] = next((c.options.platform for c in cases), None)
    errors = [
        {"case": v.scene, "name": name, "message": message}
        for v in run.verdicts
        for name, message in v.errors
    ]
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "metrics.json", combined)
    combine_reports(scored, out / "report.html", title=title, errors=errors)
    return run
