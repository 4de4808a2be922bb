"""The report of a sweep store: Pareto fronts, sensitivity and every case
(``raster-oracle report --sweep``, the end of ``sweep`` and of the main job)."""

from __future__ import annotations

import json
from pathlib import Path

from ... import raster_models
from ...metrics.catalog import error_of
from ...reports.sweep import with_memory, write_sweep_report
from .run import SweepError
from .store import SweepStore

__all__ = ["canonical_order", "family_defaults", "metric_error", "sweep_report"]


def family_defaults() -> dict:
    """``{family: {"metrics": [...], "costs": [...], "group": ...}}`` from the registry's
    family records: what the report plots for a family when no metric or cost is requested,
    and whose fronts its techniques join."""
    return {
        f.name: {"metrics": list(f.metrics), "costs": list(f.costs), "group": f.group}
        for f in raster_models.FAMILIES.values()
    }


def metric_error(metric: str, value: float) -> float:
    """``value`` of ``metric`` as an error, 0 best, for the fronts to compare
    (:func:`metrics.catalog.error_of`: ``1 - ssim``, a PSNR's MSE, ``|bias|``); a metric the
    catalogue does not score (an ``info`` one, or a key it does not know) as it is."""
    try:
        return error_of(metric, value)
    except (KeyError, ValueError):
        return value


def _param_key(value) -> tuple:
    """A parameter value as a sort key: numbers by value, before text (JSON of the rest)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return (1, 0.0, json.dumps(value, sort_keys=True))
    return (0, float(value), "")


def canonical_order(rows: list[dict]) -> list[dict]:
    """``rows`` in an order of their content alone (family, scene, technique, parameters by
    name then value, frame, film, spp, seed, key), not the order the cases finished in: on
    several workers that order changes from run to run, and the page (group, technique and
    colour order) would with it."""

    def key(r: dict) -> tuple:
        params = r.get("params") or {}
        return (
            str(r.get("family")),
            str(r.get("scene")),
            str(r.get("technique")),
            tuple((k, _param_key(params[k])) for k in sorted(params)),
            *(int(r.get(k) or 0) for k in ("frame", "width", "height", "spp", "seed")),
            str(r.get("key")),
        )

    return sorted(rows, key=key)


def _check_keys(rows, costs, metrics) -> None:
    """Requested cost and metric keys must be in some finished case of the store."""
    done = [r for r in rows if r["status"] == "done"]
    have = {
        "--cost": sorted({k for r in done for k in with_memory(r.get("cost"))}),
        "--metric": sorted({k for r in done for k in (r.get("metrics") or {})} - {"noise_floor"}),
    }
    for option, wanted in (("--cost", costs or []), ("--metric", metrics or [])):
        for key in wanted:
            if key not in have[option]:
                raise SweepError(
                    f"report {option} {key}: in no finished case; choose from "
                    f"{', '.join(have[option]) or '(none)'}"
                )


def sweep_report(
    db: Path,
    out: Path,
    *,
    sweep: str | None = None,
    title: str | None = None,
    costs=None,
    metrics=None,
    extra_sections=None,
) -> Path:
    """Write the sweep report of the store ``db`` (rows of ``sweep``, or all) to ``out``.

    Parameters
    ----------
    costs, metrics : cost and metric keys of the fronts (None: the report's defaults); a key
        in no finished case is a :class:`oracle.sweeps.run.SweepError`.
    extra_sections : report sections after the sweep's (``{"id", "title", "html"}`` records).

    Returns
    -------
    Path
        ``out``.
    """
    with SweepStore(db, readonly=True) as store:
        store.check_integrity()
        rows = canonical_order(store.rows(sweep=sweep))
        images = store.images(r["key"] for r in rows if r["status"] == "done")
        _check_keys(rows, costs, metrics)
        # the store stays open for the viewers: only the cases the summary names are read
        write_sweep_report(
            rows,
            out,
            title=title or f"raster-oracle sweep {sweep or Path(db).name}",
            provenance={"database": str(Path(db).resolve()), "sweep": sweep or "all"},
            costs=costs,
            metrics=metrics,
            extra_sections=extra_sections,
            families=family_defaults(),
            images=images,
            viewers=store.viewers,
            rank=metric_error,
        )
    return out
