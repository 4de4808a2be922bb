"""Numerical extremes: every registered model x every extreme, against the oracle.

Each extreme is a transformation of a built-in scene's dictionary (the ``plate``: one clean
hard shadow under a directional light) plus, for some, parameter overrides; the transformed
scene is loaded once and rendered by the oracle and by every model alike. A cell of the
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
import fnmatch
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "DEFAULTS",
    "DEFAULT_AA_EXPECTATION",
    "DEFAULT_EXPECTATION",
    "EXPECTATIONS",
    "EXTREMES",
    "Expectation",
    "Extreme",
    "HUGE_BYTES_PER_TEXEL",
    "expectation",
    "load_extreme",
    "run_cell",
    "run_extremes",
]

BASE_SCENE = "plate"
#: Base scene of each technique family: shadow models get the plate's clean hard shadow,
#: anti-aliasing models the Siemens star's edges against the sky (coverage to get wrong).
BASE_SCENES = {"shadow": "plate", "aa": "star"}
#: Offset of the far-from-the-origin extreme (float32 positions there are 7.8 mm apart).
FAR_OFFSET = 1e5
#: Elevation of the grazing light above the ground, degrees.
GRAZING_DEG = 2.0
#: Peak resident bytes per shadow-map texel of the current models, measured: a 16384^2
#: ``shadow-map`` peaks at 8.8 GB (float64 hit depths and masks beside the float32 map).
HUGE_BYTES_PER_TEXEL = 33
#: Huge-map size in quick mode (the main job): 8192^2 cost 2 of the 4 minutes of extremes and
#: claims together on 2 loaded cores (izb's 8192^2 grid alone 60 s).
QUICK_HUGE = 4096
#: Largest shadow-map resolution a cell uses unless its extreme sets one (fast, and fine
#: enough for the plate's 2-unit caster); a technique whose default is lower keeps it.
CELL_MAP = 512
#: Work caps of every cell (a parameter's default is kept when lower): map resolution, and
#: the number of coherent shadow maps (256 = 4^4, ~8 degrees apart; 1024 costs 4x).
CELL_CAPS = {"resolution": CELL_MAP, "directions": 256}


@dataclass(frozen=True)
class Extreme:
    """One extreme: a scene transformation and/or parameter overrides.

    ``transform(raw, width, height) -> raw`` edits a copy of the base scene's dictionary;
    ``params`` are applied to every technique that has each parameter; ``requires`` names
    parameters without which the extreme does not apply to a technique (its cell is "n/a").
    """

    name: str
    description: str
    transform: Callable[[dict, int, int], dict] | None = None
    params: dict = field(default_factory=dict)
    requires: tuple[str, ...] = ()


@dataclass(frozen=True)
class Expectation:
    """What a cell should show. ``refused``: the run raises the package's error with a
    message containing ``match``; otherwise outputs are finite and ``error <= max_error``
    (and ``>= min_error``, for documented failures that must show)."""

    max_error: float = 0.05
    min_error: float = 0.0
    refused: bool = False
    match: str = ""
    reason: str = ""

    def text(self, metric: str) -> str:
        if self.refused:
            return f"refused ({self.match})"
        lo = f"{self.min_error:g} <= " if self.min_error > 0 else ""
        return f"finite, {lo}{metric} <= {self.max_error:g}"


# ----------------------------------------------------------------------- transformations
def _sensor(raw: dict) -> dict:
    return next(v for v in raw.values() if isinstance(v, dict) and v.get("type") == "perspective")


def _sun(raw: dict) -> dict:
    return next(v for v in raw.values() if isinstance(v, dict) and v.get("type") == "directional")


def _translate(raw: dict, offset) -> dict:
    o = np.asarray(offset, dtype=np.float64)
    for v in raw.values():
        if not isinstance(v, dict):
            continue
        if v.get("type") == "ro_mesh":
            v["vertices"] = np.asarray(v["vertices"], dtype=np.float64) + o
        elif "to_world" in v:
            m = np.array(v["to_world"], dtype=np.float64)
            m[:3, 3] += o
            v["to_world"] = m
        for key in ("center", "p0", "p1", "position"):
            if key in v:
                v[key] = [float(a + b) for a, b in zip(v[key], o, strict=True)]
    return raw


def _far(raw, w, h):
    return _translate(raw, (FAR_OFFSET, 0.0, FAR_OFFSET))


def _far_near(raw, w, h):
    cam = _sensor(raw)
    cam["near_clip"] = float(cam["far_clip"]) / 1e6
    return raw


def _grazing(raw, w, h):
    sun = _sun(raw)
    d = np.asarray(sun["direction"], dtype=np.float64)
    horiz = np.array([d[0], 0.0, d[2]]) / math.hypot(d[0], d[2])
    e = math.radians(GRAZING_DEG)
    sun["direction"] = [float(c) for c in horiz * math.cos(e) + np.array([0, -math.sin(e), 0])]
    return raw


def _parallel_view(raw, w, h):
    fwd = np.asarray(_sensor(raw)["to_world"], dtype=np.float64)[:3, 2]
    _sun(raw)["direction"] = [float(c) for c in fwd / np.linalg.norm(fwd)]
    return raw


def _parallel_up(raw, w, h):
    _sun(raw)["direction"] = [0.0, -1.0, 0.0]
    return raw


def _in_wall(raw, w, h):
    from scenes import _meshes
    from scenes.builtin import _mesh

    p = np.asarray(_sensor(raw)["to_world"], dtype=np.float64)[:3, 3]
    raw["wall"] = _mesh(_meshes.box(p - 0.5, p + 0.5), 0.5)
    return raw


def _all_sky(raw, w, h):
    from scenes.builtin import _look_at

    cam = _sensor(raw)
    p = np.asarray(cam["to_world"], dtype=np.float64)[:3, 3]
    cam["to_world"] = _look_at(p, p + np.array([0.0, 1.0, 0.0]), (0.0, 0.0, 1.0))
    return raw


def _degenerate(raw, w, h):
    for v in raw.values():
        if isinstance(v, dict) and v.get("type") == "ro_mesh":
            verts = np.asarray(v["vertices"], dtype=np.float64)
            faces = np.asarray(v["faces"], dtype=np.uint32)
            n = len(verts)
            mid = 0.5 * (verts[0] + verts[1])
            extra = np.array(
                [[0, 0, 1], [1, 2, 2], [0, 0, 0], [0, n, 1]], dtype=np.uint32
            )  # repeated vertices, a point, collinear (a vertex midway along an edge)
            v["vertices"] = np.vstack([verts, mid])
            v["faces"] = np.vstack([faces, extra])
    return raw


def _far_1e4(raw, w, h):
    cam = _sensor(raw)
    cam["far_clip"] = 1e4
    return _translate(raw, (1e4, 0.0, 1e4))


EXTREMES: dict[str, Extreme] = {
    e.name: e
    for e in (
        Extreme("baseline", "the plate scene as built in (the reference row)"),
        Extreme("far_1e5", "scene and camera moved 1e5 units from the origin", _far),
        Extreme("far_near_1e6", "near plane at far/1e6 (1e-4 for far = 100)", _far_near),
        Extreme("grazing_light", f"sun {GRAZING_DEG:g} degrees above the ground", _grazing),
        Extreme("light_parallel_view", "sun along the camera's view direction", _parallel_view),
        Extreme("light_parallel_up", "sun straight down, parallel to world up", _parallel_up),
        Extreme("camera_in_wall", "the camera inside a closed 1-unit box", _in_wall),
        Extreme("all_sky", "the camera looks straight up: every pixel is sky", _all_sky),
        Extreme(
            "degenerate_triangles",
            "each mesh gets zero-area triangles (repeated vertices, a point, collinear)",
            _degenerate,
        ),
        Extreme(
            "far_1e4",
            "1e4 from the origin with the far plane at 1e4 (the float32 row's float64 control)",
            _far_1e4,
        ),
        Extreme(
            "float32_matrices",
            "1e4 from the origin, far plane 1e4, float32 matrices and a combined "
            "view-projection inverse (TheRealMJP/Shadows #6)",
            _far_1e4,
            {"matrix_precision": "float32", "view_projection_inverse": "combined"},
            ("matrix_precision", "view_projection_inverse"),
        ),
        Extreme("tiny_map", "8x8 shadow maps", None, {"resolution": 8}, ("resolution",)),
        Extreme(
            "huge_map",
            "16384^2 shadow map (one partition; 4096^2 in quick mode)",
            None,
            {"resolution": 16384, "partitions": 1},
            ("resolution",),
        ),
    )
}

#: The default expectation of a shadow model's cell without an override.
DEFAULT_EXPECTATION = Expectation(
    0.05,
    reason="default: finite, and at most 5% of receivers misclassified at <= 512^2 maps",
)
#: The default expectation of an anti-aliasing model's cell without an override.
DEFAULT_AA_EXPECTATION = Expectation(
    0.3,
    reason="default (anti-aliasing): finite, and coverage RMSE on the star no worse than one "
    "sample per pixel (the 1x straight-edge floor is 0.25 RMS an edge pixel, TECHNIQUES.md)",
)
DEFAULTS = {"shadow": DEFAULT_EXPECTATION, "aa": DEFAULT_AA_EXPECTATION}
_ACNE = (
    "acne: a constant bias of 0.005 in normalized light depth cannot cover the depth slope "
    "of a receiver lit at 2 degrees (false shadow; slope-scaled, receiver-plane or normal-offset "
    "bias fix it, tests/test_models_extremes.py)"
)
_TINY = "8x8 texels over the fitted region: the plate's shadow is a few texels, blocky and "
#: Overrides: (technique pattern, extreme) -> expectation (fnmatch patterns, first match).
#: Bands hold at the quick size (64x36, 16 spp) and the full size (160x90, 64 spp); the
#: measured values of both are in the README's extremes table.
EXPECTATIONS: list[tuple[str, str, Expectation]] = [
    (
        "*",
        "all_sky",
        Expectation(0.0, reason="no receivers and no coverage: the error is exactly 0"),
    ),
    ("csm", "grazing_light", Expectation(0.6, 0.1, reason=_ACNE)),
    ("coherent-shadow-map", "grazing_light", Expectation(0.6, 0.1, reason=_ACNE)),
    (
        "shadow-map",
        "camera_in_wall",
        Expectation(
            0.25,
            0.02,
            reason="one map fit to the whole 30-unit scene: 0.06-unit texels on a 1-unit box "
            "seen from 0.5 units (pixels 64x smaller): the box's shadow edges are undersampled "
            "(false lit)",
        ),
    ),
    (
        "csm",
        "camera_in_wall",
        Expectation(
            0.12,
            reason="cascades fit to frustum slices (0.1..100): the first slice still spans the "
            "scene, so texels are coarse for a box 0.5 units away (false lit)",
        ),
    ),
    (
        "coherent-shadow-map",
        "camera_in_wall",
        Expectation(
            0.25,
            0.02,
            reason="maps over the scene's bounding sphere at 128^2 and 256 directions: coarse "
            "texels and ~13-degree direction steps on the box's inner walls (false lit)",
        ),
    ),
    *(
        (
            "csm",
            ext,
            Expectation(
                0.12,
                reason="far plane 1e4: practical splits (lambda 0.5) give the first cascade "
                "a depth range of hundreds of units, so the plate's shadow is coarse (false "
                "lit); the same with float64 and float32 matrices",
            ),
        )
        for ext in ("far_1e4", "float32_matrices")
    ),
    (
        "sdsm",
        "float32_matrices",
        Expectation(
            0.1,
            0.01,
            reason="float32 matrices and a combined view-projection inverse 1e4 from the "
            "origin: the reconstructed receiver positions are off by millimetres, enough to "
            "misplace the tight partitions' shadow edges (float64 control: 0.002)",
        ),
    ),
    *(
        (tech, "tiny_map", Expectation(0.6, 0.1, reason=_TINY + "mostly false shadow"))
        for tech in ("shadow-map", "csm", "coherent-shadow-map")
    ),
    (
        "sdsm",
        "tiny_map",
        Expectation(
            0.15,
            0.01,
            reason="8x8 texels, but fit tightly to the visible samples of each partition: "
            "only the shadow's outline is wrong",
        ),
    ),
    (
        "coherent-shadow-map",
        "huge_map",
        Expectation(
            refused=True,
            match="resolution",
            reason="the model refuses maps above 4096^2 (and directions x r^2 above 2^25 "
            "texels when compressing) with a message naming the parameter",
        ),
    ),
    (
        "coherent-shadow-map",
        "*",
        Expectation(
            0.05,
            reason="256 directions (~13 degrees apart) move the shadow by the direction "
            "quantization: a few percent of receivers",
        ),
    ),
    *(
        (
            tech,
            "*",
            Expectation(
                0.13 if tech == "ssaa" else 0.1,
                reason=f"{n} samples on the star's edges: about the {n}x straight-edge floor "
                f"({floor} RMS an edge pixel, TECHNIQUES.md) plus the 16-spp oracle's noise",
            ),
        )
        for tech, n, floor in (
            ("ssaa", 4, 0.092),
            ("msaa", 8, 0.057),
            ("acaa", 8, 0.057),
            ("agaa", 8, 0.057),
        )
    ),
    (
        "izb",
        "*",
        Expectation(
            0.01,
            reason="one exact shadow-volume test per pixel centre: only the oracle's "
            "supersampled edge pixels differ",
        ),
    ),
]


def expectation(technique: str, extreme: str, family: str = "shadow") -> Expectation:
    """The expectation of a cell: the first override whose patterns match, else the
    family's default."""
    for pattern, ext, exp in EXPECTATIONS:
        if fnmatch.fnmatchcase(extreme, ext) and fnmatch.fnmatchcase(technique, pattern):
            return exp
    return DEFAULTS.get(family, DEFAULT_EXPECTATION)


