"""Parameter validation (non-finite values), perspective-light bias defaults, and the Dr.Jit
paths of the compare filters and the partition geometry against their NumPy forms."""

from __future__ import annotations

import re

import numpy as np
import pytest

import raster_models as rm
import scenes
from oracle.cli.app import main
from raster_models.gbuffer import trace_gbuffer
from raster_models.shadowmaps import filters as _filters
from raster_models.shadowmaps import shade as _shade

#: False-lit fraction of receivers allowed for the default spot/point configuration at
#: 2048^2 (measured 0.0001 spot / 0.0005 point at 320x180; the old constant bias 0.005 on
#: hyperbolic depth gave 0.045 / 0.084, every spot shadow and half the point shadows).
FALSE_LIT_MAX = 0.003


def _records(tech):
    from raster_models import params as _params

    return _params.describe(tech.params)


@pytest.mark.parametrize(
    ("technique", "name", "allows_inf"),
    [
        (t, rec["name"], "inf = no limit" in rec["help"])
        for t, tech in rm.TECHNIQUES.items()
        for rec in _records(tech)
        if rec["type"] in ("float", "floats")
    ],
)
def test_every_float_parameter_refuses_non_finite_values(technique, name, allows_inf):
    for text in ("nan", "-inf", "NaN"):
        with pytest.raises(rm.ModelError, match=rf"parameter {name} must be"):
            rm.parse_params(technique, [f"{name}={text}"])
    if allows_inf:
        # Documented in the help ("inf = no limit"), e.g. sdsm max_scale = FLT_MAX.
        assert rm.parse_params(technique, [f"{name}=inf"])[name] in (
            float("inf"),
            (float("inf"),),
        )
    else:
        with pytest.raises(rm.ModelError, match=rf"{name} must be .*finite"):
            rm.parse_params(technique, [f"{name}=inf"])


