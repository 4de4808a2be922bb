"""Closed form for logarithmic splits under an overhead light.

With ``k`` log splits of ``[n, f]`` and maps of ``R`` texels fit to each frustum slice, the
worst texel-to-pixel ratio (texel size over the pixel's footprint, at the near end of every
partition) is ``((f/n)^(1/k) - 1) / (R theta)``, ``theta`` the angle of one pixel; at equal
total resolution ``R = R_total / k`` it falls with ``k`` towards ``ln(f/n) / (R_total theta)``
(Lloyd et al. 2006; TECHNIQUES.md).

The 1-D analysis assumes a pixel footprint of ``z theta`` along the view direction. The
receiver here realizes it exactly: a surface whose view depth grows as ``z = C exp(s_y)``
with the tangent-space screen coordinate ``s_y``, so that one pixel step moves ``z theta``
in depth; a narrow horizontal field of view keeps the lateral direction better sampled, so
the depth direction is the worst one, which ``texels_per_pixel`` (the smallest singular value
of the texel/pixel Jacobian) measures.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from test_models_xml import write_scene

from raster_oracle import raster_models as rm
from raster_oracle import scenes

NEAR, FAR = 1.0, 100.0
TAN_X = 0.1
WIDTH = 16
#: Relative tolerance: the mesh is piecewise planar (rows 0.1 % apart in depth) and the
#: worst pixel sits up to one pixel (theta = 1.25 %) past the partition's near end.
CLOSED_FORM_RTOL = 0.02


def _exp_surface(rows: int = 4000):
    """Vertices/faces of z = C exp(s_y), y = z s_y, spanning view depths (n, f)."""
    c = math.sqrt(NEAR * FAR)
    sy = np.linspace(math.log(NEAR * 1.0005 / c), math.log(FAR * 0.9995 / c), rows)
    z = c * np.exp(sy)
    y = z * sy
    half_x = 1.5 * TAN_X * z
    verts = np.empty((2 * rows, 3))
    verts[0::2] = np.stack([-half_x, y, z], axis=1)
    verts[1::2] = np.stack([half_x, y, z], axis=1)
    i = np.arange(rows - 1)
    a, b, c_, d = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
    faces = np.concatenate([np.stack([a, c_, b], 1), np.stack([b, c_, d], 1)])
    return verts, faces


@pytest.fixture(scope="module")
def log_scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("closed_form")
    tan_y = 0.51 * math.log(FAR / NEAR)
    height = int(round(WIDTH * tan_y / TAN_X))
    path = write_scene(
        folder,
        origin=(0, 0, 0),
        target=(0, 0, 1),
        shapes=[],
        meshes={"surface.obj": _exp_surface()},
        sun=(0.0, -1.0, 0.0),
        fov=2 * math.degrees(math.atan(TAN_X)),
        near=NEAR,
        far=FAR,
        width=WIDTH,
        height=height,
    )
    return scenes.load(str(path))


def _worst_ratio(result) -> float:
    tpp = result.outputs["texels_per_pixel"]
    covered = result.outputs["cascade"] >= 0
    return float(1.0 / tpp[covered].min())


@pytest.mark.parametrize("k", [1, 2, 4])
def test_worst_texel_to_pixel_ratio_of_log_splits(log_scene, k):
    r_map = 1024
    theta = log_scene.camera.pixel_angle
    res = rm.run("csm", log_scene, partitions=k, split="log", resolution=r_map, filter="point")
    assert res.diagnostics["light_up_used"] != "world_y"  # overhead light: the fallback
    expected = ((FAR / NEAR) ** (1.0 / k) - 1.0) / (r_map * theta)
    assert _worst_ratio(res) == pytest.approx(expected, rel=CLOSED_FORM_RTOL)
    # Every partition reaches the same worst ratio at its near end (log splits equalize it).
    mins = [p["statistics"]["texels_per_pixel_min"] for p in res.diagnostics["partitions"]]
    np.testing.assert_allclose(1.0 / np.array(mins), expected, rtol=CLOSED_FORM_RTOL)


def test_equal_memory_ratio_falls_towards_log_of_far_over_near(log_scene):
    r_total = 2048
    theta = log_scene.camera.pixel_angle
    ratios = []
    for k in (1, 2, 4, 8):
        res = rm.run(
            "csm", log_scene, partitions=k, split="log", resolution=r_total // k, filter="point"
        )
        ratios.append(_worst_ratio(res))
        closed = k * ((FAR / NEAR) ** (1.0 / k) - 1.0) / (r_total * theta)
        assert ratios[-1] == pytest.approx(closed, rel=CLOSED_FORM_RTOL)
    assert all(b < a for a, b in pairwise(ratios))
    limit = math.log(FAR / NEAR) / (r_total * theta)
    # k (e^(L/k) - 1) -> L: 1.35 L at k = 8 for L = ln 100.
    assert limit < ratios[-1] < 1.4 * limit
