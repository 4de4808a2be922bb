"""``bench exact``: the exact-coverage estimate against the exact pass's actual time.

Per row (a scene at a film size) the estimate (:func:`scenes.geometry.exact_coverage.
estimate_cost`: seconds, triangles, tile pieces, piece pairs, and the seconds of the path the
work then takes) and the exact pass itself, timed in wall and process CPU seconds, with no
budget; the ratio is the estimate over the CPU time (the wall time of a quiet machine; a
loaded one stretches the wall time, not the work). Rows: the meadow, the city block with
foliage, the stacked panes (:mod:`oracle.studies.panes`) at 16:9, 4:3 and 1:1, and the
built-in scenes at their own sizes.
"""

from __future__ import annotations

import time

__all__ = ["EXACT_ROWS", "PANES_ROWS", "bench_exact", "exact_lines", "load_row"]

#: The stacked panes of the table (40 panes: the issue's 80 take minutes a row here).
PANES_ROWS = ("panes:n=40@160x90", "panes:n=40@160x120", "panes:n=40@128x128")
#: Every row of the default table: ``scene@WIDTHxHEIGHT`` (no size: the scene's own).
EXACT_ROWS = ("meadow@320x180", "city-foliage@320x180", *PANES_ROWS)


def load_row(row: str):
    """The loaded scene of a row ``scene@WxH``: a built-in scene (with its parameters) or the
    stacked panes (``panes:n=N``)."""
    from ... import scenes
    from .panes import PANES_N, panes_scene

    name, _, size = row.partition("@")
    w, h = (int(v) for v in size.split("x")) if size else (None, None)
    if name == "panes" or name.startswith("panes:"):
        n = int(name.partition("n=")[2] or PANES_N)
        return scenes.load(panes_scene(n), width=w, height=h)
    return scenes.load(name, width=w, height=h)


def _row(row: str) -> dict:
    from ...scenes.geometry.coverage_cost import polygon_seconds
    from ...scenes.geometry.exact_coverage import (
        estimate_cost,
        exact_coverage_of,
        scene_triangle_set,
    )
    from ..reference.coverage import centre_shapes

    loaded = load_row(row)
    tset = scene_triangle_set(loaded)
    centre = centre_shapes(loaded)
    t0 = time.perf_counter()
    est = estimate_cost(loaded.camera, tset)
    est_s = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    ex = exact_coverage_of(loaded.camera, tset, centre)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    method = ex.stats["method"]
    # the estimate of the path the work took (the layered one unless it fell back)
    path_s = polygon_seconds(est) if method == "polygons" else est["seconds"]
    return {
        "scene": loaded.name,
        "resolution": [loaded.width, loaded.height],
        "triangles": est["triangles"],
        "pieces": est["pieces"],
        "pairs": est["pairs"],
        "tile_pieces": ex.stats["tile_pieces"],
        "method": method,
        "estimate_seconds": path_s,
        "estimate_own_seconds": est_s,
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "estimate_over_actual": path_s / max(cpu, 1e-3),
    }


def bench_exact(rows=EXACT_ROWS, *, builtins: bool = True, log=None) -> dict:
    """Estimate against actual for ``rows`` and (``builtins``) every built-in scene at its
    own size; ``log`` is called with each finished row's line."""
    from ... import scenes

    rows = list(rows) + (scenes.scene_names() if builtins else [])
    out = {"rows": {}}
    for row in rows:
        rec = _row(row)
        out["rows"][row] = rec
        if log is not None:
            log(_line(row, rec))
    ratios = [r["estimate_over_actual"] for r in out["rows"].values()]
    out["worst_ratio"] = max(max(ratios), 1.0 / min(ratios)) if ratios else None
    out["target"] = "estimate within 3x of the CPU seconds either way, every row"
    return out


def _line(row: str, r: dict) -> str:
    w, h = r["resolution"]
    return (
        f"{row:<24} {w}x{h:<5} {r['triangles']:>7} tri {r['pieces']:>7} pieces "
        f"{r['pairs']:>10} pairs  {r['method']:<8} estimate {r['estimate_seconds']:8.3f} s  "
        f"actual {r['cpu_seconds']:8.3f} s CPU ({r['wall_seconds']:.3f} s wall)  "
        f"ratio {r['estimate_over_actual']:.2f}"
    )


def exact_lines(figures: dict) -> list[str]:
    """One line per row of :func:`bench_exact`'s figures, and the worst ratio."""
    lines = [_line(row, r) for row, r in figures["rows"].items()]
    return [*lines, f"worst estimate/actual ratio (either way): {figures['worst_ratio']:.2f}"]
