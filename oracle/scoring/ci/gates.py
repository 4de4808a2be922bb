"""CI gates of ``raster-oracle score``: thresholds judged on a record, and :func:`judge`.

A gate is ``--fail-above METRIC=V`` (passes while the value is <= V) or ``--fail-below
METRIC=V`` (passes while the value is >= V). A gate must mean something, or it would pass
silently: every rule below is an :class:`GateError` (exit 2), never a pass.

- the metric is unknown (the message lists the known ones);
- its direction makes the gate meaningless: SSIM is higher-is-better, so ``--fail-above
  ssim=0.9`` would fail good images (the message says to use ``--fail-below ssim=0.9``); an
  ``info`` metric (a technique's constant) is no score at all;
- the metric does not apply to the candidate kinds scored (a shadow metric on a colour
  candidate) or to the frame count (``flicker`` needs 2 frames);
- its value is null or NaN in this run;
- its support is empty (:func:`support_record`: no receiver in view, no edge-band pixel):
  the message names the case, the metric and the empty set, and the record says
  ``support: 0`` for it.

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

from ....metrics import catalog
from ..result import metric_limit
from .checks import (
    OPTION,
    Check,
    Gate,
    GateError,
    Verdict,
    as_number,
    format_limit,
    format_number,
    scored_kinds,
)
from .regression import BaselineOptions, compare_baseline, load_baseline

__all__ = [
    "support_record",
    "applicable_gates",
    "check_applicable",
    "evaluate_gates",
    "judge",
    "limit_texts",
    "parse_gates",
]


def parse_gates(fail_above=(), fail_below=()) -> list[Gate]:
    """``--fail-above`` and ``--fail-below`` texts (``METRIC=V``) -> gates, checked against the
    metric catalogue: unknown metrics and gates against the metric's direction are
    :class:`GateError`."""
    gates = []
    for op, texts in (("<=", fail_above), (">=", fail_below)):
        for text in texts or ():
            key, limit = metric_limit(text, separator="=", option=OPTION[op], error=GateError)
            m = catalog.CATALOG[key]
            if m.direction == "info":
                raise GateError(f"{OPTION[op]} {key}: {key} is {m.better}; it cannot be gated")
            wrong = {"<=": "higher", ">=": "lower"}[op]
            if m.direction == wrong:
                right = OPTION[{"<=": ">=", ">=": "<="}[op]]
                raise GateError(
                    f"{OPTION[op]} {key}={text.partition('=')[2].strip()}: {key} is "
                    f"{m.better}: use {right} {key}={text.partition('=')[2].strip()}"
                )
            gates.append(Gate(key, op, limit))
    return gates


def applicable_gates(gates, *, kinds, temporal: bool = False) -> tuple[list, list[str]]:
    """``gates`` without the profile gates (``optional``) whose metric does not apply to the
    candidate ``kinds`` (of a temporal family's sequence when ``temporal``), and a note naming
    each one left out."""
    kept, notes = [], []
    for g in gates:
        m = catalog.CATALOG[g.metric]
        if g.optional and not m.applies(kinds, temporal=temporal):
            notes.append(
                f"{g.where}: {g.metric} applies to {' and '.join(m.kinds)} candidates, not "
                f"{' and '.join(kinds)}: not judged"
            )
            continue
        kept.append(g)
    return kept, notes


def check_applicable(gates, *, kinds=None, frames: int = 1, temporal: bool = False) -> None:
    """:class:`GateError` for a gate whose metric does not apply to the candidate ``kinds``
    (None: not known yet, not checked; ``temporal``: of a temporal family's sequence) or to
    ``frames`` frames."""
    for g in gates:
        m = catalog.CATALOG[g.metric]
        if kinds is not None and not m.applies(kinds, temporal=temporal):
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


#: The set a shadow mask's metric is computed over: (the record's counter, its name).
_RECEIVERS = ("receiver_count", "receivers")
_DEPTH_SEEN = ("depth_pixels", "pixels where the reference sees a surface (not sky)")
_EDGE_BAND = ("edge_band_count", "edge-band receivers (within 2 px of a shadow edge)")


def _support_set(record: dict, key: str) -> tuple[str, str] | None:
    """``(counter, name)`` of the pixels ``key`` is computed over in ``record``, or None
    where the metric's support is not counted (colour, coverage: every pixel; a depth's is
    the pixels the reference sees a surface at)."""
    if record.get("channel") == "depth":
        return _DEPTH_SEEN if key.startswith("depth_") else None
    if record.get("channel") not in ("visibility", "soft_visibility", "light_fraction"):
        return None
    if key.startswith("edge_band_"):
        return _EDGE_BAND
    return _RECEIVERS  # a shadow mask is judged on the receivers: every metric of it


def support_record(record: dict) -> dict:
    """``{metric: pixels}``: the size of the set each scored metric of ``record`` is computed
    over (summed over its frames), for the metrics whose support is counted; a metric with
    support 0 is set to None in ``record`` (and its frames): never a perfect score from
    nothing. Returns the support (also stored as ``record["support"]``)."""
    frames = record.get("frames") or [record]
    support = {}
    for key in catalog.CATALOG:
        if key not in record:
            continue
        found = _support_set(record, key)
        if found is None:
            continue
        counter = found[0]
        counts = [f.get(counter) for f in frames]
        if any(c is None for c in counts):
            continue
        n = int(sum(int(c) for c in counts))
        support[key] = n
        if n == 0:
            record[key] = None
            for f in record.get("frames") or []:
                f[key] = None
    record["support"] = support
    return support


def _value(record: dict, key: str, what: str) -> float:
    n = (record.get("support") or {}).get(key)
    if n == 0:
        case = ((record.get("reference") or {}).get("scene") or {}).get("name", "?")
        found = _support_set(record, key)
        name = found[1] if found else "pixels"
        raise GateError(
            f"{what}: case {case}: {key} is computed over the {name}, and this run has none "
            "(support: 0): nothing to judge, no gate passes on nothing"
        )
    value = as_number(record.get(key))
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
    """Judge ``gates`` on a ``metrics.json`` record (applicability is checked first; the
    temporal metrics apply where the record's temporal pass ran: ``temporal_aa``)."""
    frames = len(record.get("frames") or []) or 1
    temporal = record.get("temporal_aa") is not None
    check_applicable(gates, kinds=scored_kinds(record), frames=frames, temporal=temporal)
    floors = record.get("noise_floor") or {}
    checks = []
    for g in gates:
        value = _value(record, g.metric, f"{g.where} {g.metric}")
        passed = value <= g.limit if g.op == "<=" else value >= g.limit
        shown = g.op if passed else {"<=": ">", ">=": "<"}[g.op]
        floor = floors.get(g.metric)
        line = (
            f"{'PASS' if passed else 'FAIL'} {g.metric} {format_number(value, g.limit)} {shown} "
            f"{format_limit(g.limit)} (noise floor {format_number(floor)})"
        )
        checks.append(
            Check(g.name, g.metric, passed, line, value=value, limit=g.limit, floor=floor)
        )
    return checks


def limit_texts(limits, op: str) -> list[str]:
    """``{"ssim": 0.9}`` or ``["ssim=0.9"]`` -> ``["ssim=0.9"]`` (as the CLI takes them)."""
    if limits is None:
        return []
    if isinstance(limits, dict):
        return [f"{k}={float(v)!r}" for k, v in limits.items()]
    if isinstance(limits, str):
        raise GateError(f"{OPTION[op]}: give a dict metric -> limit or a list, got {limits!r}")
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
