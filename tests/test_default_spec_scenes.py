"""The main job's default sweep scores each family on scenes where its metrics mean something:
every scene swept by a shadow technique casts a shadow onto its receivers."""

from __future__ import annotations

import pytest
from raster_oracle.oracle.sweeps.mainjob import default_spec
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from raster_oracle.raster_models.registry import family_of

from raster_oracle import scenes

#: Least fraction of a shadow scene's receiver pixels in shadow (at the pixel centres).
MIN_SHADOWED = 0.01


def _shadow_scenes() -> list[str]:
    names = set()
    for case in default_spec()["case"]:
        if family_of(case["technique"]) == "shadow":
            names.update(case["scenes"])
    return sorted(names)


@pytest.mark.parametrize("name", _shadow_scenes())
def test_every_shadow_scene_of_the_default_sweep_has_a_shadow(name):
    g = trace_gbuffer(scenes.load(name, width=96, height=54), with_lit=True)
    shadowed = (g.receiver & ~g.lit).sum() / max(int(g.receiver.sum()), 1)
    assert shadowed > MIN_SHADOWED, f"{name}: {shadowed:.4f} of its receivers in shadow"
