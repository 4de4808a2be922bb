"""The anti-aliasing ranking of the main job: on every scene of the sweep, the SMAA presets and
modes next to no AA, FXAA, MSAA and SSAA, ranked by coverage edge error (then colour edge
error), each figure with the reference's own noise floor.

Data come from the sweep's rows (the main job reads them from its store and passes them in);
nothing is rendered.
Two neighbours in the ranking whose coverage edge errors differ by less than the larger of
their noise floors are marked as not separated: the reference cannot tell them apart.

References
----------
J. Jimenez, J. I. Echevarria, T. Sousa, D. Gutierrez, SMAA: Enhanced Subpixel Morphological
Antialiasing, Computer Graphics Forum 31(2) 2012, doi:10.1111/j.1467-8659.2012.03014.x.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["LABEL_PARAMS", "RANKED_METRICS", "RANKED_TECHNIQUES", "aa_ranking"]

#: Techniques ranked, in the order of their first appearance in a tie.
RANKED_TECHNIQUES = ("noaa", "fxaa", "smaa", "msaa", "ssaa")
#: Metrics shown; the first ranks, the second breaks ties.
RANKED_METRICS = ("coverage_edge_rmse", "edge_mae", "flip_mean")
#: The parameters that name a configuration in the table.
LABEL_PARAMS = {"smaa": ("preset", "mode"), "msaa": ("samples",), "ssaa": ("samples",)}

SCHEMA = "raster-oracle.aa-ranking/1"


def _label(technique: str, params: dict) -> str:
    keys = LABEL_PARAMS.get(technique, ())
    shown = [f"{k}={params[k]}" for k in keys if k in params]
    return technique + (f" ({', '.join(shown)})" if shown else "")


def _number(v):
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _entry(row: dict) -> dict:
    metrics = row.get("metrics") or {}
    floors = metrics.get("noise_floor") or {}
    return {
        "label": _label(row["technique"], row.get("params") or {}),
        "technique": row["technique"],
        "metrics": {m: _number(metrics.get(m)) for m in RANKED_METRICS},
        "floors": {m: _number(floors.get(m)) for m in RANKED_METRICS},
        "framebuffer_bytes": _number((row.get("cost") or {}).get("framebuffer_bytes")),
    }


def _rank(entries: list[dict]) -> list[dict]:
    """Sort by the ranking metrics (missing values last) and mark unseparated neighbours."""
    first, second = RANKED_METRICS[:2]

    def key(e):
        a, b = e["metrics"][first], e["metrics"][second]
        return (a is None, a or 0.0, b is None, b or 0.0)

    out = sorted(entries, key=key)
    for i, e in enumerate(out):
        e["rank"] = i + 1
        e["separated"] = True
        if i:
            prev = out[i - 1]
            a, b = e["metrics"][first], prev["metrics"][first]
            floor = max(e["floors"][first] or 0.0, prev["floors"][first] or 0.0)
            e["separated"] = a is None or b is None or abs(a - b) > floor
    return out


def aa_ranking(rows: Iterable[dict], *, techniques=RANKED_TECHNIQUES) -> dict:
    """The ranking record of a sweep's ``rows`` (as its store gives them): one table per scene
    that has an ``smaa`` row, its finished rows of ``techniques`` ranked (see the module
    docstring).

    Returns ``{"schema", "metrics", "scenes": [{"scene", "resolution", "rows": [...]}]}``;
    each row: ``label``, ``technique``, ``metrics``, ``floors``, ``framebuffer_bytes``,
    ``rank``, ``separated``. No rows give no scenes.
    """
    done = [r for r in rows if r.get("status") == "done" and r.get("technique") in techniques]
    scenes = []
    for scene in dict.fromkeys(r["scene"] for r in done if r["technique"] == "smaa"):
        mine = [r for r in done if r["scene"] == scene]
        seen, entries = set(), []
        for r in mine:  # one entry per configuration (a frame sweep keeps its first frame)
            e = _entry(r)
            if e["label"] not in seen:
                seen.add(e["label"])
                entries.append(e)
        r0 = mine[0]
        scenes.append(
            {
                "scene": scene,
                "resolution": f"{r0.get('width')}x{r0.get('height')}",
                "rows": _rank(entries),
            }
        )
    return {"schema": SCHEMA, "metrics": list(RANKED_METRICS), "scenes": scenes}
