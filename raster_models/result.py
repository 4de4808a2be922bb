"""The record every model family returns: :class:`ModelResult`."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ModelResult"]


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
