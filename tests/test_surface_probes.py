"""Implementation-defined pixels where an engine's rasterizer may see another surface: the
model's own sub-pixel sensitivity (raster_models/sensitivity.py) and the technique's verdict
on that other surface (raster_models/shadowmaps/probes.py), issue 43 item 5."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.sensitivity import surface_sensitivity
from raster_oracle.raster_models.shadowmaps.probes import other_surface_verdicts

from raster_oracle import raster_models, scenes

CLAIM = {"resolution": 512, "filter": "pcf", "bias": 0.002, "format": "D24"}


@pytest.mark.parametrize("name", ["plate", "city"])
def test_flips_are_other_surfaces_and_the_centre_is_the_model(_backend, name):
    scene = scenes.load(name, width=160, height=90)
    got = other_surface_verdicts(scene, "shadow-map", CLAIM)
    model = raster_models.run("shadow-map", scene, **CLAIM).outputs["visibility"]
    np.testing.assert_array_equal(got["visibility"], model)
    assert not np.any(got["flipped"] & ~got["other_surface"])
    np.testing.assert_array_equal(got["other_surface"], surface_sensitivity(scene))
    # only silhouettes are sensitive: a small fraction of the image
    assert got["other_surface"].mean() < 0.01


def test_city_silhouettes_over_their_own_shadow_flip(_backend):
    scene = scenes.load("city", width=320, height=180)
    got = other_surface_verdicts(scene, "shadow-map", CLAIM)
    assert 0 < got["flipped"].sum() <= got["other_surface"].sum()
    # wider probes find more (a quarter pixel against the default 1/64)
    wide = other_surface_verdicts(scene, "shadow-map", CLAIM, offset=0.25)
    assert wide["other_surface"].sum() > got["other_surface"].sum()


def test_a_texel_rounded_the_other_way_flips_only_named_pixels(_backend):
    """An engine whose rasterizer rounds a stored depth one D24 quantum the other way (a
    hardware DepthBias of +-1) flips receivers only where the model names the compare
    implementation-defined."""
    from raster_oracle.raster_models.shadowmaps.probes import implementation_defined

    scene = scenes.load("city", width=320, height=180)
    claim = {"resolution": 1024, "filter": "point", "bias": 0.0, "format": "D24"}
    got = implementation_defined(scene, "shadow-map", claim, surfaces=False)
    model = got["outputs"]["visibility"] >= 0.5
    flips = np.zeros_like(model)
    for step in (-1, 1):
        other = raster_models.run("shadow-map", scene, **claim, depth_bias=step)
        flips |= (other.outputs["visibility"] >= 0.5) != model
    assert flips.sum() > 0  # bias 0: the receivers' own texels decide by rounding
    assert not np.any(flips & ~got["depth_rounding"])
    assert not got["other_surface"].any()
