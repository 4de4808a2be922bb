"""Numerical extremes: every registered model x every extreme, against the oracle.

Each extreme (:mod:`oracle.studies.extremes.cases`) is a transformation of a built-in scene's
dictionary (``plate``, one clean hard shadow under a directional light, for shadow models;
``star``, a Siemens star against the sky, for anti-aliasing models) plus, for some, parameter
overrides; the transformed scene is loaded once and rendered by the oracle and by every model
alike. A cell of the
matrix records whether the model's outputs and cost are finite, its error against the oracle
(misclassified receivers for shadow models, coverage RMSE for anti-aliasing models), and the
documented expected outcome with its reason; ``outcome_met`` says whether the measurement
agrees. Models registered later enter automatically through the registry (their ``lights``
and ``family``); a model without an override gets the default expectation.

``run_extremes(out, cache=..., quiet=..., echo=..., quick=...)`` is the main job's entry
point; it writes ``out/extremes.json``.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np

from ....reports.sections import extremes_section
from ...errors import one_line
from ..output import write_study
from .cases import (
    DEFAULT_AA_EXPECTATION,
    DEFAULT_EXPECTATION,
    DEFAULTS,
    EXPECTATIONS,
    EXTREMES,
    FAR_OFFSET,
    GRAZING_DEG,
    Expectation,
    Extreme,
    expectation,
)

__all__ = [
    "DEFAULTS",
    "DEFAULT_AA_EXPECTATION",
    "DEFAULT_EXPECTATION",
    "EXPECTATIONS",
    "EXTREMES",
    "Expectation",
    "Extreme",
    "FAR_OFFSET",
    "GRAZING_DEG",
    "HUGE_BYTES_PER_TEXEL",
    "expectation",
    "extreme_line",
    "load_extreme",
    "merge_extremes",
    "reference_channels",
    "run_cell",
    "run_extremes",
    "write_extremes",
]

BASE_SCENE = "plate"
# Base scene of each technique family: its record's ``extremes_scene`` (shadow models get
# the plate's clean hard shadow, anti-aliasing models the Siemens star's edges against the sky)
#: Peak resident bytes per shadow-map texel of the current models (maps are rendered and
#: filtered in bounded launches; the whole-map arrays are the stored depth and moments),
#: measured above the process's own 0.12 GB: ``shadow-map`` 16384^2 1.37 GB (about 5
#: B/texel), ``sdsm`` 8192^2 with EVSM4 moments 1.97 GB (about 28 B/texel); a bound for both.
HUGE_BYTES_PER_TEXEL = 32
#: Huge-map size in quick mode (the main job): 8192^2 cost 2 of the 4 minutes of extremes and
#: claims together on 2 loaded cores (izb's 8192^2 grid alone 60 s).
QUICK_HUGE = 4096
#: Largest shadow-map resolution a cell uses unless its extreme sets one (fast, and fine
#: enough for the plate's 2-unit caster); a technique whose default is lower keeps it.
CELL_MAP = 512
#: Work caps of every cell (a parameter's default is kept when lower): map resolution, and
#: the number of coherent shadow maps (256 = 4^4, ~8 degrees apart; 1024 costs 4x).
CELL_CAPS = {"resolution": CELL_MAP, "directions": 256}


# ----------------------------------------------------------------------- running
def load_extreme(extreme: Extreme, *, width: int, height: int, base: str = BASE_SCENE):
    """The base scene transformed by ``extreme`` (a :class:`scenes.LoadedScene`)."""
    from .... import scenes
    from ....scenes.catalogue.builtin import BUILTIN_SCENES, BuiltinScene

    spec = BUILTIN_SCENES[base]
    if extreme.transform is None:
        return scenes.load(base, width=width, height=height)

    def factory(w, h, _f=spec.factory, _t=extreme.transform):
        return _t(copy.deepcopy(_f(w, h)), w, h)

    name = f"{base}~{extreme.name}"
    return scenes.load(
        BuiltinScene(name, factory, f"{spec.description}; {extreme.description}", width, height),
        width=width,
        height=height,
    )


_REF_CHANNELS = ("visibility", "coverage", "id", "normal", "position")


def reference_channels(loaded, *, spp: int, cache, quiet: bool) -> dict:
    """The oracle's channels (visibility, coverage, id, normal, position) of ``loaded`` at
    ``spp`` (seed 0): rendered, or from ``cache`` (a reference cache) when given."""
    from ...reference.render import ReferenceSettings, render_reference

    settings = ReferenceSettings(spp=spp, seed=0, channels=_REF_CHANNELS)
    if cache is None:
        channels, _ = render_reference(loaded, settings, quiet=True)
        return channels
    from ...reference.store import get_reference

    return get_reference(loaded, settings, cache=cache, quiet=quiet).channels()


def _defaults(technique_name: str) -> dict:
    """Parameter name -> default of a registered technique (its public records)."""
    from .... import raster_models

    for t in raster_models.list_techniques():
        if t["name"] == technique_name:
            return {p["name"]: p["default"] for p in t["params"]}
    raise KeyError(technique_name)


def _params_for(technique, extreme: Extreme, huge: int) -> dict | None:
    fields = _defaults(technique.name)
    if any(r not in fields for r in extreme.requires):
        return None
    out = {name: min(int(fields[name]), cap) for name, cap in CELL_CAPS.items() if name in fields}
    for k, v in extreme.params.items():
        if k in fields:
            out[k] = huge if (k == "resolution" and extreme.name == "huge_map") else v
    return out


def memory_budget() -> int:
    """Bytes one cell's model may use: half the available memory."""
    from ...reference.render import available_memory

    return available_memory() // 2


