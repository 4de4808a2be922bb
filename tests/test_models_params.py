"""Parameter validation (non-finite values), perspective-light bias defaults, and the Dr.Jit
paths of the compare filters and the partition geometry against their NumPy forms."""

from __future__ import annotations

import re

import numpy as np
import pytest
from raster_oracle.oracle.cli.app import main
from raster_oracle.raster_models import params
from raster_oracle.raster_models.gbuffer import trace_gbuffer
from raster_oracle.raster_models.shadowmaps import csm, filters, geometry, sdsm, shade, shadow_map

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests._shadow_reference import projection_derivative

#: False-lit fraction of receivers allowed for the default spot/point configuration at
#: 2048^2 (measured 0.0001 spot / 0.0005 point at 320x180; the old constant bias 0.005 on
#: hyperbolic depth gave 0.045 / 0.084, every spot shadow and half the point shadows).
FALSE_LIT_MAX = 0.003

#: Each shadow-map technique's set-up (where its maps go).
BUILD = {"shadow-map": shadow_map.build, "csm": csm.build, "sdsm": sdsm.build}


def _records(tech):
    return params.describe(tech.params)


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
    from raster_oracle.raster_models.light_frame import Projection, make_frame

    p = rm.TECHNIQUES["shadow-map"].params()
    frame = make_frame(scene.light.direction, [("y", (0.0, 1.0, 0.0))])
    tan_half = float(np.tan(np.radians(scene.light.cutoff_angle)))
    proj = Projection("persp", frame, (tan_half, near, far), 256)
    a, b = far / (far - near), far * near / (far - near)
    tau = np.array([1.0, 5.0, 10.0])
    ref = shade.perspective_reference(p, proj, a - b / tau)
    tau_ref = b / (a - ref)
    k = 2.0 * tan_half / 256
    np.testing.assert_allclose(tau_ref, tau * (1.0 - k), rtol=1e-9)


#: The Dr.Jit compare kernel against the NumPy reference below: the weights are the same
#: float64 operations, but the LLVM backend contracts ``w * lit + acc`` into FMAs, so sums
#: of tap weights may differ in the last bits (a few ulps of values <= 1).
DRJIT_ULP_TOL = 1e-12


def _fetch_reference(depth_map, ix, iy, address):
    r = depth_map.shape[0]
    vals = depth_map.reshape(-1).take(np.clip(iy, 0, r - 1) * r + np.clip(ix, 0, r - 1))
    if address == "border":
        inside = (ix >= 0) & (ix < r) & (iy >= 0) & (iy < r)
        return np.where(inside, vals, 1.0)
    return vals


def _compare_reference(depth_map, u, v, ref, size, *, address, subtexel_bits):
    """NumPy form of :func:`filters.compare_taps`: nearest texel (``size=0``) or the
    ``(size + 1)^2`` footprint of ``size x size`` bilinear compare taps."""
    r = depth_map.shape[0]
    refc = np.clip(ref, 0.0, 1.0)
    if size == 0:
        ix, iy = np.floor(u * r).astype(np.int64), np.floor(v * r).astype(np.int64)
        return (refc <= _fetch_reference(depth_map, ix, iy, address)).astype(np.float64)
    half = (size - 1) / 2.0
    x, y = u * r - 0.5 - half, v * r - 0.5 - half
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    if subtexel_bits > 0:
        scale = float(1 << subtexel_bits)
        fx, fy = np.round(fx * scale) / scale, np.round(fy * scale) / scale
    ix0, iy0 = x0.astype(np.int64), y0.astype(np.int64)

    def weights(f, m):
        return (1.0 - f) * (m < size) + f * (m > 0)

    acc = np.zeros_like(u)
    for my in range(size + 1):
        for mx in range(size + 1):
            lit = refc <= _fetch_reference(depth_map, ix0 + mx, iy0 + my, address)
            acc += weights(fy, my) * weights(fx, mx) * lit
    return acc / float(size * size)


def test_drjit_compare_filters_match_numpy_reference():
    rng = np.random.default_rng(3)
    r = 32
    depth = rng.uniform(0, 1, (r, r)).astype(np.float32)
    texels = filters.upload_texels(depth)
    n = 4000
    u, v = rng.uniform(-0.2, 1.2, n), rng.uniform(-0.2, 1.2, n)
    ref = rng.uniform(-0.1, 1.1, n)
    u[:200] = (np.arange(200) % r + 0.5 + 0.5 / 256) / r  # sub-texel ties (round half even)
    for address in ("clamp", "border"):
        for bits in (0, 8):
            for size in (0, 1, 2, 3, 5):
                got = filters.compare_taps(
                    texels, u, v, ref, size, address=address, subtexel_bits=bits
                )
                want = _compare_reference(
                    depth, u, v, ref, size, address=address, subtexel_bits=bits
                )
                np.testing.assert_allclose(got, want, rtol=0, atol=DRJIT_ULP_TOL)
                assert want.std() > 0  # both lit and shadowed taps


