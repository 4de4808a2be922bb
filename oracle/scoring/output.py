"""Write a score folder: metrics.json, EXR and PNG error maps, report.html (+ report.json).

Everything is computed before the first file is written, and every file is written under a
temporary name and renamed, so a failed request leaves nothing half-written.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from ... import metrics as M
from ... import raster_models, reports
from ...scenes.base.files import atomic_copy, atomic_write_bytes, atomic_write_json
from ...scenes.base.records import jsonable, package_versions
from ..reference.exr import read_exr, write_exr
from .ci.checks import Gate, Verdict
from .result import ScoreResult

__all__ = [
    "MAP_STYLES",
    "MEMORY_RESOLUTIONS",
    "SCORE_FILES",
    "report_cost",
    "stale_files",
    "write_score_folder",
]

#: How each error map is drawn: palette and fixed range (the same in PNG and report).
MAP_STYLES = {
    "visibility_error": ("signed", (-1.0, 1.0)),
    "misclassified": ("signed", (-1.0, 1.0)),
    "coverage_error": ("signed", (-1.0, 1.0)),
    "flip": ("magma", (0.0, 1.0)),
    "delta_e2000": ("magma", (0.0, 20.0)),
    "neg_log10_p": ("magma", (0.0, 10.0)),
    # temporal AA (oracle.scoring.temporal): added change per frame, motion-vector error in px
    "flicker": ("magma", (0.0, 0.1)),
    "conformance_error": ("signed", (-1.0, 1.0)),
    "motion_epe": ("magma", (0.0, 2.0)),
    # linear view depth (oracle.scoring.channels): relative error, 5 % at full scale
    "depth_rel_error": ("magma", (0.0, 0.05)),
}


def _png_bytes(image) -> bytes:
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def _display(result: ScoreResult, image: np.ndarray) -> np.ndarray:
    """What the report shows: visibility as is, colour through the shared tone mapper, a
    view depth over the reference's farthest (sky 0, the farthest surface 1)."""
    if result.record["channel"] == "depth":
        top = float(np.max(result.frames[0].reference))
        return np.clip(image / top, 0.0, 1.0) if top > 0 else np.zeros_like(image)
    if image.ndim == 2:
        return np.clip(image, 0.0, 1.0)
    tm = result.record.get("tone_mapping") or {}
    return M.tonemap(image, exposure=tm.get("exposure_stops") or 0.0)


def _bounds(gates: list[Gate]) -> dict:
    """The report's thresholds: ``metric -> {"max": V}`` (``--fail-above``) and/or
    ``{"min": V}`` (``--fail-below``)."""
    out: dict = {}
    for g in gates:
        out.setdefault(g.metric, {})["max" if g.op == "<=" else "min"] = g.limit
    return out


def _viewer(result: ScoreResult, maps: dict) -> dict:
    """The linear frames for the report's pixel viewer: reference, candidate, the reference's
    stderr (read back from each frame's reference EXR), one error map, the metrics."""
    color = result.record["channel"] == "color"
    # colour: FLIP; visibility and coverage: the signed error, which reads best under a cursor
    order = ("flip",) if color else ("visibility_error", "coverage_error", "flip")
    shown = next(k for k in (*order, *maps) if k in maps)
    style, rng = MAP_STYLES[shown]
    stderr_key = f"{result.record['channel']}_stderr"
    frames = []
    for k, frame in enumerate(result.frames):
        ch = read_exr(result.reference_folders[k] / "reference.exr")
        if color:
            se = np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1)
        else:  # a depth has none: the view depth at the pixel centre is exact
            se = ch[stderr_key] if stderr_key in ch else np.zeros_like(frame.reference)
        frames.append(
            {
                "label": f"frame {k + 1}",
                "metrics": frame.metrics,
                "reference": frame.reference,
                "candidate": frame.candidate,
                "stderr": se,
                "error": frame.maps[shown],
            }
        )
    tm = result.record.get("tone_mapping") or {}
    return reports.viewer_record(
        frames,
        error_name=shown,
        error_style=style,
        error_range=rng,
        exposure=tm.get("exposure_stops") or 0.0,
        tone_mapper=tm.get("tone_mapper", "clip"),
        srgb=color,
    )