@pytest.mark.parametrize("pair", ["border_z=inf", "border_xy=inf", "border_z=nan"])
def test_cli_refuses_non_finite_parameters(tmp_path, capsys, pair):
    out = tmp_path / "o"
    rc = main(["model", "sdsm", "plate", "--set", pair, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1
    assert re.search(rf"{pair.split('=')[0]} must be a finite number >= 0, got (inf|nan)", err)


@pytest.mark.slow
@pytest.mark.parametrize("scene_name", ["spot", "point"])
def test_perspective_defaults_keep_spot_and_point_shadows(scene_name):
    """Default spot/point maps at 2048^2 against the oracle's exact shadow ray per pixel."""
    scene = scenes.load(scene_name, width=160, height=90)
    g = trace_gbuffer(scene, with_lit=True)
    rec, lit = g.receiver, g.lit
    assert (~lit[rec]).mean() > 0.03  # the scene has shadows to lose

    def false_lit(**kw):
        vis = rm.run("shadow-map", scene, resolution=2048, **kw).outputs["visibility"].ravel()
        return float(((vis >= 0.5) & ~lit)[rec].mean())

    assert false_lit() < FALSE_LIT_MAX
    # The old default (constant bias on hyperbolic depth) loses the shadows: the test fails
    # without the linear-depth bias.
    assert false_lit(perspective_bias=0.0, perspective_normal_offset=0.0) > 0.03


def test_perspective_bias_is_linear_in_light_depth():
    """The compare reference is the hyperbolic depth of tau (1 - k), k = bias texels."""
    scene = scenes.load("spot", width=16, height=9)
    r = rm.run("shadow-map", scene, resolution=256, filter="point")
    proj_rec = r.diagnostics["partitions"][0]["projection"]
    near, far = proj_rec["near"], proj_rec["far"]
    from raster_models.light_frame import Projection, make_frame

    p = rm.TECHNIQUES["shadow-map"].params()
    frame = make_frame(scene.light.direction, [("y", (0.0, 1.0, 0.0))])
    tan_half = float(np.tan(np.radians(scene.light.cutoff_angle)))
    proj = Projection("persp", frame, (tan_half, near, far), 256)
    a, b = far / (far - near), far * near / (far - near)
    tau = np.array([1.0, 5.0, 10.0])
    ref = _shade.perspective_reference(p, proj, a - b / tau)
    tau_ref = b / (a - ref)
    k = 2.0 * tan_half / 256
    np.testing.assert_allclose(tau_ref, tau * (1.0 - k), rtol=1e-9)


#: The Dr.Jit kernels use FMA contraction; results agree with NumPy to a few ulps.
DRJIT_ULP_TOL = 1e-12


def test_drjit_compare_filters_match_numpy(monkeypatch):
    rng = np.random.default_rng(3)
    r = 32
    depth = rng.uniform(0, 1, (r, r)).astype(np.float32)
    n = 4000
    u, v = rng.uniform(-0.2, 1.2, n), rng.uniform(-0.2, 1.2, n)
    ref = rng.uniform(-0.1, 1.1, n)
    u[:200] = (np.arange(200) % r + 0.5 + 0.5 / 256) / r  # sub-texel ties (round half even)
    for address in ("clamp", "border"):
        for bits in (0, 8):
            got = {}
            for threshold in (1 << 62, 1):
                monkeypatch.setattr(_filters, "DRJIT_MIN_LOOKUPS", threshold)
                got[threshold] = [
                    _filters.compare_point(depth, u, v, ref, address=address),
                    _filters.compare_bilinear(
                        depth, u, v, ref, address=address, subtexel_bits=bits
                    ),
                    *[
                        _filters.pcf_grid(depth, u, v, ref, s, address=address, subtexel_bits=bits)
                        for s in (2, 3, 5)
                    ],
                ]
            for a, b in zip(got[1 << 62], got[1], strict=True):
                np.testing.assert_allclose(b, a, rtol=0, atol=DRJIT_ULP_TOL)
                assert a.std() > 0  # both lit and shadowed taps


@pytest.mark.parametrize(
    ("scene_name", "technique", "kw"),
    [
        ("city", "sdsm", {"filter": "pcf"}),
        ("city", "csm", {"receiver_plane_bias": True, "filter": "pcf", "normal_offset": 1.0}),
        ("spot", "shadow-map", {"filter": "poisson"}),
        ("point", "shadow-map", {"filter": "hw_pcf"}),
    ],
)
def test_drjit_geometry_matches_numpy(monkeypatch, scene_name, technique, kw):
    scene = scenes.load(scene_name, width=96, height=54)
    outs = []
    for threshold in (1 << 62, 1):
        monkeypatch.setattr(_shade, "DRJIT_MIN_PIXELS", threshold)
        monkeypatch.setattr(_filters, "DRJIT_MIN_LOOKUPS", threshold)
        outs.append(rm.run(technique, scene, resolution=256, **kw).outputs)
    for key in outs[0]:
        np.testing.assert_array_equal(outs[1][key], outs[0][key])
    assert outs[0]["texels_per_pixel"].max() > 0


def test_projection_selection_checks_depth_too():
    """CSM projection selection picks a cascade only when the pixel is inside its whole
    texture volume, depth included (the ``thin`` scene had 10 receivers selected into a
    cascade whose depth range they are outside of)."""
    from raster_models import params as _params
    from raster_models.shadowmaps import csm

    scene = scenes.load("thin", width=160, height=90)
    g = trace_gbuffer(scene)
    p = _params.make("csm", csm.CsmParams, {"selection": "projection", "resolution": 512})
    setup = csm.build(scene, g, p)
    idx = np.nonzero(g.valid)[0]
    sel = _shade._select(setup, g, idx, p)
    assert (sel >= 0).mean() > 0.9
    for i, part in enumerate(setup.partitions):
        _, _, z, _ = part.projection.project(g.position[idx[sel == i]])
        assert ((z >= 0) & (z <= 1)).all()
