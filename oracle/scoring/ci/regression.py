"""A baseline run: a previous ``metrics.json`` read as untrusted input, checked to be of the
same scene, resolution, light, candidate kind and frame count, and compared metric by metric
with :func:`metrics.catalog.regressed` (worse by more than both noise floors combined)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from ....metrics import catalog
from .checks import (
    FOLDER_SCHEMA,
    METRICS_SCHEMA,
    Check,
    GateError,
    Verdict,
    as_number,
    format_limit,
    format_number,
    scored_kinds,
)

__all__ = [
    "DETERMINISTIC_TOLERANCES",
    "BaselineOptions",
    "check_baseline_scene",
    "compare_baseline",
    "load_baseline",
    "load_folder_baseline",
    "parse_baseline_metrics",
    "parse_tolerance",
]


def _read_record(path):
    """A record file read as untrusted input (a bounded regular file of strict JSON)."""
    from ....scenes.base.untrusted import read_json

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
    ``strict``: a case missing from this run or new in it (``score-folder``) fails, and so
    does a metric that cannot be compared (a value or noise floor missing).
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
    return f", tolerance {format_limit(t * 100)}%" if relative else f", tolerance {format_limit(t)}"


#: Baseline tolerance (error units) of the deterministic metrics, which have no noise floor
#: (the claimed technique's model is deterministic): a regression must exceed it. A correct
#: engine's conformance moves by float32 rounding between runs (misclassified < 1e-4,
#: edges < 0.02 px, FLIP < 1e-4 in the detection table); the smallest fault it catches
#: (a PCF one tap wider, a half-texel offset) moves them by 10x these or more.
DETERMINISTIC_TOLERANCES = {
    "conformance_misclassified_fraction": 0.0005,
    "conformance_edge_displacement_px": 0.05,
    "conformance_flip_mean": 0.0005,
}


def _uncompared(key: str, why: str, a, b, strict: bool) -> Check:
    """A requested metric that cannot be compared: passed unless ``strict``, named."""
    head = "FAIL baseline" if strict else "NOT COMPARED baseline"
    line = f"{head} {key}: {why} (--baseline-strict fails it)"
    return Check(
        f"baseline {key}", key, not strict, line, "baseline", b, None, None, a, None, False
    )


def _floors(key, floors, old_floors):
    """This run's and the baseline's noise floor of ``key`` (0 for a deterministic metric
    without one), or None where one is missing or not finite."""
    fa, fb = as_number(old_floors.get(key)), as_number(floors.get(key))
    if key in DETERMINISTIC_TOLERANCES:
        fa, fb = fa or 0.0, fb or 0.0
    if not all(v is not None and math.isfinite(v) for v in (fa, fb)):
        return None
    return fa, fb


def compare_baseline(
    record: dict,
    baseline: dict,
    *,
    source: str = "baseline",
    options: BaselineOptions | None = None,
) -> Verdict:
    """Compare this run's ``record`` with a previous run's; returns a verdict holding one
    check per compared metric (``options.metrics``; None: every one): a regression, worse
    by more than both noise floors and the metric's tolerance (a deterministic metric's
    floors are 0 and its default tolerance :data:`DETERMINISTIC_TOLERANCES`), fails it. A
    requested metric that cannot be compared (a value or noise floor missing or not finite)
    is a check too, ``compared=False``: it passes with a ``NOT COMPARED`` line, and fails
    with ``options.strict``. :class:`GateError` when the runs are not of one scene,
    resolution, light, candidate kind and frame count."""
    options = options or BaselineOptions()
    mine = _identity(record)
    _check_same_run(mine, _identity(baseline), source)
    verdict = Verdict(scene=str(mine["scene"]))
    floors = record.get("noise_floor") or {}
    old_floors = baseline.get("noise_floor") or {}
    asked = options.metrics if options.metrics not in (None, "all") else ()
    for key, m in catalog.CATALOG.items():
        if options.metrics not in (None, "all") and key not in options.metrics:
            continue
        a, b = as_number(baseline.get(key)), as_number(record.get(key))
        if m.direction == "info":
            continue
        if a is None or b is None:
            if key in asked:
                side = "this run" if b is None else "the baseline"
                why = f"no value in {side} (null: not scored, or nothing to score)"
                verdict.add([_uncompared(key, why, a, b, options.strict)])
            continue
        both = _floors(key, floors, old_floors)
        if both is None or not all(math.isfinite(v) for v in (a, b)):
            why = "a value or noise floor missing or not finite"
            verdict.add([_uncompared(key, why, a, b, options.strict)])
            continue
        fa, fb = both
        tol = options.tolerances.get(key)
        if tol is None and key in DETERMINISTIC_TOLERANCES:
            tol = (DETERMINISTIC_TOLERANCES[key], False)
        t, rel = tol or (0.0, False)
        bad = catalog.regressed(key, b, fb, a, fa, tolerance=t, relative=rel)
        line = (
            f"{'REGRESSION' if bad else 'PASS baseline'} {key} {format_number(b, a)} "
            f"(noise floor {format_number(fb)}) vs baseline {format_number(a, b)} "
            f"(noise floor {format_number(fa)}"
            f"{_tolerance_text(tol)})"
        )
        check = Check(f"baseline {key}", key, not bad, line, "baseline", b, None, fb, a, fa)
        verdict.add([check])
    return verdict