# ----------------------------------------------------------------------- running
def load_extreme(extreme: Extreme, *, width: int, height: int, base: str = BASE_SCENE):
    """The base scene transformed by ``extreme`` (a :class:`scenes.LoadedScene`)."""
    import scenes
    from scenes.builtin import BUILTIN_SCENES, BuiltinScene

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


def _reference(loaded, *, spp: int, cache, quiet: bool) -> dict:
    from .reference import ReferenceSettings, render_reference

    settings = ReferenceSettings(spp=spp, seed=0, channels=_REF_CHANNELS)
    if cache is None:
        channels, _ = render_reference(loaded, settings, quiet=True)
        return channels
    from .pipeline import get_reference

    return get_reference(loaded, settings, cache=cache, quiet=quiet).channels()


def _family(technique) -> str:
    return getattr(technique, "family", "shadow")


def _params_for(technique, extreme: Extreme, huge: int) -> dict | None:
    from raster_models import _params

    fields = {f.name: f for f in _params._fields(technique.params)}
    if any(r not in fields for r in extreme.requires):
        return None
    out = {
        name: min(int(fields[name].default), cap)
        for name, cap in CELL_CAPS.items()
        if name in fields
    }
    for k, v in extreme.params.items():
        if k in fields:
            out[k] = huge if (k == "resolution" and extreme.name == "huge_map") else v
    return out


