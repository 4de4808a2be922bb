"""Run a technique model and write ``output.exr`` + ``model.json``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .exr import atomic_write_bytes, write_exr
from .score import to_json

__all__ = ["run_model_to_folder"]


def run_model_to_folder(technique: str, loaded, pairs: list[str], out: Path) -> dict:
    """Parse ``KEY=VALUE`` pairs, run the model on ``loaded`` and write the folder."""
    import raster_models

    params = raster_models.parse_params(technique, pairs)
    res = raster_models.run(technique, loaded, **params)
    record = {
        "technique": technique,
        "params": res.params,
        "cost": res.cost,
        "diagnostics": res.diagnostics,
        "wall_seconds": res.wall_seconds,
        "scene": loaded.provenance(),
    }
    data = to_json(record)
    channels = {k: np.asarray(v, dtype=np.float32) for k, v in res.outputs.items()}
    out.mkdir(parents=True, exist_ok=True)
    write_exr(out / "output.exr", channels)
    atomic_write_bytes(out / "model.json", data)
    return record