def _finite_result(res) -> bool:
    for img in res.outputs.values():
        if not np.isfinite(np.asarray(img, dtype=np.float64)).all():
            return False
    vis = res.outputs.get("visibility")
    if vis is not None and not (0.0 <= float(np.min(vis)) and float(np.max(vis)) <= 1.0):
        return False

    def ok(v) -> bool:
        if isinstance(v, dict):
            return all(ok(x) for x in v.values())
        if isinstance(v, list | tuple):
            return all(ok(x) for x in v)
        if isinstance(v, bool) or v is None or isinstance(v, str):
            return True
        return bool(np.isfinite(v))

    return ok(res.cost)


def _error(family: str, res, ref: dict, loaded) -> tuple[str, float, dict]:
    from .... import metrics as M
    from ...scoring.channels import reference_receivers

    if family != "shadow" and "coverage" in res.outputs:
        d = np.asarray(res.outputs["coverage"], np.float64) - ref["coverage"]
        return "coverage_rmse", float(np.sqrt(np.mean(d * d))), {}
    rec = reference_receivers(ref, loaded.light)
    vis = np.clip(np.asarray(res.outputs["visibility"], dtype=np.float32), 0.0, 1.0)
    sm = M.shadow_metrics(ref["visibility"], vis, receivers=rec)
    detail = {k: sm[k] for k in ("false_lit_fraction", "false_shadow_fraction", "receiver_count")}
    return "misclassified_fraction", float(sm["misclassified_fraction"]), detail


def run_cell(technique, extreme: Extreme, loaded, ref: dict, *, huge: int) -> dict:
    """Run one technique on one extreme's scene and judge the outcome against its
    expectation. Never raises for the model's own failure: it is recorded."""
    from .... import raster_models
    from ....raster_models import ModelError
    from ....raster_models import run as run_model

    family = raster_models.family_of(technique.name)
    exp = expectation(technique.name, extreme.name, family)
    metric = raster_models.family(family).extremes_metric
    cell = {
        "technique": technique.name,
        "extreme": extreme.name,
        "family": family,
        "metric": metric,
        "expected": exp.text(metric),
        "expected_short": "refused"
        if exp.refused
        else (
            f"{exp.min_error:g}..{exp.max_error:g}"
            if exp.min_error > 0
            else f"<= {exp.max_error:g}"
        ),
        "reason": exp.reason,
        "params": None,
        "status": None,
        "finite": None,
        "error": None,
        "message": None,
        "seconds": None,
    }
    if loaded.light.kind not in technique.lights:
        cell.update(status="n/a", message=f"needs a {' or '.join(technique.lights)} light")
        cell["outcome_met"] = True
        return cell
    params = _params_for(technique, extreme, huge)
    if params is None:
        cell.update(status="n/a", message=f"no parameter {', '.join(extreme.requires)}")
        cell["outcome_met"] = True
        return cell
    cell["params"] = params
    if "resolution" in params:
        # maps are rendered one at a time: the peak is one map's
        need = HUGE_BYTES_PER_TEXEL * params["resolution"] ** 2
        budget = memory_budget()
        if need > budget:
            cell.update(
                status="refused",
                message=f"a {params['resolution']}^2 map needs about {need / 2**30:.1f} GiB "
                f"(measured {HUGE_BYTES_PER_TEXEL} B/texel peak); the budget, half the "
                f"available memory, is {budget / 2**30:.1f} GiB",
            )
            cell["outcome_met"] = exp.refused or extreme.name == "huge_map"
            return cell
    t0 = time.perf_counter()
    try:
        res = run_model(technique.name, loaded, **params)
    except ModelError as exc:
        cell.update(status="refused", message=str(exc), seconds=time.perf_counter() - t0)
        cell["outcome_met"] = exp.refused and exp.match in str(exc)
        return cell
    except Exception as exc:  # an unexpected failure is a result of the matrix
        cell.update(
            status="error",
            message=one_line(exc, with_type=True),
            seconds=time.perf_counter() - t0,
        )
        cell["outcome_met"] = False
        return cell
    cell["seconds"] = time.perf_counter() - t0
    finite = _finite_result(res)
    cell["finite"] = finite
    cell["status"] = "ok" if finite else "non-finite"
    if finite:
        metric, err, detail = _error(family, res, ref, loaded)
        cell.update(metric=metric, error=err, detail=detail)
        cell["outcome_met"] = (not exp.refused) and exp.min_error <= err <= exp.max_error
    else:
        cell["outcome_met"] = False
    return cell