def memory_budget() -> int:
    """Bytes one cell's model may use: half the available memory."""
    from .reference import available_memory

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
    import metrics as M

    from .score import _receivers

    if family == "aa" and "coverage" in res.outputs:
        d = np.asarray(res.outputs["coverage"], np.float64) - ref["coverage"]
        return "coverage_rmse", float(np.sqrt(np.mean(d * d))), {}
    rec = _receivers(ref, loaded.light)
    vis = np.clip(np.asarray(res.outputs["visibility"], dtype=np.float32), 0.0, 1.0)
    sm = M.shadow_metrics(ref["visibility"], vis, receivers=rec)
    detail = {k: sm[k] for k in ("false_lit_fraction", "false_shadow_fraction", "receiver_count")}
    return "misclassified_fraction", float(sm["misclassified_fraction"]), detail


def run_cell(technique, extreme: Extreme, loaded, ref: dict, *, huge: int) -> dict:
    """Run one technique on one extreme's scene and judge the outcome against its
    expectation. Never raises for the model's own failure: it is recorded."""
    from raster_models import ModelError
    from raster_models import run as run_model

    family = _family(technique)
    exp = expectation(technique.name, extreme.name, family)
    metric = "coverage_rmse" if family == "aa" else "misclassified_fraction"
    cell = {
        "technique": technique.name,
        "extreme": extreme.name,
        "family": family,
        "metric": metric,
        "expected": exp.text(metric),
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
            message=f"{type(exc).__name__}: {exc}",
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
    import raster_models

    say = echo or (lambda *_: None)
    width, height, spp = (64, 36, 16) if quick else (160, 90, 64)
    huge = int(huge or (QUICK_HUGE if quick else 16384))
    techs = [raster_models.TECHNIQUES[t] for t in (techniques or raster_models.TECHNIQUES)]
    names = extremes or list(EXTREMES)
    t0 = time.perf_counter()
    cells, scenes_info = [], {}
    families = sorted({_family(t) for t in techs})
    for name in names:
        ext = EXTREMES[name]
        row = []
        scenes_info[name] = {"description": ext.description, "params": ext.params, "scenes": {}}
        for fam in families:
            base = BASE_SCENES.get(fam, BASE_SCENE)
            loaded = load_extreme(ext, width=width, height=height, base=base)
            ref = _reference(loaded, spp=spp, cache=cache, quiet=quiet)
            scenes_info[name]["scenes"][fam] = {
                "scene": loaded.name,
                "light": loaded.light.kind,
                "sky_fraction": float(np.mean(ref["id"] < 0)),
            }
            row += [
                dict(run_cell(t, ext, loaded, ref, huge=huge), scene=loaded.name)
                for t in techs
                if _family(t) == fam
            ]
        cells.extend(row)
        bad = [c["technique"] for c in row if not c["outcome_met"]]
        say(f"extremes {name:<22} {len(row)} models" + (f"; unexpected: {bad}" if bad else ""))
    data = {
        "schema": "raster-oracle.extremes/1",
        "quick": quick,
        "resolution": [width, height],
        "reference_spp": spp,
        "cell_map": CELL_MAP,
        "huge_map": huge,
        "base_scene": BASE_SCENE,
        "base_scenes": dict(BASE_SCENES),
        "extremes": scenes_info,
        "techniques": [t.name for t in techs],
        "cells": cells,
        "unexpected": [f"{c['technique']} x {c['extreme']}" for c in cells if not c["outcome_met"]],
        "wall_seconds": time.perf_counter() - t0,
    }
    if out is not None:
        from .exr import atomic_write_bytes

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(out / "extremes.json", json.dumps(data, indent=2).encode())
        from reports._extremes import render_extremes_page

        atomic_write_bytes(out / "extremes.html", render_extremes_page(data).encode())
    return data
