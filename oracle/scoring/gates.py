"""CI gates of ``raster-oracle score``: thresholds, a baseline run and their JUnit XML.

A gate is ``--fail-above METRIC=V`` (passes while the value is <= V) or ``--fail-below
METRIC=V`` (passes while the value is >= V). A gate must mean something, or it would pass
silently: every rule below is an :class:`GateError` (exit 2), never a pass.

- the metric is unknown (the message lists the known ones);
- its direction makes the gate meaningless: SSIM is higher-is-better, so ``--fail-above
  ssim=0.9`` would fail good images (the message says to use ``--fail-below ssim=0.9``); an
  ``info`` metric (a technique's constant) is no score at all;
- the metric does not apply to the candidate kinds scored (a shadow metric on a colour
  candidate) or to the frame count (``flicker`` needs 2 frames);
- its value is null or NaN in this run (e.g. no receiver in view).

Judged gates give one line each, with the value, the limit and the noise floor:
``FAIL visibility_mae 0.0719 > 0.02 (noise floor 0.0011)``,
``PASS ssim 0.996 >= 0.9 (noise floor 0.9991)``.

A baseline is a previous run's ``metrics.json``. It must be one (its schema), and of the same
scene, resolution, light, candidate kind and frame count; otherwise :class:`GateError`. Each
scored metric that has a noise floor in both runs is compared with
:func:`metrics.catalog.regressed` (worse by more than both floors combined, in the metric's
bad direction) and a regression is a ``REGRESSION`` line with both values and floors.

Every gate and baseline comparison is a :class:`Check`; :func:`junit_xml` writes them as one
JUnit ``<testcase>`` each (classname: the scene, name: ``visibility_mae <= 0.02``, ``ssim >=
0.9`` or ``baseline visibility_mae``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from ...metrics import catalog
from ...scenes.base.files import atomic_write_bytes
from .result import ScoreError, metric_limit

__all__ = [
    "BaselineOptions",
    "FOLDER_SCHEMA",
    "METRICS_SCHEMA",
    "Check",
    "Gate",
    "GateError",
    "Verdict",
    "applicable_gates",
    "check_applicable",
    "check_baseline_scene",
    "compare_baseline",
    "evaluate_gates",
    "judge",
    "limit_texts",
    "junit_xml",
    "load_baseline",
    "load_folder_baseline",
    "parse_baseline_metrics",
    "parse_tolerance",
    "parse_gates",
    "scored_kinds",
    "write_junit",
]

#: ``schema`` of a ``metrics.json`` record (what ``--baseline`` accepts).
METRICS_SCHEMA = "raster-oracle/metrics/1"
#: ``schema`` of a ``score-folder`` run's combined ``metrics.json``.
FOLDER_SCHEMA = "raster-oracle/score-folder/1"
_OPTION = {"<=": "--fail-above", ">=": "--fail-below"}


class GateError(ScoreError):
    """A gate or baseline that cannot be judged (exit 2)."""


@dataclass(frozen=True)
class Gate:
    """``metric op limit`` must hold: ``op`` is ``"<="`` (``--fail-above``) or ``">="``
    (``--fail-below``)."""

    metric: str
    op: str
    limit: float
    #: where the gate was asked for, for messages (``--gate-profile edge-aware``,
    #: ``[scenes.plate.channels.shadow].fail_above``); None: ``--fail-above``/``--fail-below``
    origin: str | None = field(default=None, compare=False)
    #: a gate of a profile: skipped (with a note) on a candidate kind its metric does not
    #: apply to, since a profile is a bundle applied to what it fits
    optional: bool = field(default=False, compare=False)

    @property
    def option(self) -> str:
        return _OPTION[self.op]

    @property
    def where(self) -> str:
        """How messages name the gate's source: its origin, else its option."""
        return self.origin or self.option

    @property
    def name(self) -> str:
        """The JUnit test name, e.g. ``visibility_mae <= 0.02``."""
        return f"{self.metric} {self.op} {_limit(self.limit)}"