def _case(
    result: ScoreResult,
    *,
    name: str,
    scene: str,
    thresholds: dict,
    technique,
    params,
    cost,
    checks=(),
) -> dict:
    frame = result.frames[0]
    maps = {}
    for key, data in frame.maps.items():
        style, rng = MAP_STYLES[key]
        maps[key] = {
            "data": np.nan_to_num(data).astype(np.float32),
            "style": style,
            "range": list(rng),
            "primary": key in ("visibility_error", "flip")
            and (key == "visibility_error" or "visibility_error" not in frame.maps),
        }
    record = result.record
    # every catalogue metric the record holds (the on-request conformance ones too)
    values = {k: record[k] for k in M.CATALOG if record.get(k) is not None}
    if not values and record.get("support"):
        values = {"support": 0}  # nothing was scored (no receiver in view): shown as such
    return reports.make_case(
        name=name,
        scene=scene,
        reference=_display(result, frame.reference),
        candidate=_display(result, frame.candidate),
        # a coverage mask is (H, W) data in [0, 1]: drawn as visibility images are
        kind="color" if record["channel"] == "color" else "visibility",
        metrics=values,
        error_maps=maps,
        noise_floor=record.get("noise_floor") or None,
        thresholds={k: v for k, v in thresholds.items() if k in values} or None,
        # the noise floor is judged in each metric's direction (a low SSIM is not "within")
        directions={k: M.CATALOG[k].direction for k in values if k in M.CATALOG},
        cost=report_cost(cost, technique),
        technique=technique,
        family=_front(technique, scene),
        params=params,
        exr_links={
            "reference": "reference.exr",
            "candidate": "candidate.exr",
            "error maps": "error_maps.exr",
        },
        viewer=_viewer(result, maps),
        checks=[c.as_record() for c in checks],
        # the likely causes, then an engine colour's worst shapes and gain-corrected metrics
        diagnoses=[d["message"] for d in result.record.get("diagnoses") or []]
        + list((result.record.get("colour_causes") or {}).get("details") or []),
    )


def _frame_cases(result: ScoreResult, *, name: str, scene: str, technique, params) -> list:
    """One report case per frame of a multi-frame score (its own metrics, images and error
    maps), after the case of the averaged metrics: the report shows every frame."""
    if len(result.frames) < 2:
        return []
    cases = []
    for k, frame in enumerate(result.frames):
        primary = "visibility_error" if "visibility_error" in frame.maps else "flip"
        maps = {
            key: {
                "data": np.nan_to_num(data).astype(np.float32),
                "style": MAP_STYLES[key][0],
                "range": list(MAP_STYLES[key][1]),
                "primary": key == primary,
            }
            for key, data in frame.maps.items()
        }
        values = {k2: v for k2, v in frame.metrics.items() if k2 in M.CATALOG and v is not None}
        values = values or {"support": 0}  # nothing scored in this frame
        case = reports.make_case(
            name=f"{name} frame {k}",
            scene=scene,
            reference=_display(result, frame.reference),
            candidate=_display(result, frame.candidate),
            kind="color" if result.record["channel"] == "color" else "visibility",
            metrics=values,
            error_maps=maps,
            technique=technique,
            params=params,
        )
        # a frame of a multi-frame case: shown after it, not counted as a case of its own
        case["frame"] = k
        cases.append(case)
    return cases


#: Files a score folder holds besides the error-map PNGs (``report.json`` is the report's twin).
SCORE_FILES = (
    "metrics.json",
    "report.html",
    "report.json",
    "candidate.exr",
    "error_maps.exr",
    "reference.exr",
)


