"""No anti-aliasing (``noaa``): one sample at each pixel centre, shaded where it lies.

The baseline of the anti-aliasing family: :mod:`.ssaa` with one sample at ``(0.5, 0.5)``
(the oracle's per-sample path, :func:`scenes.backend.raycast.trace_film_dr`: shading at the hit,
exact shadow ray), so aliasing is the only error it adds to the reference.

References
----------
F. C. Crow, The aliasing problem in computer-generated shaded images, CACM 20(11) 1977,
doi:10.1145/359863.359869.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from .. import params as _params
from . import samples as _samples
from .ssaa import supersample

__all__ = ["NoAAParams", "run"]

NAME = "noaa"


@dataclass(frozen=True)
class NoAAParams:
    """Parameters of :func:`run`: none but the sample count, which is always 1."""

    samples: int = _params.param(
        1, source="no anti-aliasing: one sample at the pixel centre", help="always 1", lo=1, hi=1
    )


def run(scene, params: NoAAParams | None = None, **kwargs):
    """Run ``noaa`` (one sample at each pixel centre); see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, NoAAParams, kwargs)
    return supersample(NAME, scene, p, _samples.positions(1), t0=t0)
