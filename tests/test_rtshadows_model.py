"""The rtshadows models end to end on the event scenes: one ray a pixel is an unbiased
estimate of the area-light truth, frames are cached and reproducible, and the flicker
scene's light goes off and on."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.raster_models.rtshadows import model
from raster_oracle.raster_models.rtshadows.frames import build_frame
from raster_oracle.scenes.catalogue.event_scenes import FLICKER_OFF, FLICKER_ON
from raster_oracle.scenes.loader import load

W, H = 80, 45


@pytest.mark.parametrize("name", ["occluder-rect", "occluder-sun"])
def test_one_ray_a_pixel_is_an_unbiased_estimate_of_the_truth(name):
    sc = load(name, width=W, height=H, n_frames=4)
    f = build_frame(sc, 0, None)
    ch, _ = render_reference(sc, ReferenceSettings(spp=4, channels=("soft",)), quiet=True)
    r = f.receiver
    truth = ch["light_fraction"][r]
    assert 0.02 < 1 - truth.mean() < 0.5  # there are shadows to estimate
    # a mean of ~3500 Bernoulli samples: standard error below 0.006; 4 sigma
    se = np.sqrt(np.mean(truth * (1 - truth)) / r.sum())
    assert abs(f.noisy[r].mean() - truth.mean()) < 4 * se + 2e-3
    # and pixel by pixel the noisy value is 0 or 1, in the penumbra either
    assert set(np.unique(f.noisy[r])) <= {0.0, 1.0}
    assert f.rays == int(r.sum())


def test_frames_are_cached_and_reproducible():
    sc = load("occluder-rect", width=W, height=H, n_frames=4)
    run = model.make_runner("rtshadows-ffx", "ffx")
    model._STATES.clear()
    a = run(sc.with_frame(2, n_frames=4))
    assert a.diagnostics["frames_run"] == 3
    b = run(sc.with_frame(3, n_frames=4))
    assert b.diagnostics["frames_run"] == 1
    model._STATES.clear()
    c = run(sc.with_frame(3, n_frames=4))
    assert c.diagnostics["frames_run"] == 4
    for k in ("soft_visibility", "noisy"):
        assert np.array_equal(b.outputs[k], c.outputs[k])
    v = c.outputs["soft_visibility"]
    assert v.dtype == np.float32 and np.isfinite(v).all() and v.min() >= 0 and v.max() <= 1
    assert c.cost["rays_per_pixel"] == 1 and c.cost["shadow_rays"] > 0


def test_denoisers_share_the_frames_and_get_what_they_get_alone(monkeypatch):
    """The frames' inputs are the sequence's, not a denoiser's: built once for the five
    models (read-only), each model's output equal to its run on freshly built frames."""
    sc = load("occluder-sun", width=W, height=H, n_frames=4).with_frame(3, n_frames=4)
    built = []
    real = model.build_frame
    monkeypatch.setattr(model, "build_frame", lambda *a: built.append(a[1]) or real(*a))
    model.clear_shared_frames()
    shared = {d: model.make_runner(f"rtshadows-{d}", d)(sc) for d in model.DENOISERS}
    assert built == [0, 1, 2, 3]  # one sequence traced once, whatever the denoisers
    frame = model.shared_frame(sc, 3, None)
    with pytest.raises(ValueError, match="read-only"):
        frame.noisy[0, 0] = 1.0
    for denoiser, result in shared.items():
        model.clear_shared_frames()
        alone = model.make_runner(f"rtshadows-{denoiser}", denoiser)(sc)
        for key in ("soft_visibility", "noisy", "penumbra"):
            assert np.array_equal(alone.outputs[key], result.outputs[key]), (denoiser, key)
    assert len(built) == 4 + 4 * len(model.DENOISERS)


def test_flicker_scene_switches_the_light_off_and_on():
    sc = load("flicker-rect", width=W, height=H, n_frames=FLICKER_ON + 1)
    lit = []
    for k in (FLICKER_OFF - 1, FLICKER_OFF, FLICKER_ON - 1, FLICKER_ON):
        f = build_frame(sc.with_frame(k, n_frames=FLICKER_ON + 1), k, None)
        lit.append(f.noisy[f.receiver].mean())
    assert lit[0] > 0.5 and lit[1] == 0.0 and lit[2] == 0.0 and lit[3] > 0.5


@pytest.mark.parametrize(
    "technique,denoiser", [("rtshadows-ffx", "ffx"), ("rtshadows-sigma", "sigma")]
)
def test_an_integration_that_passes_the_noisy_input_through_fails_the_recommended_gate(
    technique, denoiser
):
    """The silent failure users report (nvpro-samples/vk_denoise_nrd issue 1): the "denoised"
    output is the one-ray input. Scored against the claimed denoiser's model with the
    conformance metrics of ``score --expect``, it fails the recommended gate; the model's own
    output passes it."""
    from raster_oracle.oracle.studies.detection import conformance_values, gate_fails

    sc = load("occluder-rect", width=W, height=H, n_frames=4).with_frame(3, n_frames=4)
    model._STATES.clear()
    res = model.make_runner(technique, denoiser)(sc)
    claimed = res.outputs["soft_visibility"]
    recv = build_frame(sc, 3, None).receiver
    passthrough = conformance_values(claimed, res.outputs["noisy"], recv)
    assert gate_fails(passthrough)
    assert gate_fails(conformance_values(claimed, claimed, recv)) == []
