"""Neighbour-aware adaptive sampling (issue 18): a pixel refines when it or a neighbour shows
an edge, an id change or a visibility change, so thin features that its own samples all
missed are not invisible to it; progressive (Sobol) passes keep the union stratified."""

from __future__ import annotations

import math

import numpy as np
import pytest
from raster_oracle.oracle.reference import render as R
from raster_oracle.oracle.reference.adaptive import refine_mask
from raster_oracle.oracle.reference.coverage import CoverageGroup
from raster_oracle.oracle.reference.edge import EdgeGroup
from raster_oracle.oracle.reference.group import Accumulators
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.oracle.reference.visibility import VisibilityGroup

from raster_oracle import scenes

CHANNELS = ("visibility", "coverage")


class _Sums:
    """The groups an adaptive render keeps without colour (visibility, coverage without its
    front part, the shape range), their sums reachable by name."""

    def __init__(self, npix: int):
        vis = VisibilityGroup(npix)
        groups = {"visibility": vis, "coverage": CoverageGroup(npix, output=False)}
        groups["edge"] = EdgeGroup(npix, visibility=vis)
        self.acc = Accumulators(npix, groups, color=False)
        self.n = self.acc.n
        self.vis, self.cov = vis.vis, groups["coverage"].cov
        self.smin, self.smax = groups["edge"].smin, groups["edge"].smax


def _uniform_acc(width: int, height: int, n: int, shape_id: int = 0) -> _Sums:
    """Every pixel: ``n`` samples, all lit, all covered, all on shape ``shape_id``."""
    acc = _Sums(width * height)
    acc.n[:] = n
    acc.vis[:] = n
    acc.cov[:] = n
    acc.smin[:] = shape_id
    acc.smax[:] = shape_id
    return acc


def test_a_neighbours_id_change_refines_a_pixel_whose_own_samples_agree():
    """7x5 image, 16 agreeing samples everywhere; pixel (3, 2) saw shape 1 in one sample.
    It shows an edge, its 3x3 neighbours an id change against it: with the 3x3 dilation the
    5x5 block around it refines (its neighbours' own samples agree), columns 0 and 6 not."""
    w, h = 7, 5
    acc = _uniform_acc(w, h, 16)
    centre = 2 * w + 3
    acc.smax[centre] = 1
    settings = ReferenceSettings(adaptive=True, target_stderr=0.01).validate()
    mask = refine_mask(acc.acc, settings, w, h).reshape(h, w)
    expected = np.zeros((h, w), bool)
    expected[:, 1:6] = True
    np.testing.assert_array_equal(mask, expected)


def test_a_neighbours_visibility_change_refines_agreeing_pixels_on_both_sides():
    """Left half all shadowed, right half all lit, every pixel's samples agree: no pixel has
    sample variance, yet the columns along the boundary (and one more each side) refine."""
    w, h = 8, 3
    acc = _uniform_acc(w, h, 16)
    acc.vis.reshape(h, w)[:, :4] = 0
    settings = ReferenceSettings(adaptive=True, target_stderr=0.01).validate()
    mask = refine_mask(acc.acc, settings, w, h).reshape(h, w)
    assert mask[:, 2:6].all() and not mask[:, :2].any() and not mask[:, 6:].any()
    # once a pixel meets the target (floor below it) it stops although it is near the edge
    acc.n[:] = 256
    acc.vis[acc.vis > 0] = 256
    acc.cov[:] = 256
    assert not refine_mask(acc.acc, settings, w, h).any()


def test_binary_stderr_is_the_floor_for_agreeing_samples_and_jeffreys_otherwise():
    n = np.array([16.0, 128.0, 128.0])
    k = np.array([16.0, 1.0, 127.0])
    se = R.binary_stderr(k, n)
    floor = math.sqrt((0.5 / 17) * (1 - 0.5 / 17) / 16)
    assert se[0] == pytest.approx(floor)
    p = 1.5 / 129
    assert se[1] == pytest.approx(math.sqrt(p * (1 - p) / 128)) and se[1] == se[2]


def test_sobol_passes_are_nets_for_every_doubling():
    """Points [0, 2^k) and [2^k, 2^(k+1)) of a pixel's sequence each hold one point in every
    elementary interval of their size: each adaptive pass, and their union, is stratified."""
    from raster_oracle.scenes import backend

    mi = backend.mitsuba()
    n = 256
    u, v = R.sobol_sample(mi.UInt32(np.full(n, 5, np.uint32)), mi.UInt32(np.arange(n)), 3)
    u, v = np.array(u), np.array(v)
    assert np.all((u >= 0) & (u < 1) & (v >= 0) & (v < 1))
    for lo, hi in ((0, 16), (16, 32), (32, 64), (64, 128), (128, 256), (0, 256)):
        m = hi - lo
        bits = int(math.log2(m))
        for i in range(bits + 1):
            cu = (u[lo:hi] * 2**i).astype(int)
            cv = (v[lo:hi] * 2 ** (bits - i)).astype(int)
            cells = set(zip(cu, cv, strict=True))
            assert len(cells) == m


@pytest.fixture(scope="module")
def thin_case():
    scene = scenes.load("thin", width=160, height=90)
    truth, _ = render_reference(
        scene, ReferenceSettings(spp=4096, seed=1000, channels=CHANNELS), quiet=True
    )
    settings = ReferenceSettings(
        adaptive=True, adaptive_spp=16, target_stderr=0.005, max_spp=1024, channels=CHANNELS
    )
    ch, stats = render_reference(scene, settings, quiet=True)
    return scene, truth, settings, ch, stats


def test_adaptive_worst_pixel_is_no_worse_than_uniform_at_equal_rays(thin_case):
    """Uniform sampling given 1.5x adaptive's rays (its mean spp) still leaves a larger
    worst-pixel error than adaptive on `thin` (160x90, target 0.005: adaptive 0.0178 at 552
    mean spp, uniform at 828 spp 0.0284). The per-pixel rule with separate jittered grids
    per pass failed it: 0.0269 at 555 mean spp against uniform's 0.0249 at 1.5x."""
    scene, truth, _, ch, stats = thin_case
    spp = int(math.ceil(1.5 * stats["adaptive"]["mean_spp"]))
    uni, _ = render_reference(scene, ReferenceSettings(spp=spp, channels=CHANNELS), quiet=True)

    def worst(img):
        return max(float(np.abs(img[c] - truth[c]).max()) for c in CHANNELS)

    assert worst(ch) <= worst(uni)
    assert stats["adaptive"]["mean_spp"] < 0.7 * stats["adaptive"]["max_spp_used"]


def test_adaptive_results_are_the_same_bytes_for_the_same_seed(thin_case):
    scene, _, settings, ch, stats = thin_case
    again, again_stats = render_reference(scene, settings, quiet=True)
    assert again_stats["passes"] == stats["passes"]
    for name in ch:
        assert again[name].tobytes() == ch[name].tobytes()
    other, _ = render_reference(
        scene, ReferenceSettings(**{**settings.__dict__, "seed": 1}), quiet=True
    )
    assert other["visibility"].tobytes() != ch["visibility"].tobytes()
