"""The shipped alpha-test rules as registered techniques (``alpha-test``, ``alpha-threejs-a2c``,
``alpha-filament-a2c``, ``alpha-hashed``; family ``alpha``): :func:`.model.alpha_raster` on a
loaded scene's current frame, scored on ``coverage`` against the alpha-tested truth.

Parameters: ``samples`` (MSAA count at the standard positions), ``mips`` (``box``: box-filtered
mips; ``nvtt``: coverage-preserving mips, Castano's alpha scaling as NVTT ships it) and
``cutoff`` (``-1``: each material's own ``alphaCutoff``; Filament's default replaces it with
its ``maskThreshold`` 0.4). A scene without alpha-tested shapes is rasterized as opaque
(every fragment keeps its samples): the rule changes nothing there.

Outputs: ``coverage`` (fraction of the samples on a kept fragment) and ``layers`` (the most
fragments a sample of the pixel passed). Cost: ``samples``, ``framebuffer_bytes`` a pixel
(RGBA8 colour and D32F depth a sample, as MSAA's forward path counts them) and
``layers_mean`` (the mean over pixels of ``layers``: cut-out fragments a sample looked past).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...scenes.shading.alpha import AlphaTable
from .. import params as _params
from ..aa import samples as _samples
from ..result import model_result
from .model import AlphaRasterParams, alpha_raster
from .rules import FILAMENT_MASK_THRESHOLD

__all__ = ["AlphaParams", "FilamentAlphaParams", "TECHNIQUE_RULES", "make_runner"]

#: Registered technique -> the rule of :data:`.rules.RULES` it runs.
TECHNIQUE_RULES = {
    "alpha-test": "test",
    "alpha-threejs-a2c": "threejs-a2c",
    "alpha-filament-a2c": "filament-a2c",
    "alpha-hashed": "hashed",
}

#: Technique ``mips`` value -> the model's mip chain.
_MIPS = {"box": "box", "nvtt": "coverage"}

#: Bytes a sample: RGBA8 colour and D32F depth.
_BYTES_PER_SAMPLE = 4 + 4


@dataclass(frozen=True)
class AlphaParams:
    """Parameters of an alpha-test rule's model (see the module text)."""

    samples: int = _params.param(
        4,
        source="three.js WebGLRenderer antialias: true (a 4x multisampled framebuffer)",
        help="MSAA samples per pixel at the standard positions: 1, 2, 4, 8 or 16",
        lo=1,
        hi=16,
    )
    mips: str = _params.param(
        "box",
        source="LINEAR_MIPMAP_LINEAR over box-filtered mips (glGenerateMipmap)",
        help="box: box-filtered mips; nvtt: coverage-preserving mips (NVTT's alpha scaling)",
        choices=tuple(_MIPS),
    )
    cutoff: float = _params.param(
        -1.0,
        source="glTF 2.0 alphaCutoff (the material's own; default 0.5)",
        help="alpha cutoff; -1: each material's alphaCutoff",
        lo=-1.0,
        hi=1.0,
    )

    def check(self, technique: str) -> None:
        _samples.check_standard_count(technique, self.samples)


@dataclass(frozen=True)
class FilamentAlphaParams(AlphaParams):
    """Filament's masked materials: the same parameters, its ``maskThreshold`` 0.4 the
    default cutoff."""

    cutoff: float = _params.param(
        FILAMENT_MASK_THRESHOLD,
        source="Filament MaterialBuilder mMaskThreshold = 0.4f (google/filament 001a4c4)",
        help="Filament's maskThreshold; -1: each material's alphaCutoff",
        lo=-1.0,
        hi=1.0,
    )


def _table(scene) -> AlphaTable:
    """The scene's alpha table; every shape opaque when it has none."""
    if scene.alpha is not None:
        return scene.alpha
    return AlphaTable([], np.full(len(scene.mi_scene.shapes()), -1, np.int32))


def make_runner(name: str):
    """The entry point of registered technique ``name`` (a key of :data:`TECHNIQUE_RULES`)."""
    rule = TECHNIQUE_RULES[name]

    def run(scene, params: AlphaParams):
        t0 = time.perf_counter()
        model = AlphaRasterParams(
            rule=rule,
            samples=params.samples,
            mips=_MIPS[params.mips],
            cutoff=None if params.cutoff < 0 else float(params.cutoff),
        )
        out = alpha_raster(scene.mi_scene, _table(scene), scene.camera, model)
        layers = out["layers"]
        cost = {
            "samples": int(params.samples),
            "framebuffer_bytes": int(params.samples * _BYTES_PER_SAMPLE),
            "layers_mean": float(np.mean(layers)),
            "width": int(scene.width),
            "height": int(scene.height),
        }
        return model_result(
            name,
            scene,
            outputs={
                "coverage": out["coverage"].astype(np.float32),
                "layers": layers.astype(np.float32),
            },
            cost=cost,
            diagnostics={"rule": rule, "max_layers": int(np.max(layers, initial=0))},
            params=_params.as_dict(params),
            t0=t0,
        )

    run.__name__ = f"run_{rule.replace('-', '_')}"
    return run
