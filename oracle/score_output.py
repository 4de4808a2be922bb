"""Write a score folder: metrics.json, EXR and PNG error maps, report.html (+ report.json).

Everything is computed before the first file is written, and every file is written under a
temporary name and renamed, so a failed request leaves nothing half-written.
"""

from __future__ import annotations

import io
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

import metrics as M
import reports

from .exr import atomic_write_bytes, make_readable, write_exr
from .pipeline import package_versions
from .score import METRIC_KEYS, ScoreResult, failures, to_json

__all__ = ["MAP_STYLES", "write_score_folder"]

#: How each error map is drawn: palette and fixed range (the same in PNG and report).
MAP_STYLES = {
    "visibility_error": ("signed", (-1.0, 1.0)),
    "misclassified": ("signed", (-1.0, 1.0)),
    "flip": ("magma", (0.0, 1.0)),
    "delta_e2000": ("magma", (0.0, 20.0)),
    "neg_log10_p": ("magma", (0.0, 10.0)),
}


def _png_bytes(image) -> bytes:
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def _display(result: ScoreResult, image: np.ndarray) -> np.ndarray:
    """What the report shows: visibility as is, colour through the shared tone mapper."""
    if image.ndim == 2:
        return np.clip(image, 0.0, 1.0)
    tm = result.record.get("tone_mapping") or {}
    return M.tonemap(image, exposure=tm.get("exposure_stops") or 0.0)


def _case(
    result: ScoreResult, *, name: str, scene: str, thresholds: dict, technique, params, cost
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
    values = {k: record[k] for k in METRIC_KEYS if record.get(k) is not None}
    return reports.make_case(
        name=name,
        scene=scene,
        reference=_display(result, frame.reference),
        candidate=_display(result, frame.candidate),
        kind=record["channel"],
        metrics=values,
        error_maps=maps,
        noise_floor=record.get("noise_floor") or None,
        thresholds={k: v for k, v in thresholds.items() if k in values} or None,
        cost=cost,
        technique=technique,
        family=_family(technique, scene),
        params=params,
        exr_links={
            "reference": "reference.exr",
            "candidate": "candidate.exr",
            "error maps": "error_maps.exr",
        },
    )


def _family(technique: str | None, scene: str) -> str | None:
    """Pareto fronts compare techniques of one family on one scene."""
    if technique is None:
        return None
    family = "shadow maps" if technique in ("shadow-map", "csm", "sdsm") else technique
    return f"{family} on {scene}"


def provenance(result: ScoreResult, loaded) -> dict:
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
    thresholds: dict,
    technique=None,
    params=None,
    cost=None,
) -> list[str]:
    """Write the score folder; returns the metrics that exceed their thresholds."""
    record = dict(result.record)
    record["thresholds"] = thresholds
    record["failed"] = failures(record, thresholds)
    record["technique"] = technique
    record["params"] = params
    record["cost"] = cost
    record["maps"] = {
        k: {"exr": f"error_maps.exr:{k}", "png": f"{k}.png"} for k in result.frames[0].maps
    }
    frame = result.frames[0]
    case = _case(
        result,
        name=name,
        scene=loaded.name,
        thresholds=thresholds,
        technique=technique,
        params=params,
        cost=cost,
    )
    report = reports.build_report(
        [case], title=f"{name} on {loaded.name}", provenance=provenance(result, loaded)
    )
    pngs = {}
    for key, data in frame.maps.items():
        style, rng = MAP_STYLES[key]
        pngs[f"{key}.png"] = _png_bytes(
            reports.colorize(np.nan_to_num(data), style=style, value_range=rng)
        )
    cand = frame.candidate
    cand_channels = (
        {"visibility": cand}
        if cand.ndim == 2
        else {f"color.{c}": cand[..., i] for i, c in enumerate("RGB")}
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    write_exr(out_dir / "candidate.exr", cand_channels)
    write_exr(out_dir / "error_maps.exr", {k: np.nan_to_num(v) for k, v in frame.maps.items()})
    fd, tmp = tempfile.mkstemp(prefix=".reference.", suffix=".exr", dir=out_dir)
    os.close(fd)
    shutil.copyfile(result.reference_folders[0] / "reference.exr", tmp)
    make_readable(tmp)
    os.replace(tmp, out_dir / "reference.exr")
    for fname, data in pngs.items():
        atomic_write_bytes(out_dir / fname, data)
    atomic_write_bytes(out_dir / "metrics.json", to_json(record))
    reports.write_report(report, out_dir / "report.html")
    return record["failed"]
