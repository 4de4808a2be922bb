"""IZB's epsilon band far from the origin and for gaps below float32 rounding scale.

A plate ``gap`` above the ground (``gap`` < the 1e-3 epsilon) under a grazing sun: an exact
ray from the ground beside the plate's far edge hits the plate over a strip ``gap / tan(sun
elevation)`` wide, which the epsilon rule lights. The band must flag every receiver of that
strip (the model cannot know the truth there), at any distance from the origin, and stay a
band (not the whole image).
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from test_models_xml import quad, write_scene

from raster_oracle import raster_models as rm
from raster_oracle import scenes

#: Sun direction: elevation atan(1/200), so the plate's shadow reaches 200 gap past its edge.
SUN = (1.0, -1.0 / 200.0, 0.0)
PLATE_HALF = 2.0


def _scene(tmp_path, offset: float, gap: float, view: float):
    """Camera straight down over the plate's +x edge at ``(offset, gap, offset)``; the view is
    ``view`` units wide."""
    o = np.array([offset, 0.0, offset])
    fov = float(np.degrees(2 * np.arctan(view / 2)))  # camera 1 unit above the ground
    path = write_scene(
        tmp_path,
        name=f"band{int(offset)}",
        origin=o + (0, 1, 0),
        target=o,
        up=(0, 0, 1),
        fov=fov,
        near=0.01,
        far=10.0,
        width=96,
        height=54,
        sun=SUN,
        shapes=[
            quad(o, (15, 0, 0), (0, 0, -15)),
            quad(o + (-PLATE_HALF, gap, 0), (PLATE_HALF, 0, 0), (0, 0, -PLATE_HALF)),
        ],
    )
    return scenes.load(str(path))


def _exact_shadow(p: np.ndarray, offset: float, gap: float) -> np.ndarray:
    """Float64 shadow rays from ground points ``p`` (their surface point: y = 0) toward the sun
    against the plate: the plate's plane is reached ``gap * 200`` units toward -x."""
    x_hit = p[:, 0] - gap * 200.0
    z_hit = p[:, 2]
    return (
        (x_hit >= offset - 2 * PLATE_HALF)
        & (x_hit <= offset)
        & (np.abs(z_hit - offset) <= PLATE_HALF)
    )


@pytest.mark.parametrize(
    ("offset", "gap", "view"),
    [(1000.0, 5e-4, 0.4), (0.0, 1e-5, 0.008), (0.0, 3e-6, 0.0024)],
    ids=["far-5e-4", "origin-1e-5", "origin-3e-6"],
)
def test_epsilon_band_flags_every_receiver_the_epsilon_lights_wrongly(tmp_path, offset, gap, view):
    s = _scene(tmp_path, offset, gap, view)
    g = trace_gbuffer(s)
    r = rm.run("izb", s)
    band = r.outputs["epsilon_band"].ravel() > 0
    vis = r.outputs["visibility"].ravel()
    ground = g.receiver & (g.position[:, 1] < gap / 2)
    truth = np.zeros_like(ground)
    truth[ground] = _exact_shadow(g.position[ground], offset, gap)
    assert truth.sum() > 200  # the strip is in view
    # the epsilon (1e-3 > gap) lights the whole strip: the band must flag all of it
    assert (vis[truth] == 1.0).all()
    missed = truth & ~band
    assert missed.sum() == 0, f"{missed.sum()} of {truth.sum()} strip receivers not flagged"
    # ... and stay a band: nothing flagged away from the strip
    extra = band & ~truth
    assert extra.sum() <= 0.01 * g.receiver.sum(), f"{extra.sum()} receivers flagged off the strip"
