"""``raster-oracle tune``: the cheapest configuration of a technique that meets an error target.

The search is Optuna's: a constrained TPE study (objective: the cost key; constraint
``metric - target <= 0``, set with ``Trial.set_constraint``), or, when the search space is
discrete and no larger than the trial budget, Optuna's grid sampler, which tries every
configuration once (the answer is then exact). The study is stored in the sweep store's
SQLite file (Optuna's own tables), so a second run with the same arguments continues it;
every evaluated configuration is also a row of the store (sweep ``tune:<study>``), so
repeated configurations are not scored twice and ``report --sweep`` shows them.

References
----------
Akiba, T., Sano, S., Yanase, T., Ohta, T., Koyama, M. (2019). Optuna: A Next-generation
Hyperparameter Optimization Framework. KDD 2019, doi:10.1145/3292500.3330701.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import optuna

from ... import raster_models, scenes
from ...metrics.catalog import CATALOG
from ...raster_models import params
from ...scenes import backend
from ..errors import InputError
from ..scoring.result import metric_limit
from .cases import run_case
from .run import store_row, sweep_keys
from .spec import Case
from .store import SweepStore

__all__ = ["TuneError", "parse_space", "parse_target", "run_tune"]

#: Default search space: shadow-map resolution from 64^2 to 4096^2 texels (log scale).
DEFAULT_RESOLUTION = (64, 4096)
#: Constraint value of a trial whose case failed (infeasible, worse than any real miss).
FAILED_CONSTRAINT = 1e30


class TuneError(InputError):
    """Bad tuning request (target, search space, cost key)."""


def parse_target(text: str) -> tuple[str, float]:
    """``"flip_mean<=0.05"`` -> ``("flip_mean", 0.05)``; the metric must be a metric key whose
    lower values are better (:mod:`metrics.catalog`): ``ssim<=0.9`` would search for bad
    configurations."""
    key, limit = metric_limit(text, separator="<=", option="--target", error=TuneError)
    m = CATALOG[key]
    if m.direction != "lower":
        raise TuneError(
            f"--target {key}: {key} is {m.better}; --target METRIC<=V takes a lower-is-better "
            "metric (e.g. flip_mean, visibility_mae)"
        )
    return key, limit


def parse_space(technique: str, vary: list[str]) -> dict[str, tuple]:
    """Search space from ``--vary`` texts: ``{name: ("int"|"float", lo, hi) | ("choice", vals)}``.

    ``KEY=lo:hi`` is a log-uniform integer or float range (by the parameter's kind);
    ``KEY=a,b,c`` a set of choices (parsed as ``--set`` values are). Without ``--vary`` the
    space is ``resolution`` over :data:`DEFAULT_RESOLUTION` when the technique has one.
    """
    if technique not in raster_models.TECHNIQUES:
        raise TuneError(
            f"unknown technique {technique!r}; choose one of {', '.join(raster_models.TECHNIQUES)}"
        )
    fields = {p["name"]: p for p in params.describe(raster_models.TECHNIQUES[technique].params)}
    if not vary:
        if "resolution" not in fields:
            raise TuneError(f"{technique} has no resolution parameter: give --vary KEY=SPEC")
        return {"resolution": ("int", *DEFAULT_RESOLUTION)}
    space: dict[str, tuple] = {}
    for text in vary:
        key, sep, spec = text.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or not spec.strip():
            raise TuneError(f"--vary expects KEY=lo:hi or KEY=a,b,c, got {text!r}")
        if key not in fields:
            raise TuneError(
                f"--vary: unknown parameter {key!r} of {technique}; valid: {', '.join(fields)}"
            )
        kind = fields[key]["type"]
        if ":" in spec and "," not in spec:
            if kind not in ("int", "float"):
                raise TuneError(f"--vary {key}: a lo:hi range needs a number parameter ({kind})")
            lo_text, hi_text = spec.split(":", 1)
            try:
                lo, hi = float(lo_text), float(hi_text)
            except ValueError:
                raise TuneError(f"--vary {key}: expected lo:hi numbers, got {spec!r}") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
                raise TuneError(f"--vary {key}: need 0 < lo < hi (log scale), got {spec!r}")
            if kind == "int":
                if not (lo.is_integer() and hi.is_integer()):
                    raise TuneError(f"--vary {key}: integer bounds expected, got {spec!r}")
                space[key] = ("int", int(lo), int(hi))
            else:
                space[key] = ("float", lo, hi)
        else:
            values = []
            for item in (s for s in spec.split(",") if s.strip()):
                try:
                    parsed = raster_models.parse_params(technique, [f"{key}={item}"])[key]
                except raster_models.ModelError as exc:
                    raise TuneError(f"--vary {key}: {exc}") from None
                values.append(list(parsed) if isinstance(parsed, tuple) else parsed)
            if not values:
                raise TuneError(f"--vary {key}: no values in {spec!r}")
            space[key] = ("choice", list(dict.fromkeys(json.dumps(v) for v in values)))
    return space


def _suggest(trial, space: dict) -> dict:
    out = {}
    for key, spec in space.items():
        if spec[0] == "int":
            out[key] = trial.suggest_int(key, spec[1], spec[2], log=True)
        elif spec[0] == "float":
            out[key] = trial.suggest_float(key, spec[1], spec[2], log=True)
        else:
            out[key] = json.loads(trial.suggest_categorical(key, spec[1]))
    return out


def _grid(space: dict) -> dict | None:
    """Optuna grid of a discrete space (choices only), else None."""
    if all(spec[0] == "choice" for spec in space.values()):
        return {key: list(spec[1]) for key, spec in space.items()}
    return None


@dataclass(frozen=True)
class _Problem:
    """A tuning problem: what is varied and fixed, on which scene, against which target."""

    scene: str
    technique: str
    loaded: object
    space: dict
    fixed: dict
    metric: str
    limit: float
    cost_key: str
    name: str
    spp: int
    seed: int
    light: int


def _problem(
    scene, *, technique, target, minimize, vary, fixed, width, height, light, spp, seed, study_name
) -> _Problem:
    """Check the request and name the study (the same request continues the same study)."""
    metric, limit = target
    space = parse_space(technique, list(vary or []))
    try:
        fixed_params = raster_models.parse_params(technique, list(fixed or []))
    except raster_models.ModelError as exc:
        raise TuneError(str(exc)) from None
    clash = sorted(set(fixed_params) & set(space))
    if clash:
        raise TuneError(f"parameter {clash[0]} is both --set and --vary")
    loaded = scenes.load(scene, width=width, height=height, light=light)
    if loaded.light.kind not in raster_models.TECHNIQUES[technique].lights:
        raise TuneError(f"{technique} does not support the {loaded.light.kind} light of {scene}")
    # the cost minimised when --minimize is not given: the family's memory
    cost_key = minimize or raster_models.family(technique).memory_cost
    _probe_cost_key(scene, technique=technique, cost_key=cost_key, light=light, params=fixed_params)
    ident = json.dumps(
        [
            scene,
            loaded.content_hash,
            technique,
            metric,
            limit,
            cost_key,
            space,
            sorted(fixed_params.items()),
            spp,
            seed,
            light,
        ],
        sort_keys=True,
        default=str,
    )
    name = study_name or (
        f"{technique} on {loaded.name}: min {cost_key} s.t. {metric}<={limit:g} "
        f"[{hashlib.sha256(ident.encode()).hexdigest()[:10]}]"
    )
    return _Problem(
        scene,
        technique,
        loaded,
        space,
        fixed_params,
        metric,
        limit,
        cost_key,
        name,
        spp,
        seed,
        light,
    )


def _evaluate(problem: _Problem, params: dict, *, store: SweepStore, cache, variant) -> dict:
    """The store row of one configuration: scored now, or found in the store."""
    case = Case(
        scene=problem.scene,
        technique=problem.technique,
        params={**problem.fixed, **params},
        width=problem.loaded.width,
        height=problem.loaded.height,
        spp=problem.spp,
        seed=problem.seed,
        light=problem.light,
    )
    key, rec, row = sweep_keys([case], variant)[0]
    stored = store.get(key)
    if stored is None or stored["status"] != "done":
        res = run_case(rec, str(cache.root), variant)
        sweep = f"tune:{problem.name}"
        store.put(store_row(row, key=key, rec=rec, res=res, sweep=sweep, run_id="tune"))
        stored = store.get(key)
    return stored


def _infeasible(trial, error: str) -> None:
    trial.set_user_attr("error", error)
    trial.set_user_attr("constraint", FAILED_CONSTRAINT)
    trial.set_constraint("target", FAILED_CONSTRAINT)
    raise optuna.TrialPruned(error)


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _cost_value(cost: dict | None, *, key: str, technique: str) -> float:
    """The number ``cost[key]``; a key that is not a numeric cost is a TuneError naming the
    technique's numeric costs."""
    value = (cost or {}).get(key)
    if not _is_number(value):
        numeric = [
            k
            for k, v in (cost or {}).items()
            if isinstance(v, int | float) and not isinstance(v, bool)
        ]
        raise TuneError(
            f"--minimize {key}: not a cost of {technique}; choose from {', '.join(numeric)}"
        )
    return float(value)


#: Film size of the probe run that checks ``--minimize`` before the study starts.
_PROBE_SIZE = (16, 9)


def _probe_cost_key(scene, *, technique: str, cost_key: str, light: int, params: dict) -> None:
    """Check ``cost_key`` on a tiny run of the technique, before the store is opened (a cost
    record has the same keys at any size). A run the model refuses is left to the trials."""
    probe = scenes.load(scene, width=_PROBE_SIZE[0], height=_PROBE_SIZE[1], light=light)
    try:
        result = raster_models.run(technique, probe, **params)
    except raster_models.ModelError:
        return
    _cost_value(result.cost, key=cost_key, technique=technique)


def _cost_of(problem: _Problem, row: dict) -> float:
    return _cost_value(row["cost"], key=problem.cost_key, technique=problem.technique)


def _objective(problem: _Problem, *, store: SweepStore, cache, variant):
    """Optuna's objective: the configuration's cost, its metric's excess as the constraint."""
    technique = problem.technique

    def objective(trial):
        params = _suggest(trial, problem.space)
        try:
            raster_models.params.make(
                technique, raster_models.TECHNIQUES[technique].params, {**problem.fixed, **params}
            )
        except raster_models.ModelError as exc:
            _infeasible(trial, str(exc))
        row = _evaluate(problem, params, store=store, cache=cache, variant=variant)
        trial.set_user_attr("key", row["key"])
        if row["status"] != "done":
            _infeasible(trial, row["error"])
        value = row["metrics"].get(problem.metric)
        if value is None:
            raise TuneError(f"metric {problem.metric} does not apply to {technique}")
        cost = _cost_of(problem, row)
        trial.set_user_attr("metric", float(value))
        trial.set_user_attr("constraint", float(value) - problem.limit)
        # Optuna's constrained TPE reads this: feasible when <= 0
        trial.set_constraint("target", float(value) - problem.limit)
        return cost

    return objective


def _optimize(problem: _Problem, objective, *, store: SweepStore, trials: int, quiet: bool):
    """Create (or continue) the study and run its remaining trials; ``(study, sampler name)``.

    A discrete space no larger than ``trials`` is searched exhaustively by Optuna's grid
    sampler; anything else by constrained TPE.
    """
    grid = _grid(problem.space)
    n_grid = math.prod(len(v) for v in grid.values()) if grid is not None else None
    if grid is not None and n_grid <= trials:
        sampler = optuna.samplers.GridSampler(grid, seed=problem.seed)
        sampler_name = "grid"
    else:
        sampler = optuna.samplers.TPESampler(seed=problem.seed)
        sampler_name = "tpe"
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    with warnings.catch_warnings():
        # GridSampler and the SQLite storage are marked experimental by Optuna
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        study = optuna.create_study(
            study_name=problem.name,
            storage=store.url(),
            sampler=sampler,
            direction="minimize",
            load_if_exists=True,
        )
        done = [t for t in study.trials if t.state.is_finished()]
        budget = trials if sampler_name == "tpe" else max(0, min(trials, n_grid) - len(done))
        if budget:
            study.optimize(objective, n_trials=budget, show_progress_bar=not quiet)
    return study, sampler_name


def _evaluated(study, space: dict) -> list[dict]:
    """Every distinct configuration the study completed, cheapest first."""
    results, seen = [], set()
    for t in study.trials:
        key = t.user_attrs.get("key")
        if t.state != optuna.trial.TrialState.COMPLETE or key in seen:
            continue
        seen.add(key)
        results.append(
            {
                "params": {
                    k: json.loads(v) if space[k][0] == "choice" else v for k, v in t.params.items()
                },
                "cost": t.value,
                "metric": t.user_attrs["metric"],
                "feasible": t.user_attrs["constraint"] <= 0,
                "key": key,
            }
        )
    results.sort(key=lambda r: (r["cost"], r["metric"]))
    return results


def run_tune(
    scene: str,
    *,
    technique: str,
    target: tuple[str, float],
    minimize: str | None = None,
    trials: int = 20,
    vary: list[str] | None = None,
    fixed: list[str] | None = None,
    width: int | None = None,
    height: int | None = None,
    light: int = 0,
    spp: int = 64,
    seed: int = 0,
    db: str | Path,
    study_name: str | None = None,
    cache,
    quiet: bool = True,
) -> dict:
    """Find the cheapest configuration meeting ``target``; returns the study's summary.

    Parameters
    ----------
    target : ``(metric, limit)`` from :func:`parse_target`.
    vary, fixed : ``--vary`` texts (:func:`parse_space`) and ``--set`` ``KEY=VALUE`` texts.
    db : the sweep store holding the study and the evaluated cases.
    cache : the reference cache (a :class:`oracle.reference.cache.ReferenceCache`).

    Returns
    -------
    dict
        ``{"study", "db", "sampler", "target", "minimize", "trials", "feasible", "best":
        {"params", "cost", "metric", "key"} or None, "evaluated": [{"params", "cost",
        "metric", "feasible"}]}`` (``evaluated`` sorted by cost).
    """
    problem = _problem(
        scene,
        technique=technique,
        target=target,
        minimize=minimize,
        vary=vary,
        fixed=fixed,
        width=width,
        height=height,
        light=light,
        spp=spp,
        seed=seed,
        study_name=study_name,
    )
    store = SweepStore(db)
    try:
        variant = backend.active().variant
        objective = _objective(problem, store=store, cache=cache, variant=variant)
        study, sampler_name = _optimize(problem, objective, store=store, trials=trials, quiet=quiet)
    finally:
        store.close()
    results = _evaluated(study, problem.space)
    feasible = [r for r in results if r["feasible"]]
    best = feasible[0] if feasible else None
    return {
        "study": problem.name,
        "db": str(db),
        "sampler": sampler_name,
        "target": {"metric": problem.metric, "max": problem.limit},
        "minimize": problem.cost_key,
        "fixed": problem.fixed,
        "trials": len(study.trials),
        "feasible": len(feasible),
        "best": None if best is None else {**best, "params": {**problem.fixed, **best["params"]}},
        "evaluated": results,
    }