@dataclass(frozen=True)
class Check:
    """One judged gate or baseline comparison: ``line`` is what the CLI prints."""

    name: str
    metric: str
    passed: bool
    line: str
    kind: str = "gate"
    #: this run's value, the gate's limit (gates), this run's noise floor, and for a baseline
    #: comparison the previous run's value and noise floor
    value: float | None = None
    limit: float | None = None
    floor: float | None = None
    previous: float | None = None
    previous_floor: float | None = None

    def as_record(self) -> dict:
        """The JSON record of the check: what ``metrics.json``, the report, the JUnit
        properties and the Markdown summary show (one naming everywhere)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "metric": self.metric,
            "passed": self.passed,
            "line": self.line,
            "value": self.value,
            "limit": self.limit,
            "noise_floor": self.floor,
            "previous": self.previous,
            "previous_noise_floor": self.previous_floor,
        }


class Verdict(list):
    """Every check of one scored run of scene ``scene``: ``checks`` and ``notes``.

    As a list, a verdict holds the names of its failed checks (what ``score_to_folder``
    returned before verdicts: ``if verdict:`` means a check failed); :meth:`add` keeps the
    two in step.
    """

    def __init__(self, scene: str, checks=(), notes=()):
        super().__init__()
        self.scene = scene
        self.checks: list[Check] = []
        self.notes: list[str] = []
        #: ``(name, message)`` of each part of the scene that could not be scored (a
        #: manifest's layer missing from the file): a JUnit ``<error>`` case each
        self.errors: list[tuple[str, str]] = []
        self.add(checks, notes)

    def add(self, checks=(), notes=()) -> Verdict:
        """Append ``checks`` and ``notes``; returns the verdict."""
        self.checks.extend(checks)
        self.notes.extend(notes)
        self[:] = [c.name for c in self.checks if not c.passed]
        return self

    @property
    def failed(self) -> list[str]:
        return list(self)

    def add_error(self, name: str, message: str) -> Verdict:
        """Record a part of the scene that could not be scored (it fails the run: exit 1,
        the others scored and written all the same)."""
        self.errors.append((name, message))
        return self

    @property
    def exit_code(self) -> int:
        """0 when every check passed, 1 when one failed or a part could not be scored."""
        return 1 if self.failed or self.errors else 0

    @property
    def failed_checks(self) -> list[Check]:
        """The failed gates and regressions, in check order."""
        return [c for c in self.checks if not c.passed]

    def as_record(self) -> dict:
        """``{"exit_code", "failed": [names], "checks": [records]}``: the verdict as
        ``metrics.json`` and the report hold it."""
        return {
            "exit_code": self.exit_code,
            "failed": self.failed,
            "errors": [{"name": n, "message": m} for n, m in self.errors],
            "checks": [c.as_record() for c in self.checks],
            "notes": list(self.notes),
        }

    @property
    def lines(self) -> list[str]:
        """Every check's line (``PASS``/``FAIL``/``REGRESSION``), then the notes."""
        return [c.line for c in self.checks] + list(self.notes)


def _limit(x: float) -> str:
    """A limit as the user wrote it: ``0.02``, ``10``, ``1e-05``, ``0.123456789``."""
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


def _num(x: float, other: float | None = None) -> str:
    """``x`` with 4 significant digits, more when needed to tell it from ``other``."""
    if x is None:
        return "n/a"
    for digits in (4, 6, 9):
        text = f"{x:.{digits}g}"
        if other is None or x == other or text != f"{other:.{digits}g}":
            return text
    return repr(x)


def parse_gates(fail_above=(), fail_below=()) -> list[Gate]:
    """``--fail-above`` and ``--fail-below`` texts (``METRIC=V``) -> gates, checked against the
    metric catalogue: unknown metrics and gates against the metric's direction are
    :class:`GateError`."""
    gates = []
    for op, texts in (("<=", fail_above), (">=", fail_below)):
        for text in texts or ():
            key, limit = metric_limit(text, separator="=", option=_OPTION[op], error=GateError)
            m = catalog.CATALOG[key]
            if m.direction == "info":
                raise GateError(f"{_OPTION[op]} {key}: {key} is {m.better}; it cannot be gated")
            wrong = {"<=": "higher", ">=": "lower"}[op]
            if m.direction == wrong:
                right = _OPTION[{"<=": ">=", ">=": "<="}[op]]
                raise GateError(
                    f"{_OPTION[op]} {key}={text.partition('=')[2].strip()}: {key} is "
                    f"{m.better}: use {right} {key}={text.partition('=')[2].strip()}"
                )
            gates.append(Gate(key, op, limit))
    return gates


def scored_kinds(record: dict) -> tuple[str, ...]:
    """Candidate kinds a ``metrics.json`` record scored: its channel, plus coverage where an
    anti-aliasing model's coverage was scored beside its colour."""
    kinds = [record["channel"]]
    if record.get("coverage_reference") is not None and "coverage" not in kinds:
        kinds.append("coverage")
    return tuple(kinds)


