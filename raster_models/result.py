"""The record every model family returns: :class:`ModelResult`."""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..scenes.backend import provenance
from ..scenes.base.records import jsonable

__all__ = ["ModelResult", "model_result"]


@dataclass
class ModelResult:
    """What a model run produced.

    Attributes
    ----------
    outputs : name -> ``(H, W)`` float32 (see module docstring).
    cost : the technique's own GPU budget (bytes, texels, passes, lookups, latency).
    diagnostics : JSON-serialisable record (splits, per-partition bounds and statistics).
    params : every parameter with its value.
    wall_seconds : NumPy/Dr.Jit run time of the model (not the technique's GPU time).
    """

    technique: str
    outputs: dict
    cost: dict
    diagnostics: dict
    params: dict
    wall_seconds: float

    def to_json(self) -> dict:
        """model.json record (everything but the images)."""
        return {
            "technique": self.technique,
            "params": self.params,
            "cost": self.cost,
            "diagnostics": self.diagnostics,
            "wall_seconds": self.wall_seconds,
            "outputs": sorted(self.outputs),
        }


def model_result(
    technique: str, scene, *, outputs: dict, cost: dict, diagnostics: dict, params: dict, t0: float
) -> ModelResult:
    """The result of a model run that started at ``t0`` (``time.perf_counter()``).

    The diagnostics get the scene's provenance (``scene``) and the packages' (``provenance``)
    as their last keys and are cleaned to JSON values (:func:`scenes.base.records.jsonable`);
    ``cost`` and ``params`` (a plain record, see :func:`raster_models.params.as_dict`) are
    kept as given.
    """
    diag = dict(diagnostics)
    diag["scene"] = scene.provenance()
    diag["provenance"] = provenance()
    return ModelResult(
        technique=technique,
        outputs=outputs,
        cost=cost,
        diagnostics=jsonable(diag),
        params=params,
        wall_seconds=time.perf_counter() - t0,
    )
