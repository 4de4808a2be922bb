"""AGAA's Dr.Jit frame (:mod:`raster_models.aa.agaa.kernels`) against the NumPy references of
its rules (:mod:`tests.aa_reference`): the per-pixel grouping and clustering, and the
material accumulation, shading and resolve in float64."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models.aa import samples, trace
from raster_oracle.raster_models.aa.agaa import kernels, pixels
from raster_oracle.scenes import backend
from raster_oracle.scenes.backend.raycast import shape_table

from raster_oracle import raster_models as rm
from raster_oracle import scenes
from tests.aa_reference import agaa_colors, cluster, first_of_key, quantize_normals

SMALL = {"width": 64, "height": 36}
#: The frame's colour against the float64 reference: the model averages at most 16 samples'
#: attributes in float32 and shades in float32 (normalizations, Toksvig's factor, a power
#: of the half-vector cosine up to the shininess, which multiplies relative errors); the
#: float32 positions also move the test's visibility function. Measured: at most 3.1e-5
#: relative (city, glossy's highlights), 7e-7 absolute on colours near 0; a wrong aggregate
#: or weight differs by more than 1e-2.
COLOR_RTOL = 1e-4
COLOR_ATOL = 1e-6
#: Pixels whose aggregates may differ from the float32 NumPy rule: none where float32 and
#: float64 evaluations of the rule agree (no decision at a rounding tie); the ties are pixels
#: whose distances are equal in exact arithmetic (thin's symmetric slats: 0.35 %).
TIE_FRACTION = 1e-2
#: Stored normals against the NumPy rule: rgb10a2 and rgba16f take the same float32 steps
#: (one ulp of slack); oct16's NumPy rule has float64 intermediates, so a value at a
#: half-step may round to the next SNORM16 step (1/32767), which the final normalization
#: can stretch to at most two steps.
NORMAL_TOL = {"rgb10a2": 1.2e-7, "rgba16f": 1.2e-7, "oct16": 2.0 / 32767}


def _prepass(scene, n, k, fmt, threshold=0.1, weight=1.0):
    """The frame's per-pixel prepass: ``(first, aggregate, rep_bits)`` as ``(P, N)`` arrays
    (``rep_bits`` ``(P, N)`` bool) and the samples' view depth and normal (NumPy)."""
    mi = backend.mitsuba()
    import drjit as dr

    offs = samples.positions(n)
    ox, oy = mi.Float(offs[:, 0]), mi.Float(offs[:, 1])
    n_pix = scene.width * scene.height
    pix = dr.arange(mi.UInt32, n_pix)
    table = shape_table(mi, dr, scene)
    valid, depth, prim, shape, nrm, _ = trace.prepass_dr(
        scene, scene.mi_scene, table, ox, oy, pix, n, normals=True, group=False
    )
    first, agg, rep_bits = pixels.pixel_prepass(
        mi, dr, (valid, depth, prim, shape, nrm), n, k, threshold, weight, fmt
    )
    dr.eval(first, agg, rep_bits)
    return {
        "valid": valid.numpy().reshape(n_pix, n),
        "shape": shape.numpy().reshape(n_pix, n),
        "prim": prim.numpy().reshape(n_pix, n),
        "depth": depth.numpy().reshape(n_pix, n),
        "normal": trace.to_numpy(nrm).T.reshape(n_pix, n, 3),
        "first": np.stack([f.numpy() for f in first], axis=1).astype(np.int64),
        "aggregate": np.stack([a.numpy() for a in agg], axis=1),
        "rep": ((rep_bits.numpy()[:, None] >> np.arange(n)) & 1).astype(bool),
    }


def _smooth_visibility(attrs):
    """A visibility in [0, 1] that varies smoothly with the shading point (so the
    comparison within a tolerance also checks which aggregate it was given to)."""
    p = np.asarray(attrs["position"], np.float64)
    return 0.5 + 0.5 * np.sin(3.0 * p[:, 0] + 2.0 * p[:, 1] - p[:, 2])


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("foliage", {"samples": 16, "normal_format": "rgb10a2"}),
        ("foliage", {"samples": 8, "aggregates": 1, "normal_format": "oct16"}),
        ("glossy", {"samples": 8, "normal_format": "rgba16f"}),
        ("thin", {"samples": 4}),
        ("city", {"samples": 2}),
        ("foliage", {"samples": 1}),
    ],
)
def test_frame_equals_float64_reference(name, params):
    """The frame's colour with a given visibility equals the float64 reference of
    accumulation, shading and resolve on the frame's own fragments and aggregates, within
    :data:`COLOR_RTOL`; counts equal exactly; no shadow ray is cast."""
    scene = scenes.load(name, **SMALL)
    p = rm.AgaaParams(**params)
    offs = samples.positions(p.samples)
    got = kernels.render(
        scene,
        offs,
        k=p.aggregates,
        threshold=p.threshold,
        depth_weight=p.depth_weight,
        fmt=p.normal_format,
        visibility=_smooth_visibility,
    )
    pre = _prepass(scene, p.samples, p.aggregates, p.normal_format)
    expect = agaa_colors(scene, offs, pre["first"], pre["aggregate"], visibility=_smooth_visibility)
    assert np.allclose(got["color"], expect, rtol=COLOR_RTOL, atol=COLOR_ATOL)
    assert got["shadow_rays"] == 0
    n_pix = scene.width * scene.height
    valid = pre["first"] < p.samples
    assert np.array_equal(got["covered"], valid.sum(axis=1))
    assert np.array_equal(got["surfaces"], pre["rep"].sum(axis=1))
    n_agg = np.zeros(n_pix, np.int64)
    for a in range(p.aggregates):
        n_agg += ((pre["aggregate"] == a) & valid).any(axis=1)
    assert np.array_equal(got["aggregates"], n_agg)
    assert expect.max() > 0.05


