"""The oracle's shaded colour against Mitsuba's own ``direct`` integrator (Z-test).

Per pixel-channel two-sided Z-test of the difference of the two estimates with both standard
errors (ours from the stratified samples, Mitsuba's from four independently seeded renders),
Sidak-corrected over pixel-channels at alpha = 0.01; as in Mitsuba's render regression tests
it passes when at least 99.75 % of pixel-channels pass.
"""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from scipy.special import erfc

from raster_oracle import scenes

ALPHA = 0.01
PASS_RATE = 0.9975
VARIANCE_FLOOR = 1e-8  # pixels where both estimates are noiseless (sky, flat lit ground)


@pytest.mark.parametrize("name", ["plate", "point", "spot"])
def test_color_agrees_with_mitsuba_direct(mi, name):
    loaded = scenes.load(name, width=48, height=27)
    ch, _ = render_reference(
        loaded, ReferenceSettings(spp=256, seed=3, channels=("color",)), quiet=True
    )
    ours = np.stack([ch[f"color.{c}"] for c in "RGB"], -1).astype(np.float64)
    ours_se = np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1).astype(np.float64)
    integrator = mi.load_dict({"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})
    runs = np.stack(
        [
            np.array(mi.render(loaded.mi_scene, integrator=integrator, spp=64, seed=k))
            for k in range(4)
        ]
    ).astype(np.float64)
    theirs = runs.mean(0)
    theirs_se = runs.std(0, ddof=1) / np.sqrt(len(runs))
    assert theirs.shape == ours.shape
    z = np.abs(ours - theirs) / np.sqrt(ours_se**2 + theirs_se**2 + VARIANCE_FLOOR)
    p = erfc(z / np.sqrt(2))
    alpha_sidak = 1 - (1 - ALPHA) ** (1 / p.size)
    assert np.mean(p >= alpha_sidak) >= PASS_RATE
    # and a planted 3 % bias is caught: the test has power
    z_bias = np.abs(ours * 1.03 - theirs) / np.sqrt(ours_se**2 + theirs_se**2 + VARIANCE_FLOOR)
    assert np.mean(erfc(z_bias / np.sqrt(2)) >= alpha_sidak) < PASS_RATE
