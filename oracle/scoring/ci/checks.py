"""What a CI judgement is made of: a :class:`Gate`, a judged :class:`Check` and the
:class:`Verdict` of a run, their record schemas, and how their lines print numbers.

:mod:`oracle.scoring.ci.gates` judges gates, :mod:`oracle.scoring.ci.regression` compares a
baseline run and :mod:`oracle.scoring.ci.junit` writes them as JUnit XML.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..channels import CHANNEL_KIND
from ..result import ScoreError

__all__ = [
    "FOLDER_SCHEMA",
    "METRICS_SCHEMA",
    "OPTION",
    "Check",
    "Gate",
    "GateError",
    "Verdict",
    "as_number",
    "format_limit",
    "format_number",
    "scored_kinds",
]

#: ``schema`` of a ``metrics.json`` record (what ``--baseline`` accepts).
METRICS_SCHEMA = "raster-oracle/metrics/1"
#: ``schema`` of a ``score-folder`` run's combined ``metrics.json``.
FOLDER_SCHEMA = "raster-oracle/score-folder/1"
OPTION = {"<=": "--fail-above", ">=": "--fail-below"}


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
        return OPTION[self.op]

    @property
    def where(self) -> str:
        """How messages name the gate's source: its origin, else its option."""
        return self.origin or self.option

    @property
    def name(self) -> str:
        """The JUnit test name, e.g. ``visibility_mae <= 0.02``."""
        return f"{self.metric} {self.op} {format_limit(self.limit)}"


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
    #: False for a baseline check that could not compare (a value or noise floor missing):
    #: passed unless ``--baseline-strict``, and named in the CLI, JUnit and Markdown
    compared: bool = True

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
            "compared": self.compared,
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


def format_limit(x: float) -> str:
    """A limit as the user wrote it: ``0.02``, ``10``, ``1e-05``, ``0.123456789``."""
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


def format_number(x: float, other: float | None = None) -> str:
    """``x`` with 4 significant digits, more when needed to tell it from ``other``."""
    if x is None:
        return "n/a"
    for digits in (4, 6, 9):
        text = f"{x:.{digits}g}"
        # an SSIM floor of 0.99996 is not "1": more digits until a rounded integer is told
        # apart from the value
        whole = float(text) == round(float(text)) and float(text) != x
        if whole and digits < 9:
            continue
        if other is None or x == other or text != f"{other:.{digits}g}":
            return text
    return repr(x)


def scored_kinds(record: dict) -> tuple[str, ...]:
    """Candidate kinds (the metric catalogue's) a ``metrics.json`` record scored: its
    channel's (``soft_visibility`` is ``visibility``), plus coverage where an anti-aliasing
    model's coverage was scored beside its colour."""
    kinds = [CHANNEL_KIND.get(record["channel"], record["channel"])]
    if record.get("coverage_reference") is not None and "coverage" not in kinds:
        kinds.append("coverage")
    return tuple(kinds)


def as_number(value) -> float | None:
    """A record's metric value as a float (``"nan"``/``"inf"`` as JSON stores them), None
    for null or anything that is not a number."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None
