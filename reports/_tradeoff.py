"""Cost-versus-error trade-off: Pareto fronts per technique family.

Lower cost and lower error are both better. A point is on the Pareto front (non-dominated)
when no other point is at least as good in both and strictly better in one.

References
----------
Deb, K. (2001). *Multi-Objective Optimization Using Evolutionary Algorithms*, Wiley,
ch. 2 (dominance and the non-dominated set). ISBN 978-0-471-87339-6.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ._validate import decode_float

__all__ = ["COST_PREFERENCE", "pareto_front", "tradeoff_section"]

#: Cost keys tried, in order, when ``build_report`` is not told which cost to plot.
COST_PREFERENCE = ("memory_bytes", "texels_rendered", "texture_lookups_per_pixel")


def pareto_front(cost: Sequence[float], error: Sequence[float]) -> np.ndarray:
    """Boolean mask of the non-dominated points (minimising both ``cost`` and ``error``).

    Parameters
    ----------
    cost, error : sequence of float, length N
        Finite values; equal points do not dominate each other (both stay on the front).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    c = np.asarray(cost, dtype=np.float64)
    e = np.asarray(error, dtype=np.float64)
    if c.shape != e.shape or c.ndim != 1:
        raise ValueError(f"cost and error must be 1-D of one length, got {c.shape} and {e.shape}")
    # [i, j]: point j is at least as good as point i in both, and strictly better in one.
    no_worse = (c[None, :] <= c[:, None]) & (e[None, :] <= e[:, None])
    better = (c[None, :] < c[:, None]) | (e[None, :] < e[:, None])
    return ~(no_worse & better).any(axis=1)


def _pick(requested: str | None, available: list[str], preference: Sequence[str], what: str):
    if requested is not None:
        if requested not in available:
            raise ValueError(f"{what} {requested!r} is in no case; available: {available}")
        return requested
    for name in preference:
        if name in available:
            return name
    return available[0] if available else None


def tradeoff_section(
    cases: Sequence[dict], *, cost_key: str | None, metric: str | None
) -> dict | None:
    """Build the trade-off record of ``build_report`` or ``None`` when no case has a cost.

    Returns
    -------
    dict or None
        ``{"cost_key", "metric", "families": [{"family", "points": [{"case_id", "name",
        "technique", "params", "cost", "error", "on_front"}], "front": [indices into points,
        by increasing cost]}]}``.
    """
    costed = [case for case in cases if case.get("cost")]
    cost_keys = list(dict.fromkeys(k for case in costed for k in case["cost"]))
    metrics = list(dict.fromkeys(k for case in costed for k in case["metrics"]))
    if not cost_keys:
        if cost_key is not None:
            raise ValueError(f"tradeoff_cost {cost_key!r} given but no case carries a cost")
        return None
    cost_key = _pick(cost_key, cost_keys, COST_PREFERENCE, "tradeoff_cost")
    metric = _pick(metric, metrics, (), "tradeoff_metric")
    if metric is None:
        return None
    families: dict[str, list[dict]] = {}
    for case in costed:
        cost = case["cost"].get(cost_key)
        error = decode_float(case["metrics"].get(metric))
        if cost is None or not math.isfinite(error):
            continue
        family = case.get("family") or case.get("technique") or "unassigned"
        families.setdefault(family, []).append(
            {
                "case_id": case["id"],
                "name": case["name"],
                "technique": case.get("technique"),
                "params": case.get("params", {}),
                "cost": cost,
                "error": error,
            }
        )
    out = []
    for family, points in families.items():
        mask = pareto_front([p["cost"] for p in points], [p["error"] for p in points])
        for point, on_front in zip(points, mask, strict=True):
            point["on_front"] = bool(on_front)
        front = sorted(np.flatnonzero(mask).tolist(), key=lambda i: (points[i]["cost"], i))
        out.append({"family": family, "points": points, "front": front})
    return {"cost_key": cost_key, "metric": metric, "families": out}