#: The Dr.Jit shading geometry against :meth:`Projection.project` / ``derivative`` in NumPy:
#: the same float64 quantities by a different operation order (explicit sums with FMA
#: contraction against matrix products), a few ulps, amplified by ``1/w`` and by the
#: singular-value formula for the texel density.
GEOMETRY_RTOL = 1e-9

#: Absolute tolerance of texture coordinates and depth: they are differences of terms of the
#: light matrix times world positions (up to ~1e6 for SDSM's tight partitions), so rounding
#: is an ulp of those terms, ~1e-10, whatever the result's own size.
GEOMETRY_ATOL = 1e-9

#: With ``matrix_precision="float32"`` the projection runs in float32 on both sides, by a
#: different operation order (FMA against NumPy's matrix product): a few float32 ulps
#: (2^-24 ~ 6e-8) of coordinates near [0, 1] (measured <= 2.4e-7), and as much relative
#: error in the Jacobian through ``u, v, z, w``.
GEOMETRY_ATOL_F32 = 1e-6
GEOMETRY_RTOL_F32 = 1e-5


@pytest.mark.parametrize(
    ("scene_name", "technique", "kw"),
    [
        ("city", "sdsm", {"filter": "pcf"}),
        ("city", "csm", {"receiver_plane_bias": True, "filter": "pcf", "normal_offset": 1.0}),
        ("spot", "shadow-map", {"filter": "poisson"}),
        ("point", "shadow-map", {"filter": "hw_pcf"}),
        ("city", "csm", {"matrix_precision": "float32", "normal_offset": 1.0}),
        ("spot", "shadow-map", {"matrix_precision": "float32"}),
    ],
)
def test_drjit_geometry_matches_numpy_reference(scene_name, technique, kw):
    scene = scenes.load(scene_name, width=96, height=54)
    tech = rm.TECHNIQUES[technique]
    p = params.make(technique, tech.params, {"resolution": 256, **kw})
    gb = trace_gbuffer(scene)
    setup = BUILD[technique](scene, gb, p)
    checked = 0
    for part in setup.partitions:
        if part.projection is None:
            continue
        proj = part.projection
        pix = np.nonzero(gb.valid)[0]
        geo = geometry.partition_geometry(p, part, gb, pix)
        pos = gb.position[pix]
        offset = geometry.normal_offset_texels(p, proj)
        if offset > 0.0:
            _, _, _, w = proj.project(pos)
            texel = np.broadcast_to(proj.texel_world_size(w), len(pix))
            scale = offset * texel * (1.0 - np.clip(gb.cos_l[pix], 0.0, 1.0))
            pos = pos + gb.normal[pix] * scale[:, None]
        u, v, z, w = proj.project(pos)
        jac = projection_derivative(proj, u, v, z, w)
        j3 = np.einsum("nij,njk->nik", jac, np.stack([gb.dpdx[pix], gb.dpdy[pix]], axis=-1))
        tpp = np.linalg.svd(j3[:, :2, :] * proj.resolution, compute_uv=False)[:, -1]
        # Near the map (texture coordinates far outside it lose digits to cancellation).
        ok = (np.abs(u - 0.5) < 2.0) & (np.abs(v - 0.5) < 2.0) & (w > 0)
        f32 = p.matrix_precision == "float32"
        atol = GEOMETRY_ATOL_F32 if f32 else GEOMETRY_ATOL
        for got, want in ((geo["u"], u), (geo["v"], v), (geo["z"], z)):
            np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=atol)
        rtol = GEOMETRY_RTOL_F32 if f32 else GEOMETRY_RTOL
        np.testing.assert_allclose(geo["tpp"][ok], tpp[ok], rtol=rtol)
        if p.receiver_plane_bias:
            np.testing.assert_allclose(geo["j3"][ok], j3[ok], rtol=GEOMETRY_RTOL, atol=1e-15)
        checked += int(ok.sum())
    assert checked > 1000


def test_projection_selection_checks_depth_too():
    """CSM projection selection picks a cascade only when the pixel is inside its whole
    texture volume, depth included (the ``thin`` scene had 10 receivers selected into a
    cascade whose depth range they are outside of)."""
    scene = scenes.load("thin", width=160, height=90)
    g = trace_gbuffer(scene)
    p = params.make("csm", csm.CsmParams, {"selection": "projection", "resolution": 512})
    setup = csm.build(scene, g, p)
    idx = np.nonzero(g.valid)[0]
    sel = shade.select_partitions(setup, g, idx, p)
    assert (sel >= 0).mean() > 0.9
    for i, part in enumerate(setup.partitions):
        _, _, z, _ = part.projection.project(g.position[idx[sel == i]])
        assert ((z >= 0) & (z <= 1)).all()
