"""Shared parts of the claims: the measurement context, summaries and verdict names."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["NOT", "PARTLY", "REPRODUCED", "ClaimContext", "run_model", "summary"]

REPRODUCED, PARTLY, NOT = "reproduced", "partly", "not reproduced"


def summary(values) -> dict:
    """Mean with its standard error (sample standard deviation / sqrt(n)), min, max, n."""
    v = np.asarray([float(x) for x in values], dtype=np.float64)
    n = int(v.size)
    if n == 0:
        return {"mean": None, "stderr": None, "min": None, "max": None, "n": 0}
    se = float(v.std(ddof=1) / math.sqrt(n)) if n > 1 else 0.0
    return {
        "mean": float(v.mean()),
        "stderr": se,
        "min": float(v.min()),
        "max": float(v.max()),
        "n": n,
    }


@dataclass
class ClaimContext:
    """Sizes of a claims run and a memo of loaded scenes and oracle references."""

    quick: bool
    cache: object = None
    quiet: bool = True
    width: int = 160
    height: int = 90
    spp: int = 16
    frames: int = 4
    shadow_scenes: tuple[str, ...] = ("plate", "city", "curved", "thin")
    _refs: dict = field(default_factory=dict)
    _runs: dict = field(default_factory=dict)

    def run(self, technique: str, loaded, **params):
        """A model result, memoized per (scene content, frame, technique, parameters)."""
        key = (
            loaded.content_hash,
            loaded.camera_path,
            loaded.frame,
            technique,
            json.dumps(params, sort_keys=True),
        )
        if key not in self._runs:
            self._runs[key] = run_model(technique, loaded, **params)
        return self._runs[key]

    def scene(self, name: str, *, frame: int = 0, path: str | None = None, size=None):
        from .... import scenes

        w, h = size or (self.width, self.height)
        loaded = scenes.load(name, width=w, height=h)
        if path is not None:
            loaded = loaded.with_frame(frame, path=path, n_frames=self.frames)
        return loaded

    def reference(self, loaded, channels=("visibility", "id", "normal", "position")) -> dict:
        from ...reference.render import ReferenceSettings, render_reference

        key = (loaded.content_hash, loaded.camera_path, loaded.frame, tuple(channels))
        if key not in self._refs:
            settings = ReferenceSettings(spp=self.spp, seed=0, channels=tuple(channels))
            if self.cache is None:
                self._refs[key] = render_reference(loaded, settings, quiet=True)[0]
            else:
                from ...reference.store import get_reference

                ref = get_reference(loaded, settings, cache=self.cache, quiet=self.quiet)
                self._refs[key] = ref.channels()
        return self._refs[key]

    def shadow_error(self, loaded, result) -> dict:
        """Shadow metrics of a model result against the oracle (receivers only)."""
        from .... import metrics as M
        from ...scoring.channels import reference_receivers

        ref = self.reference(loaded)
        rec = reference_receivers(ref, loaded.light)
        vis = np.clip(np.asarray(result.outputs["visibility"], dtype=np.float32), 0.0, 1.0)
        return M.shadow_metrics(ref["visibility"], vis, receivers=rec)


def run_model(technique: str, loaded, **params):
    """``raster_models.run`` (imported late: the models package is optional)."""
    from .... import raster_models

    return raster_models.run(technique, loaded, **params)