def applicable_gates(gates, *, kinds) -> tuple[list, list[str]]:
    """``gates`` without the profile gates (``optional``) whose metric does not apply to the
    candidate ``kinds``, and a note naming each one left out."""
    kept, notes = [], []
    for g in gates:
        m = catalog.CATALOG[g.metric]
        if g.optional and not set(m.kinds) & set(kinds):
            notes.append(
                f"{g.where}: {g.metric} applies to {' and '.join(m.kinds)} candidates, not "
                f"{' and '.join(kinds)}: not judged"
            )
            continue
        kept.append(g)
    return kept, notes


def check_applicable(gates, *, kinds=None, frames: int = 1) -> None:
    """:class:`GateError` for a gate whose metric does not apply to the candidate ``kinds``
    (None: not known yet, not checked) or to ``frames`` frames."""
    for g in gates:
        m = catalog.CATALOG[g.metric]
        if kinds is not None and not set(m.kinds) & set(kinds):
            raise GateError(
                f"{g.where} {g.metric}: {g.metric} applies to {' and '.join(m.kinds)} "
                f"candidates; this run scores {' and '.join(kinds)} "
                "(--channel says what a candidate file holds)"
            )
        if frames < m.min_frames:
            raise GateError(
                f"{g.where} {g.metric}: {g.metric} needs at least {m.min_frames} frames; "
                f"this run scores {frames} (use --frames {m.min_frames} or more)"
            )


