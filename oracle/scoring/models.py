"""Run a technique model and write ``output.exr`` + ``model.json``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ... import raster_models
from ...scenes.base.files import atomic_write_json
from ...scenes.base.records import jsonable
from ..reference.exr import write_exr

__all__ = ["output_channels", "run_model_to_folder"]


def output_channels(outputs: dict) -> dict[str, np.ndarray]:
    """EXR channels of a model's outputs: ``(H, W, 3)`` images as ``name.R/G/B``.

    ``color`` of the anti-aliasing models becomes ``color.R``, ``color.G``, ``color.B``
    (linear radiance, float32); ``(H, W)`` outputs keep their names.
    """
    channels = {}
    for name, value in outputs.items():
        arr = np.asarray(value, dtype=np.float32)
        if arr.ndim == 3 and arr.shape[-1] == 3:
            for i, c in enumerate("RGB"):
                channels[f"{name}.{c}"] = np.ascontiguousarray(arr[..., i])
        elif arr.ndim == 2:
            channels[name] = arr
        else:
            raise ValueError(
                f"model output {name!r} must be (H, W) or (H, W, 3), got shape {arr.shape}"
            )
    return channels


def run_model_to_folder(technique: str, loaded, *, params: dict, out: Path) -> dict:
    """Run ``technique`` with ``params`` on ``loaded``; write ``out/output.exr`` (its outputs)
    and ``out/model.json`` (parameters, cost, diagnostics, time, scene); returns the record."""
    res = raster_models.run(technique, loaded, **params)
    record = jsonable(
        {
            "technique": technique,
            "params": res.params,
            "cost": res.cost,
            "diagnostics": res.diagnostics,
            "wall_seconds": res.wall_seconds,
            "scene": loaded.provenance(),
        }
    )
    channels = output_channels(res.outputs)
    out.mkdir(parents=True, exist_ok=True)
    write_exr(out / "output.exr", channels)
    atomic_write_json(out / "model.json", record)
    return record
