"""The shading point of the multisample models lies on its surface within the shadow offset:
a lit wall turned away from the camera is lit everywhere (issue 18, "shading-point acne").

The point is rebuilt from the pixel-centre (or centroid) ray and the primitive's plane as
``o + t d`` in float32; its rounding error follows the ray's origin and length, and exceeded
the mesh shadow offset (scaled by |p|) on tilted walls: up to 617 of 6,144 fully covered
pixels rendered black under msaa, acaa and agaa where ssaa, noaa and the oracle light them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.scenes.catalogue.builtin import BuiltinScene
from raster_oracle.scenes.catalogue.factories import mesh, sensor, sun
from raster_oracle.scenes.geometry import meshes

from raster_oracle import raster_models as rm
from raster_oracle import scenes


def _tilted_wall(width: int, height: int, *, degrees: float, offset_x: float) -> dict:
    """A 6 x 6 wall turned ``degrees`` about +Y, centred at ``(offset_x, 0, 0)``, seen
    head-on from 8 units and lit from the camera's side (no occluder anywhere)."""
    a = math.radians(degrees)
    right, up = np.array([math.cos(a), 0.0, math.sin(a)]), np.array([0.0, 1.0, 0.0])
    normal = np.cross(right, up)  # unit: right and up are orthonormal
    centre = np.array([offset_x, 0.0, 0.0])
    corners = [
        centre + 3.0 * (sx * right + sy * up) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))
    ]
    eye = centre + 8.0 * normal
    return {
        "type": "scene",
        "camera": sensor(
            width, height, origin=tuple(eye), target=tuple(centre), fov=30, near=0.1, far=100
        ),
        "sun": sun(tuple(-0.6 * normal + np.array([0.0, -0.3, 0.0]))),
        "wall": mesh(meshes.quad(np.array(corners)), 0.5),
    }


@pytest.mark.parametrize("technique", ["msaa", "acaa", "agaa"])
@pytest.mark.parametrize("degrees", [20.0, 40.0, 63.0, 87.0])
@pytest.mark.parametrize("offset_x", [0.0, 30.0])
def test_lit_tilted_wall_has_no_black_pixel(technique, degrees, offset_x):
    def factory(w, h):
        return _tilted_wall(w, h, degrees=degrees, offset_x=offset_x)

    loaded = scenes.load(BuiltinScene("tilted-wall", factory, "a lit tilted wall", 96, 64))
    res = rm.run(technique, loaded)
    covered = res.outputs["coverage"] >= 1.0
    assert covered.sum() > 0.9 * covered.size  # the wall fills the frame
    luminance = res.outputs["color"].sum(-1)[covered]
    # one light, no occluder: every covered pixel is lit (within a factor of the median)
    assert (luminance > 0.5 * np.median(luminance)).all(), int(
        (luminance <= 0.5 * np.median(luminance)).sum()
    )


@pytest.mark.parametrize("technique", ["msaa", "acaa"])
def test_stripes_shaded_inside_their_primitives_match_supersampling(technique):
    """`stripes` (one zigzag period a pixel, flat strips under a sun): shaded at the centroid,
    every fragment's shading point is on its strip, so the resolve equals 8x SSAA with the same
    sample positions in every pixel: no pixel darker, no acne. Shaded at the pixel centre (the
    hardware default), the red strip's attributes are extrapolated past its crease, where the
    blue strip shadows them: every pixel is darker by the same factor, the centroid artifact
    MSAA is known for, not scattered acne."""
    s = scenes.load("stripes", width=160, height=90)
    ssaa = rm.run("ssaa", s, samples=8).outputs["color"].sum(-1)
    assert (ssaa > 0.05).all()  # lit everywhere
    inside = rm.run(technique, s, samples=8, centroid=True).outputs["color"].sum(-1)
    np.testing.assert_allclose(inside, ssaa, rtol=1e-5)
    centre = rm.run(technique, s, samples=8).outputs["color"].sum(-1) / ssaa
    assert centre.max() - centre.min() < 1e-5  # the same in every pixel
    assert 0.3 < centre.mean() < 0.9