def stale_files(out_dir: Path, written: list[str]) -> list[Path]:
    """Files an earlier score wrote to ``out_dir`` that this one does not rewrite.

    An earlier run's files are those its ``metrics.json`` lists under ``files`` (or, for a
    record written before that list existed, its fixed files and error-map PNGs). Only those
    are ever removed: a file the oracle did not write (a note, the engine's own render) is
    kept, so pointing ``--out`` at a folder that holds other files is safe.
    """
    try:
        prev = json.loads((out_dir / "metrics.json").read_text())
    except (OSError, ValueError):
        return []
    if not isinstance(prev, dict):
        return []
    listed = prev.get("files")
    if not isinstance(listed, list):
        maps = prev.get("maps") if isinstance(prev.get("maps"), dict) else {}
        listed = [*SCORE_FILES, *(f"{k}.png" for k in maps)]
    keep = set(written)
    out = []
    for entry in listed:
        # only plain names of this folder: a record cannot point outside it
        if isinstance(entry, str) and entry == Path(entry).name and entry not in keep:
            path = out_dir / entry
            if path.is_file() and not path.is_symlink():
                out.append(path)
    return out


def _front(technique: str | None, scene: str) -> str | None:
    """The report's group of a case: Pareto fronts compare techniques of one group on one
    scene (the shadow maps together, the anti-aliasing techniques together, others alone)."""
    if technique is None:
        return None
    return f"{raster_models.front_group(technique)} on {scene}"


#: Resolutions at which the report restates an anti-aliasing model's framebuffer memory: the
#: AGAA seed slides' 1280x736 (41 / 71 / 112 MB for 1 aggregate / 2 aggregates / deferred 8x)
#: and 1080p.
MEMORY_RESOLUTIONS = ((1280, 736), (1920, 1080))


def report_cost(cost: dict | None, technique: str | None) -> dict | None:
    """The cost entries the report shows: numbers, per-buffer bytes, restated memory.

    Lists (histograms) stay in ``metrics.json`` only; a ``name -> number`` dict such as
    ``framebuffer_bytes_by_buffer`` becomes one entry per buffer (``"color framebuffer_bytes"``).
    For the anti-aliasing family, whose buffers are all per pixel or per sample, the model's
    ``framebuffer_bytes`` at its ``width`` x ``height`` is restated at each of
    :data:`MEMORY_RESOLUTIONS` as ``framebuffer_WxH_bytes`` (bytes per pixel times pixels;
    only when the bytes are a whole number per pixel, i.e. the accounting is per pixel).
    """
    if cost is None:
        return None
    out = {}
    for key, value in cost.items():
        if isinstance(value, bool):
            continue
        if isinstance(value, int | float | np.integer | np.floating) and np.isfinite(value):
            out[key] = value
        elif isinstance(value, dict):
            stem = key.split("_by_")[0]
            for sub, v in value.items():
                if isinstance(v, int | float | np.integer | np.floating) and np.isfinite(v):
                    out[f"{sub} {stem}"] = v
    if technique is not None and raster_models.family(technique).per_pixel_memory:
        total, w, h = cost.get("framebuffer_bytes"), cost.get("width"), cost.get("height")
        if all(isinstance(v, int | np.integer) and v > 0 for v in (total, w, h)):
            per_pixel, rest = divmod(int(total), int(w) * int(h))
            if rest == 0:
                for rw, rh in MEMORY_RESOLUTIONS:
                    out[f"framebuffer_{rw}x{rh}_bytes"] = per_pixel * rw * rh
    return out


def _provenance(result: ScoreResult, loaded) -> dict:
    """The report's provenance table: scene, reference, tone mapping, backend, versions."""
    ref = result.record["reference"]
    tm = result.record.get("tone_mapping") or {}
    return {
        "scene": loaded.name,
        "scene source": loaded.source,
        "scene hash": loaded.content_hash[:16],
        "light": f"{loaded.light_index}: {loaded.light.kind}",
        "resolution": f"{loaded.width}x{loaded.height}",
        "reference spp": ref["spp"],
        "seed": ref["seed"],
        "filter": ref["filter"],
        # coverage scores: exact (analytic) truth, Monte Carlo, or exact where valid
        "coverage truth": ref.get("coverage_truth"),
        "ppd": result.record["ppd"],
        "exposure (stops)": tm.get("exposure_stops"),
        "tone mapper": tm.get("tone_mapper", "none (visibility is data)"),
        "backend": ref["variant"],
        "versions": package_versions(),
        "score seconds": round(result.record["wall_seconds"], 3),
    }