def test_shadow_technique_goes_through_the_frame():
    """``shadows=shadow-map`` runs the same frame with the technique's visibility at the
    aggregates: no shadow ray, the counts of the exact frame, the colour of exact rays except
    near shadow edges."""
    scene = scenes.load("city", **SMALL)
    exact = rm.run("agaa", scene)
    mapped = rm.run("agaa", scene, shadows="shadow-map")
    assert exact.cost["shadow_rays"] > 0 and mapped.cost["shadow_rays"] == 0
    for key in ("coverage", "aggregates", "surfaces"):
        assert np.array_equal(exact.outputs[key], mapped.outputs[key]), key
    # the map agrees with exact rays away from shadow edges, not on all of them
    same = np.isclose(exact.outputs["color"], mapped.outputs["color"], rtol=1e-4, atol=1e-6)
    assert 0.8 < same.all(axis=2).mean() < 1.0


def test_frame_launch_by_launch(monkeypatch):
    """Launches of two pixel rows, some of them all sky (the star's top rows: no fragment
    in the launch) give the bytes of one launch."""
    scene = scenes.load("star", **SMALL)
    kw = {"k": 2, "threshold": 0.1, "depth_weight": 1.0, "fmt": "rgb10a2"}
    whole = kernels.render(scene, samples.positions(8), **kw)
    monkeypatch.setattr(trace, "CHUNK", 8 * 2 * SMALL["width"] // kernels.LAUNCH_CHUNKS)
    parts = kernels.render(scene, samples.positions(8), **kw)
    rows = parts["covered"].reshape(SMALL["height"], SMALL["width"]).sum(axis=1)
    assert (rows[0::2] + rows[1::2] == 0).any()  # a launch without a surface
    for key, val in whole.items():
        assert np.asarray(parts[key]).tobytes() == np.asarray(val).tobytes(), key


@pytest.mark.parametrize(
    ("name", "n", "fmt", "k"),
    [
        ("foliage", 16, "rgb10a2", 2),
        ("foliage", 8, "oct16", 2),
        ("thin", 4, "rgba16f", 2),
        ("glossy", 2, "rgb10a2", 2),
        ("foliage", 1, "rgb10a2", 2),
        ("foliage", 8, "rgb10a2", 1),
    ],
)
def test_pixel_lanes_follow_the_numpy_rules(name, n, fmt, k):
    """Fragment representatives from one lane a pixel equal the NumPy grouping sample for
    sample; aggregates equal the NumPy clustering (on the NumPy-stored normals) wherever
    float32 rounding cannot flip the rule's decision (float32 and float64 agree), and the
    other samples are at most :data:`TIE_FRACTION`."""
    scene = scenes.load(name, **SMALL)
    pre = _prepass(scene, n, k, fmt)
    v = pre["valid"]
    assert np.array_equal(np.where(v, first_of_key(v, pre["shape"], pre["prim"]), n), pre["first"])
    assert np.array_equal(pre["rep"], v & (pre["first"] == np.arange(n)))
    stored = quantize_normals(pre["normal"], fmt)
    ref32 = cluster(v, pre["depth"], stored, k, 0.1, 1.0)
    ref64 = cluster(v, pre["depth"], stored, k, 0.1, 1.0, dtype=np.float64)
    robust = (ref32 == ref64).all(axis=1)
    assert np.array_equal(pre["aggregate"][robust], ref32[robust])
    assert (~robust).mean() <= TIE_FRACTION
    if k == 2 and n >= 4:
        assert (pre["aggregate"] == 1).any()


@pytest.mark.parametrize("fmt", ["rgb10a2", "oct16", "rgba16f"])
def test_stored_normals_match_numpy(fmt):
    """:func:`raster_models.aa.pixel_dr.store_normal` equals the NumPy storage rule within
    :data:`NORMAL_TOL`."""
    from raster_oracle.raster_models.aa.pixel_dr import store_normal

    mi = backend.mitsuba()
    import drjit as dr

    r = np.random.default_rng(1).normal(size=(5000, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    got = store_normal(mi, dr, mi.Vector3f(*(mi.Float(r[:, a]) for a in range(3))), fmt)
    got = trace.to_numpy(got).T
    assert np.abs(got - quantize_normals(r, fmt)).max() <= NORMAL_TOL[fmt]