def _number(value) -> float | None:
    """A record's metric value as a float (``"nan"``/``"inf"`` as JSON stores them), None
    for null or anything that is not a number."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _value(record: dict, key: str, what: str) -> float:
    value = _number(record.get(key))
    skipped = ((record.get("temporal_aa") or {}).get("video") or {}).get("skipped")
    if value is None and key == "cvvdp_jod" and skipped:
        raise GateError(f"{what}: {skipped}")
    if value is None or not math.isfinite(value):
        raise GateError(
            f"{what}: {key} is {'null' if value is None else value} for this run "
            "(nothing to judge: e.g. no receiver or edge pixel in view)"
        )
    return value


def evaluate_gates(gates, record: dict) -> list[Check]:
    """Judge ``gates`` on a ``metrics.json`` record (applicability is checked first)."""
    frames = len(record.get("frames") or []) or 1
    check_applicable(gates, kinds=scored_kinds(record), frames=frames)
    floors = record.get("noise_floor") or {}
    checks = []
    for g in gates:
        value = _value(record, g.metric, f"{g.where} {g.metric}")
        passed = value <= g.limit if g.op == "<=" else value >= g.limit
        shown = g.op if passed else {"<=": ">", ">=": "<"}[g.op]
        floor = floors.get(g.metric)
        line = (
            f"{'PASS' if passed else 'FAIL'} {g.metric} {_num(value, g.limit)} {shown} "
            f"{_limit(g.limit)} (noise floor {_num(floor)})"
        )
        checks.append(
            Check(g.name, g.metric, passed, line, value=value, limit=g.limit, floor=floor)
        )
    return checks


def _read_record(path):
    """A record file read as untrusted input (a bounded regular file of strict JSON)."""
    from ...scenes.base.untrusted import read_json

    return read_json(path, what="--baseline", error=GateError)


def _check_record(record, where: str) -> dict:
    if not isinstance(record, dict) or record.get("schema") != METRICS_SCHEMA:
        found = record.get("schema") if isinstance(record, dict) else type(record).__name__
        hint = " (a score-folder record: give it to score-folder --baseline)"
        raise GateError(
            f"{where} is not a raster-oracle metrics.json (schema {found!r}, "
            f"expected {METRICS_SCHEMA!r}){hint if found == FOLDER_SCHEMA else ''}"
        )
    reference = record.get("reference")
    scene = reference.get("scene") if isinstance(reference, dict) else None
    if not isinstance(scene, dict) or not isinstance(record.get("channel"), str):
        raise GateError(f"{where} is a metrics record without its scene or channel")
    size = scene.get("resolution")
    if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) for v in size)):
        raise GateError(f"{where}: its scene resolution is not [width, height]")
    if not isinstance(record.get("frames"), list | type(None)):
        raise GateError(f"{where}: its frames are not a list")
    floors = record.get("noise_floor")
    if floors is not None and not isinstance(floors, dict):
        raise GateError(f"{where}: its noise_floor is not a metric -> number record")
    return record


def load_baseline(path) -> dict:
    """Read a previous run's ``metrics.json`` (or the one in the folder ``path``);
    :class:`GateError` when it is missing, not JSON, or not a raster-oracle metrics record."""
    path = Path(path)
    where = f"--baseline {path}"
    if path.is_dir():
        path = path / "metrics.json"
    return _check_record(_read_record(path), where)


def load_folder_baseline(path) -> dict[str, dict]:
    """Read a previous ``score-folder`` run's ``metrics.json`` (or the one in the folder
    ``path``): scene folder name -> that scene's metrics record. :class:`GateError` when it is
    missing, not JSON, or not a score-folder record of metrics records."""
    path = Path(path)
    where = f"--baseline {path}"
    if path.is_dir():
        path = path / "metrics.json"
    record = _read_record(path)
    if not isinstance(record, dict) or record.get("schema") != FOLDER_SCHEMA:
        found = record.get("schema") if isinstance(record, dict) else type(record).__name__
        raise GateError(
            f"{where} is not a score-folder metrics.json (schema {found!r}, "
            f"expected {FOLDER_SCHEMA!r})"
        )
    scenes = record.get("scenes")
    if not isinstance(scenes, dict):
        raise GateError(f"{where} has no scenes record")
    return {str(k): _check_record(v, f"{where} scene {k}") for k, v in scenes.items()}


def _identity(record: dict) -> dict:
    """What two runs must share to be compared: scene, resolution, light, kinds, frames."""
    scene = record["reference"]["scene"]
    return {
        "scene": scene.get("name"),
        "resolution": "x".join(str(v) for v in scene.get("resolution") or ()),
        "light": scene.get("light_index"),
        "candidate kind": " and ".join(scored_kinds(record)),
        "frames": len(record.get("frames") or []) or 1,
        "platform": record.get("platform") or "default",
    }


def _check_same_run(mine: dict, theirs: dict, source: str) -> None:
    """:class:`GateError` naming each field of ``mine`` that differs in ``theirs``."""
    diffs = [f"{k} {theirs[k]} vs {mine[k]}" for k in mine if mine[k] != theirs[k]]
    if diffs:
        raise GateError(
            f"--baseline {source} is another run: {'; '.join(diffs)} (baseline vs this run); "
            "compare runs of one scene, size, light, candidate kind, frame count and platform"
        )


def check_baseline_scene(
    baseline: dict,
    loaded,
    *,
    frames: int,
    kinds=None,
    source: str = "baseline",
    platform: str | None = None,
) -> None:
    """Before rendering: :class:`GateError` when ``baseline`` scored another scene, size, light
    or frame count than ``loaded`` with ``frames`` frames, or (``kinds`` given: the candidate
    kinds this run will score) another candidate kind."""
    theirs = _identity(baseline)
    mine = {
        "scene": loaded.name,
        "resolution": f"{loaded.width}x{loaded.height}",
        "light": loaded.light_index,
        "frames": frames,
        "platform": platform or "default",
    }
    if kinds is not None:
        mine["candidate kind"] = " and ".join(kinds)
    _check_same_run(mine, theirs, source)


@dataclass(frozen=True)
class BaselineOptions:
    """What a baseline comparison compares and allows.

    ``metrics``: the metric keys compared; ``"all"``: every scored metric with a noise floor
    in both runs; None: the default, the gated metrics (:meth:`for_gates`; all when none is
    gated). ``tolerances``: metric -> ``(t, relative)``: a regression must be worse by
    more than both floors plus ``t`` (error units) or ``t`` times the baseline's error.
    ``strict``: a case missing from this run or new in it (``score-folder``) fails.
    """

    metrics: tuple[str, ...] | str | None = None
    tolerances: dict = field(default_factory=dict)
    strict: bool = False

    @classmethod
    def gated(cls, gates, **kw) -> BaselineOptions:
        """The default: the gated metrics (every metric when no gate is given)."""
        return cls(**kw).for_gates(gates)

    def for_gates(self, gates) -> BaselineOptions:
        """These options, with the gated metrics where ``metrics`` was left to the default
        (a manifest's cases differ in their gates)."""
        if self.metrics is not None:
            return self
        keys = tuple(dict.fromkeys(g.metric for g in gates or ()))
        return BaselineOptions(keys or "all", dict(self.tolerances), self.strict)


def parse_tolerance(text: str, *, option: str = "--baseline-tolerance") -> tuple[str, tuple]:
    """``"flip_mean=0.01"`` -> ``("flip_mean", (0.01, False))``; ``"flip_mean=5%"`` ->
    ``("flip_mean", (0.05, True))``: a non-negative absolute or relative tolerance."""
    key, sep, value = str(text).partition("=")
    key, value = key.strip(), value.strip()
    relative = value.endswith("%")
    number = value[:-1].strip() if relative else value
    if not sep:
        raise GateError(f"{option} expects METRIC=VALUE or METRIC=PERCENT%, got {text!r}")
    if key not in catalog.CATALOG:
        raise GateError(
            f"{option}: unknown metric {key!r}; choose from {', '.join(catalog.CATALOG)}"
        )
    try:
        t = float(number)
    except ValueError:
        raise GateError(
            f"{option} {key}: expected a number or a percentage, got {value!r}"
        ) from None
    if not math.isfinite(t) or t < 0:
        raise GateError(f"{option} {key}: expected a finite number >= 0, got {value!r}")
    return key, (t / 100.0 if relative else t, relative)


def parse_baseline_metrics(texts, *, option: str = "--baseline-metrics") -> tuple | None:
    """``["flip_mean,ssim", "misclassified_fraction"]`` -> the metric keys (``all``:
    ``"all"``, every metric; none given: None, the default); unknown or ``info`` metrics are
    :class:`GateError`."""
    keys = [k.strip() for t in texts or () for k in str(t).split(",") if k.strip()]
    if not keys:
        return None
    if keys == ["all"]:
        return "all"
    for key in keys:
        if key not in catalog.CATALOG:
            raise GateError(
                f"{option}: unknown metric {key!r}; choose from all, {', '.join(catalog.CATALOG)}"
            )
        if catalog.CATALOG[key].direction == "info":
            raise GateError(f"{option} {key}: {key} is {catalog.CATALOG[key].better}")
    return tuple(dict.fromkeys(keys))


def _tolerance_text(tol) -> str:
    if not tol or not tol[0]:
        return ""
    t, relative = tol
    return f", tolerance {_limit(t * 100)}%" if relative else f", tolerance {_limit(t)}"


def compare_baseline(
    record: dict,
    baseline: dict,
    *,
    source: str = "baseline",
    options: BaselineOptions | None = None,
) -> Verdict:
    """Compare this run's ``record`` with a previous run's; returns a verdict holding one
    check per compared metric (``options.metrics``; None: every one) with a noise floor in
    both (a regression, worse by more than both floors and the metric's tolerance, fails
    it), and a note naming the metrics left out. :class:`GateError` when the runs are not of
    one scene, resolution, light, candidate kind and frame count."""
    options = options or BaselineOptions()
    mine = _identity(record)
    _check_same_run(mine, _identity(baseline), source)
    verdict = Verdict(scene=str(mine["scene"]))
    floors = record.get("noise_floor") or {}
    old_floors = baseline.get("noise_floor") or {}
    skipped: list[str] = []
    for key, m in catalog.CATALOG.items():
        if options.metrics not in (None, "all") and key not in options.metrics:
            continue
        a, b = _number(baseline.get(key)), _number(record.get(key))
        if m.direction == "info" or a is None or b is None:
            continue
        fa, fb = _number(old_floors.get(key)), _number(floors.get(key))
        if not all(v is not None and math.isfinite(v) for v in (a, b, fa, fb)):
            skipped.append(key)
            continue
        tol = options.tolerances.get(key)
        t, rel = tol or (0.0, False)
        bad = catalog.regressed(key, b, fb, a, fa, tolerance=t, relative=rel)
        line = (
            f"{'REGRESSION' if bad else 'PASS baseline'} {key} {_num(b, a)} "
            f"(noise floor {_num(fb)}) vs baseline {_num(a, b)} (noise floor {_num(fa)}"
            f"{_tolerance_text(tol)})"
        )
        check = Check(f"baseline {key}", key, not bad, line, "baseline", b, None, fb, a, fa)
        verdict.add([check])
    if skipped:
        why = "a value or noise floor missing or not finite"
        verdict.add(notes=[f"baseline: not compared ({why}): {', '.join(skipped)}"])
    return verdict


def limit_texts(limits, op: str) -> list[str]:
    """``{"ssim": 0.9}`` or ``["ssim=0.9"]`` -> ``["ssim=0.9"]`` (as the CLI takes them)."""
    if limits is None:
        return []
    if isinstance(limits, dict):
        return [f"{k}={float(v)!r}" for k, v in limits.items()]
    if isinstance(limits, str):
        raise GateError(f"{_OPTION[op]}: give a dict metric -> limit or a list, got {limits!r}")
    return [str(t) for t in limits]


def judge(record: dict, *, fail_above=None, fail_below=None, baseline=None) -> Verdict:
    """Judge a ``metrics.json`` record (a dict) as ``score`` does: the library's gate.

    Parameters
    ----------
    record : a metrics record (``score``'s ``metrics.json``, or the API's result).
    fail_above, fail_below : ``{metric: limit}`` or ``["metric=limit", ...]``
        (``--fail-above`` / ``--fail-below``).
    baseline : a previous run's record (dict) or the path of its ``metrics.json``.

    Returns the :class:`Verdict` (``exit_code``: 0 pass, 1 a gate failed or a metric
    regressed; ``lines``). Raises :class:`GateError` for a gate that cannot be judged or a
    baseline of another run (the CLI's exit 2).
    """
    gates = parse_gates(limit_texts(fail_above, "<="), limit_texts(fail_below, ">="))
    scene = ((record.get("reference") or {}).get("scene") or {}).get("name", "?")
    verdict = Verdict(scene=str(scene), checks=evaluate_gates(gates, record))
    if baseline is not None:
        source = "baseline" if isinstance(baseline, dict) else str(baseline)
        previous = baseline if isinstance(baseline, dict) else load_baseline(baseline)
        against = compare_baseline(
            record, previous, source=source, options=BaselineOptions.gated(gates)
        )
        verdict.add(against.checks, against.notes)
    return verdict


def _properties(case, check: Check) -> None:
    """The check's numbers as JUnit ``<property>`` entries (passing cases carry them too, so
    a CI dashboard can chart a metric's history)."""
    values = {
        "metric": check.metric,
        "kind": "regression" if check.kind == "baseline" else check.kind,
        "value": check.value,
        "limit": check.limit,
        "noise_floor": check.floor,
        "previous": check.previous,
        "previous_noise_floor": check.previous_floor,
    }
    props = ET.SubElement(case, "properties")
    for key, value in values.items():
        if value is not None:
            text = value if isinstance(value, str) else repr(float(value))
            ET.SubElement(props, "property", {"name": key, "value": text})


def junit_xml(verdicts) -> bytes:
    """JUnit XML of the checks of ``verdicts``: one ``<testsuite>`` with one ``<testcase>`` per
    scene x check (classname = the scene, name = the check's name, its numbers as
    properties), a ``<failure>`` holding the line of a failed one, and an ``<error>`` case
    per scene that could not be scored (``Verdict.errors``)."""
    checks = [(v.scene, c) for v in verdicts for c in v.checks]
    errors = [(v.scene, e) for v in verdicts for e in getattr(v, "errors", [])]
    n_fail = sum(not c.passed for _, c in checks)
    counts = {
        "tests": str(len(checks) + len(errors)),
        "failures": str(n_fail),
        "errors": str(len(errors)),
        "skipped": "0",
    }
    root = ET.Element("testsuites", {"name": "raster-oracle", **counts})
    suite = ET.SubElement(root, "testsuite", {"name": "raster-oracle score", **counts})
    for scene, c in checks:
        case = ET.SubElement(suite, "testcase", {"classname": scene, "name": c.name})
        _properties(case, c)
        if not c.passed:
            kind = "regression" if c.kind == "baseline" else "threshold"
            failure = ET.SubElement(case, "failure", {"message": c.line, "type": kind})
            failure.text = c.line
    for scene, (name, message) in errors:
        case = ET.SubElement(suite, "testcase", {"classname": scene, "name": name})
        error = ET.SubElement(case, "error", {"message": message, "type": "input"})
        error.text = message
    _xml_safe(root)
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def _xml_safe(root) -> None:
    """Every attribute and text of ``root`` with only the characters XML allows (user text:
    scene and check names, messages; a NUL or an escape character would make it unreadable)."""
    from ...scenes.base.untrusted import xml_text

    for el in root.iter():
        el.attrib.update({k: xml_text(v) for k, v in el.attrib.items()})
        if el.text is not None:
            el.text = xml_text(el.text)


def write_junit(path, verdicts) -> None:
    """Write :func:`junit_xml` of ``verdicts`` to ``path`` atomically."""
    atomic_write_bytes(path, junit_xml(verdicts))