def run_extremes(
    out: Path | None,
    *,
    cache=None,
    quiet: bool = True,
    echo=None,
    quick: bool = True,
    techniques: list[str] | None = None,
    extremes: list[str] | None = None,
    huge: int | None = None,
) -> dict:
    """The matrix of every registered model x every extreme; writes ``out/extremes.json``.

    ``quick``: 64x36 pixels, 16-spp oracle, a 4096^2 huge map (the main job's budget:
    8192^2 alone took 2 minutes of the 4 on 2 loaded cores);
    otherwise 160x90, 64 spp and 16384^2 (refused when its measured peak memory exceeds half
    the available memory).
    """
    from .... import raster_models

    say = echo or (lambda *_: None)
    width, height, spp = (64, 36, 16) if quick else (160, 90, 64)
    huge = int(huge or (QUICK_HUGE if quick else 16384))
    techs = [raster_models.TECHNIQUES[t] for t in (techniques or raster_models.TECHNIQUES)]
    # families without an extremes scene (the temporal ones) are not in this study
    techs = [t for t in techs if raster_models.family(t.name).extremes_scene is not None]
    names = extremes or list(EXTREMES)
    t0 = time.perf_counter()
    cells, scenes_info = [], {}
    families = sorted({raster_models.TECHNIQUES[t.name].family for t in techs})
    for name in names:
        ext = EXTREMES[name]
        row = []
        scenes_info[name] = {"description": ext.description, "params": ext.params, "scenes": {}}
        for fam in families:
            base = raster_models.FAMILIES[fam].extremes_scene
            loaded = load_extreme(ext, width=width, height=height, base=base)
            ref = reference_channels(loaded, spp=spp, cache=cache, quiet=quiet)
            scenes_info[name]["scenes"][fam] = {
                "scene": loaded.name,
                "light": loaded.light.kind,
                "sky_fraction": float(np.mean(ref["id"] < 0)),
            }
            row += [
                dict(run_cell(t, ext, loaded, ref, huge=huge), scene=loaded.name)
                for t in techs
                if raster_models.TECHNIQUES[t.name].family == fam
            ]
        cells.extend(row)
        say(extreme_line(name, row))
    data = {
        "schema": "raster-oracle.studies.extremes.run/1",
        "quick": quick,
        "resolution": [width, height],
        "reference_spp": spp,
        "cell_map": CELL_MAP,
        "huge_map": huge,
        "base_scene": BASE_SCENE,
        "base_scenes": {f: raster_models.FAMILIES[f].extremes_scene for f in families},
        "extremes": scenes_info,
        "techniques": [t.name for t in techs],
        "cells": cells,
        "unexpected": _unexpected(cells),
        "wall_seconds": time.perf_counter() - t0,
    }
    if out is not None:
        write_extremes(out, data)
    return data


def _unexpected(cells: list[dict]) -> list[str]:
    return [f"{c['technique']} x {c['extreme']}" for c in cells if not c["outcome_met"]]


def extreme_line(name: str, cells: list[dict]) -> str:
    """The line an extremes run prints for one extreme's cells."""
    bad = [c["technique"] for c in cells if not c["outcome_met"]]
    return f"extremes {name:<22} {len(cells)} models" + (f"; unexpected: {bad}" if bad else "")


def merge_extremes(parts: list[dict]) -> dict:
    """One extremes record from the records of runs over parts of the extremes
    (``extremes=``), each at the same sizes and techniques: extremes and cells in the parts'
    order, seconds summed (the main job runs each extreme on a worker of its own,
    :mod:`oracle.sweeps.mainjob`)."""
    if not parts:
        raise ValueError("no extremes record to merge")
    first = parts[0]
    same = ("quick", "resolution", "reference_spp", "cell_map", "huge_map", "techniques")
    if any(p[k] != first[k] for p in parts for k in same):
        raise ValueError("extremes records at different sizes cannot be merged")
    cells = [c for p in parts for c in p["cells"]]
    data = {k: v for k, v in first.items() if k not in ("extremes", "cells", "unexpected")}
    data["base_scenes"] = {k: v for p in parts for k, v in p["base_scenes"].items()}
    data["extremes"] = {k: v for p in parts for k, v in p["extremes"].items()}
    data["cells"] = cells
    data["unexpected"] = _unexpected(cells)
    data["wall_seconds"] = sum(p["wall_seconds"] for p in parts)
    keys = list(first)  # the key order of a whole run's record
    return {k: data[k] for k in keys}


def write_extremes(out: Path, data: dict) -> None:
    """Write ``out/extremes.json`` and its page."""
    section = extremes_section(data)
    write_study(out, name="extremes", data=data, section=section, title="raster-oracle extremes")