def write_score_folder(
    result: ScoreResult,
    out_dir: Path,
    *,
    loaded,
    name: str,
    gates: list[Gate] = (),
    verdict: Verdict | None = None,
    technique=None,
    params=None,
    cost=None,
) -> dict:
    """Write the score folder; returns the ``metrics.json`` record written.

    ``gates`` and ``verdict`` (their checks and the baseline's, judged by the caller) are
    recorded in ``metrics.json``: ``thresholds`` (``--fail-above`` limits), ``fail_below``,
    ``gates`` (every check: name, kind, metric, pass, line, value, limit, noise floor, the
    baseline's value and floor), ``failed`` (the names of the failed checks, gates and
    regressions alike: ``visibility_mae <= 0.02``, ``baseline ssim``), ``regressions``
    (metrics worse than the baseline) and ``exit_code``. The report's case carries the same
    checks, so its status and first screen say what the exit code says.
    """
    record = dict(result.record)
    checks = verdict.checks if verdict is not None else []
    record["thresholds"] = {g.metric: g.limit for g in gates if g.op == "<="}
    record["fail_below"] = {g.metric: g.limit for g in gates if g.op == ">="}
    record["gates"] = [c.as_record() for c in checks]
    # one verdict: the names of every failed check, gates and baseline regressions alike
    # (the names JUnit, the report and the printed lines use)
    record["failed"] = [c.name for c in checks if not c.passed]
    record["regressions"] = [c.metric for c in checks if not c.passed and c.kind == "baseline"]
    record["exit_code"] = 1 if record["failed"] else 0
    record["technique"] = technique
    record["params"] = params
    record["cost"] = cost
    restated = {
        k: v
        for k, v in (report_cost(cost, technique) or {}).items()
        if k.startswith("framebuffer_")
        and k[len("framebuffer_") : len("framebuffer_") + 1].isdigit()
    }
    if restated:
        # the model's own memory accounting at the seed slides' resolutions (see report_cost)
        record["framebuffer_bytes_restated"] = restated
    record["maps"] = {
        k: {"exr": f"error_maps.exr:{k}", "png": f"{k}.png"} for k in result.frames[0].maps
    }
    record = jsonable(record)  # a record JSON cannot hold fails here, before any file
    frame = result.frames[0]
    case = _case(
        result,
        name=name,
        scene=loaded.name,
        thresholds=_bounds(list(gates)),
        technique=technique,
        params=params,
        cost=cost,
        checks=checks,
    )
    frame_cases = _frame_cases(
        result, name=name, scene=loaded.name, technique=technique, params=params
    )
    report = reports.build_report(
        [case, *frame_cases],
        title=f"{name} on {loaded.name}",
        provenance=_provenance(result, loaded),
    )
    pngs = {}
    for key, data in frame.maps.items():
        style, rng = MAP_STYLES[key]
        pngs[f"{key}.png"] = _png_bytes(
            reports.colorize(np.nan_to_num(data), style=style, value_range=rng)
        )
    record["files"] = sorted([*SCORE_FILES, *pngs])
    stale = stale_files(out_dir, record["files"])
    cand = frame.candidate
    cand_channels = (
        {"coverage" if record["channel"] == "coverage" else "visibility": cand}
        if cand.ndim == 2
        else {f"color.{c}": np.ascontiguousarray(cand[..., i]) for i, c in enumerate("RGB")}
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    write_exr(out_dir / "candidate.exr", cand_channels)
    write_exr(out_dir / "error_maps.exr", {k: np.nan_to_num(v) for k, v in frame.maps.items()})
    atomic_copy(result.reference_folders[0] / "reference.exr", out_dir / "reference.exr")
    for fname, data in pngs.items():
        atomic_write_bytes(out_dir / fname, data)
    atomic_write_json(out_dir / "metrics.json", record)
    reports.write_report(report, out_dir / "report.html")
    for path in stale:  # after every new file is in place: a failed run removes nothing
        path.unlink(missing_ok=True)
    return record
