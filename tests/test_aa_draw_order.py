"""MSAA's samples on coplanar surfaces go to the surface a rasterizer keeps: depth test LESS
on the rasterized depth (:mod:`raster_models.aa.acaa.plane`), first drawn (shape order, then
primitive order) among equal stored depths; shading events are counted from those owners,
not from the ray tracer's tie-break (issue 18: MSAA on ``decal`` counted 1.149 events a pixel
where OpenGL counts 1.011).
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa import msaa, owners, samples, trace
from raster_oracle.raster_models.aa.acaa import groups, plane
from raster_oracle.raster_models.aa.fragments import Fragments
from raster_oracle.scenes import backend
from raster_oracle.scenes.backend.raycast import camera_rays_dr
from raster_oracle.scenes.catalogue.builtin import BuiltinScene

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests.test_aa_acaa_raster_depth import _sloped_decal

W, H, N = 64, 36, 8


def _owners_closed_form(scene, n, fmt):
    """Per sample the (shape, prim) a LESS depth test in draw order keeps, from each shape
    traced alone and its rasterized depth stored in ``fmt``: the lowest (depth, shape,
    prim); ``(pixel, shape, prim)`` arrays, shape -1 on sky."""
    mi = backend.mitsuba()
    offs = samples.positions(n)
    pix = np.repeat(np.arange(W * H), n)
    slot = np.tile(np.arange(n), W * H)
    sx = (pix % W).astype(np.float32) + offs[slot, 0].astype(np.float32)
    sy = (pix // W).astype(np.float32) + offs[slot, 1].astype(np.float32)
    n_shapes = len(scene.shape_names)
    subs = groups.group_scenes(scene, [[k] for k in range(n_shapes)])
    best = (np.full(len(sx), np.inf), np.full(len(sx), -1), np.full(len(sx), -1))
    for k, sub in enumerate(subs):  # in draw order: a later equal depth never wins
        ray = camera_rays_dr(scene.camera, mi.Float(sx), mi.Float(sy))
        pi = sub.ray_intersect_preliminary(ray)
        hit = pi.is_valid().numpy()
        prim = np.where(hit, pi.prim_index.numpy().astype(np.int64), 0)
        vz = np.where(hit, trace.view_depth(scene.camera, ray.o + ray.d * pi.t).numpy(), 1.0)
        q = plane.stored_raster_depths(scene, np.full(len(sx), k), prim, sx, sy, vz, fmt)
        win = hit & (q < best[0])
        best = tuple(np.where(win, new, old) for new, old in zip((q, k, prim), best, strict=True))
    return pix, best[1], best[2]


def _events(pix, shape, prim):
    ok = shape >= 0
    key = np.unique((pix[ok] << 40) | (shape[ok] << 32) | prim[ok])
    return np.bincount(key >> 40, minlength=W * H)


@pytest.mark.parametrize("fmt", ["D32F", "D24"])
def test_decal_events_follow_draw_order(fmt):
    """Built-in decal: the decal lies on the wall (equal depths everywhere, the wall drawn
    first keeps every sample) and the panel is duplicated (the first copy keeps them)."""
    scene = scenes.load("decal", width=W, height=H)
    res = rm.run("msaa", scene, samples=N, depth_format=fmt)
    pix, shape, prim = _owners_closed_form(scene, N, fmt)
    assert np.array_equal(res.outputs["shading_events"].ravel(), _events(pix, shape, prim))
    names = list(scene.shape_names)
    assert not np.isin(shape, [names.index("decal"), names.index("panel_copy")]).any()
    # the wall alone under the decal (the ray tracer's tie-break: 1.273 a pixel here)
    assert res.outputs["shading_events"].mean() < 1.07


def test_sloped_decal_events_follow_the_depth_test():
    scene = scenes.load(BuiltinScene("sloped-decal", _sloped_decal, "a sloped decal", W, H))
    res = rm.run("msaa", scene, samples=N)
    pix, shape, prim = _owners_closed_form(scene, N, "D32F")
    assert np.array_equal(res.outputs["shading_events"].ravel(), _events(pix, shape, prim))
    # coverage-weighted colour: each owner's samples, shaded on the owner's surface
    decal = list(scene.shape_names).index("decal")
    share = np.bincount(pix, weights=shape == decal, minlength=W * H) / N
    red = res.outputs["color"][..., 0].ravel() - res.outputs["color"][..., 2].ravel()
    assert np.corrcoef(share, red)[0, 1] > 0.99


def test_reassign_samples_by_hand():
    """Pixel 1's samples 0 and 1 go from shape 1 (prim 4) to shape 0 (prim 2): the shape-0
    fragment takes them; shape 1 keeps sample 3; pixel 0 is untouched."""
    valid = np.array([[True, True, False, False], [True, True, True, True]])
    shape = np.array([[0, 0, -1, -1], [1, 1, 0, 1]])
    prim = np.array([[7, 7, -1, -1], [4, 4, 2, 4]])
    frags = Fragments(
        np.array([0, 1, 1]),
        np.array([0, 0, 2]),
        np.array([2, 3, 1]),
        np.array([[0, 0, -1, -1], [1, 1, 2, 1]]),
    )
    own = (np.array([1, 1]), np.array([0, 1]), np.array([0, 0]), np.array([2, 2]))
    got, regroup = owners.reassign_samples(frags, valid, shape, prim, own)
    assert got.pixel.tolist() == [0, 1, 1]
    assert got.count.tolist() == [2, 3, 1]
    assert got.of_sample.tolist() == [[0, 0, -1, -1], [1, 1, 1, 2]]
    # the shape-0 fragment is traced through sample 2 (where the ray met it); shape 1 via 3
    assert got.sample.tolist() == [0, 2, 3]
    assert regroup.tolist() == [-1, -1, -1]


def test_scenes_without_ties_are_unchanged():
    """One tie group (no two shapes ever close enough to tie): no search, the prepass's
    fragments as they were."""
    scene = scenes.load("plate", width=W, height=H)
    assert len(groups.tie_groups(scene, "D32F")) == 1
    assert owners.draw_order_owners(scene, samples.positions(N), "D32F") is None
    ms = msaa.multisample(scene, samples.positions(N), centroid=False, shadows="exact")
    assert ms["frags"].count.sum() == ms["buffer"]["valid"].sum()
