"""The faster paths of the AA models give the results of the direct ones.

ACAA's tie search traces groups of shapes (:func:`raster_models.aa.acaa.groups.tie_groups`)
instead of one scene per shape: the outputs must be those of the per-shape search, byte for byte,
on scenes with ties (decal), with many shapes (city) and with many surfaces a pixel (thin).
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa.acaa import groups
from raster_oracle.raster_models.aa.acaa import model as acaa

from raster_oracle import raster_models as rm
from raster_oracle import scenes

SMALL = {"width": 64, "height": 36}


def _per_shape_groups(scene, fmt):
    return [[k] for k in range(len(scene.mi_scene.shapes()))]


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("decal", {"samples": 8}),
        ("decal", {"samples": 4, "depth_format": "D32F"}),
        ("city", {"samples": 8}),
        ("thin", {"samples": 4}),
    ],
)
def test_grouped_tie_search_equals_per_shape_search(monkeypatch, name, params):
    scene = scenes.load(name, **SMALL)
    grouped = rm.run("acaa", scene, **params)
    monkeypatch.setattr(acaa, "tie_groups", _per_shape_groups)
    direct = rm.run("acaa", scenes.load(name, **SMALL), **params)
    n_shapes = len(scene.mi_scene.shapes())
    assert direct.diagnostics["tie_groups"] == n_shapes
    for key, value in direct.outputs.items():
        assert np.array_equal(grouped.outputs[key], value), key
    assert grouped.diagnostics["tie_samples"] == direct.diagnostics["tie_samples"]
    assert grouped.diagnostics["fragments"] == direct.diagnostics["fragments"]


def test_tie_groups_split_touching_shapes_only():
    """City: 196 boxes standing on the ground, at least 10 m apart (grid pitch 24 x 30 m,
    widths <= 14 m): the ground touches every box (its own group), the boxes never come
    within a tie distance of each other (decimetres at the city's depths) and share one.
    Decal: the decal lies on the wall and the panel is duplicated: never in one group."""
    city = scenes.load("city", **SMALL)
    found = groups.tie_groups(city, "D24")
    names = city.shape_names
    assert len(found) == 2
    ground = [g for g in found if any(names[k] == "ground" for k in g)]
    assert ground == [[names.index("ground")]]
    decal = scenes.load("decal", **SMALL)
    for fmt in ("D24", "D32F"):
        for g in groups.tie_groups(decal, fmt):
            members = {decal.shape_names[k] for k in g}
            assert not ({"wall", "decal"} <= members), members
            assert not ({"panel", "panel_copy"} <= members), members


def test_tie_distance_grows_with_depth_and_precision():
    """One D24 quantum of normalized depth spans ``z^2 (f - n) / (f n)`` view units near
    view depth ``z`` (the derivative of ``f/(f-n) (1 - n/z)``): the tie distance is about
    :data:`TIE_QUANTA` of them over the corner cosine, and grows with depth."""
    cam = scenes.load("city", **SMALL).camera
    z = np.array([10.0, 100.0, 400.0])
    got = groups.tie_distance(cam, z, "D24")
    assert np.all(np.diff(got) > 0)
    n, f = cam.near, cam.far
    step = z**2 * (f - n) / (f * n) / ((1 << 24) - 1)
    t = cam.tan_half_x
    cos_min = 1.0 / np.sqrt(1.0 + t * t + (t / cam.aspect) ** 2)
    expect = groups.TIE_QUANTA * step / cos_min + groups.TIE_SLACK
    assert np.allclose(got, expect, rtol=1e-2)


@pytest.mark.parametrize("n", [1, 2, 4, 8, 16])
@pytest.mark.parametrize("planar", [False, True])
def test_box_resolve_fast_path_equals_the_weighted_sum(n, planar):
    """The unit-weight box resolve (a float64 reduction over the sample axis, on interleaved
    or planar colours) gives the bytes of the weighted einsum form it replaces, on colours
    spanning 60 binades (where float64 sums of float32 values could round)."""
    from raster_oracle.raster_models.aa import resolve

    rng = np.random.default_rng(n)
    h, w = 7, 5
    values = rng.standard_normal((h * w, n, 3)) * 2.0 ** rng.integers(-30, 30, (h * w, n, 3))
    colors = values.astype(np.float32)
    if planar:
        colors = np.moveaxis(np.ascontiguousarray(np.moveaxis(colors, -1, 0)), 0, -1)
    offsets = rng.random((n, 2))
    c = np.asarray(colors, np.float64).reshape(h, w, n, 3)
    expected = (np.einsum("hwn,hwnc->hwc", np.ones((h, w, n)), c) / n).astype(np.float32)
    got = resolve.resolve(colors, offsets, w, h, "box")
    assert got.dtype == np.float32 and got.shape == (h, w, 3)
    assert got.tobytes() == expected.tobytes()
