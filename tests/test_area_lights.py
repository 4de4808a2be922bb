"""Area lights (issue 38): the XML loader, lights.json and the export's scene.xml, the colour
under an area light against Mitsuba's own ``direct`` integrator and a sphere light's closed
form, and the ``soft`` group's sampling (punctual lights, chunking, adaptive refinement)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from raster_oracle.oracle.cli import main
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.catalogue.builtin import BuiltinScene
from raster_oracle.scenes.catalogue.factories import ground, sensor
from raster_oracle.scenes.catalogue.soft_scenes import soft_contact
from raster_oracle.scenes.loaded import SceneError
from raster_oracle.scenes.shading.materials import diffuse
from scipy.special import erfc

from raster_oracle import scenes

SENSOR = (
    '<sensor type="perspective"><float name="fov" value="50"/><transform name="to_world">'
    '<lookat origin="0,6,6" target="0,0,0" up="0,1,0"/></transform><film type="hdrfilm">'
    '<integer name="width" value="32"/><integer name="height" value="18"/></film></sensor>'
    '<shape type="rectangle"><transform name="to_world"><scale value="20"/>'
    '<rotate x="1" angle="-90"/></transform></shape>'
)


def _xml(tmp_path, body: str, name="s.xml"):
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">{SENSOR}{body}</scene>')
    return path


def _area(shape: str, transform: str, radiance="2,3,4", extra="") -> str:
    return (
        f'<shape type="{shape}" id="lamp_{shape}">{extra}<transform name="to_world">{transform}'
        f'</transform><emitter type="area"><rgb name="radiance" value="{radiance}"/></emitter>'
        "</shape>"
    )


RECT = _area(
    "rectangle",
    '<scale x="0.8" y="0.3"/><rotate x="1" angle="90"/><rotate y="1" angle="30"/>'
    '<translate x="1" y="4" z="-1"/>',
)
DISK = _area("disk", '<scale value="0.5"/><rotate x="1" angle="120"/><translate y="3"/>')
SPHERE = _area("sphere", '<scale value="0.25"/><translate x="-1" y="2" z="0.5"/>')


def test_xml_area_lights_are_read(tmp_path):
    path = _xml(tmp_path, RECT + DISK + SPHERE)
    rect, disk, sphere = (scenes.load(path, light=i).light for i in range(3))
    assert (rect.area, disk.area, sphere.area) == ("rectangle", "disk", "sphere")
    assert rect.name == "lamp_rectangle" and rect.kind == "point"
    np.testing.assert_allclose(rect.half_size, (0.8, 0.3), rtol=1e-6)
    np.testing.assert_allclose(rect.position, (1, 4, -1), atol=1e-6)
    # rotate x by 90: local +Z (the emitting side) to -Y; then 30 degrees about Y keeps it
    np.testing.assert_allclose(rect.direction, (0, -1, 0), atol=1e-6)
    t, b, n = rect.frame
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-6)
    np.testing.assert_allclose(
        t, (math.cos(math.radians(30)), 0, -math.sin(math.radians(30))), atol=1e-6
    )
    np.testing.assert_allclose(rect.radiance, (2, 3, 4))
    np.testing.assert_allclose(rect.color, np.array([2, 3, 4]) * 4 * 0.8 * 0.3, rtol=1e-6)
    np.testing.assert_allclose(disk.radius, 0.5, rtol=1e-6)
    np.testing.assert_allclose(disk.direction, (0, -math.cos(math.radians(30)), -0.5), atol=1e-6)
    np.testing.assert_allclose(disk.color, np.array([2, 3, 4]) * math.pi * 0.25, rtol=1e-6)
    np.testing.assert_allclose(sphere.position, (-1, 2, 0.5), atol=1e-6)
    assert sphere.radius == pytest.approx(0.25) and sphere.shadow_end == pytest.approx(0.25)
    assert sphere.surface_area == pytest.approx(4 * math.pi * 0.0625)
    record = json.loads(json.dumps(rect.to_json()))
    assert record["area"]["shape"] == "rectangle"
    np.testing.assert_allclose(record["area"]["size"], (1.6, 0.6), rtol=1e-6)
    np.testing.assert_allclose(record["area"]["normal"], (0, -1, 0), atol=1e-6)
    assert "radius" in json.loads(json.dumps(sphere.to_json()))["area"]


def test_area_points_cover_the_light_uniformly(tmp_path):
    rect, disk = (scenes.load(_xml(tmp_path, RECT + DISK), light=i).light for i in range(2))
    rng = np.random.default_rng(1)
    u, v = rng.random(200_000), rng.random(200_000)
    for light in (rect, disk):
        t, b, n = light.frame
        d = light.area_point(u, v) - np.asarray(light.position)
        np.testing.assert_allclose(d @ n, 0.0, atol=1e-9)  # in the light's plane
        s, r = d @ t, d @ b
        if light.area == "rectangle":
            a0, a1 = light.half_size
            assert np.abs(s).max() <= a0 + 1e-9 and np.abs(r).max() <= a1 + 1e-9
            assert np.mean(s > 0.5 * a0) == pytest.approx(0.25, abs=0.005)
        else:
            rho2 = (s * s + r * r) / light.radius**2
            assert rho2.max() <= 1 + 1e-9
            # uniform in area: P(rho^2 < q) = q, P(angle in a quadrant) = 1/4
            assert np.mean(rho2 < 0.3) == pytest.approx(0.3, abs=0.005)
            assert np.mean((s > 0) & (r > 0)) == pytest.approx(0.25, abs=0.005)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            _area("rectangle", '<matrix value="1 0.5 0 0  0 1 0 3  0 0 1 0  0 0 0 1"/>'),
            "without shear",
        ),
        (_area("disk", '<scale x="1" y="0.5"/><translate y="3"/>'), "must be round"),
        (_area("sphere", '<scale x="1" y="2" z="1"/><translate y="3"/>'), "scaled uniformly"),
        (_area("cube", '<translate y="3"/>'), "no usable light.*AreaLight on a Cube"),
        # issue 48: singular transforms and radiance that is not finite and non-negative
        (_area("rectangle", '<scale x="1" y="1" z="0"/><translate y="3"/>'), "singular"),
        (_area("disk", '<scale x="1" y="1" z="0"/><translate y="3"/>'), "lamp_disk.*singular"),
        (_area("disk", '<translate y="3"/>', radiance="-1,1,1"), "finite, non-negative"),
        (_area("rectangle", '<translate y="3"/>', radiance="1e30,1,1"), "at most 1e\\+15"),
        (_area("sphere", '<translate y="3"/>', radiance="inf,1,1"), "finite, non-negative"),
        (_area("sphere", '<translate y="3"/>', radiance="nan,1,1"), "finite, non-negative"),
    ],
)
def test_bad_area_lights_are_one_line_exit_2(tmp_path, monkeypatch, capsys, body, message):
    monkeypatch.chdir(tmp_path)
    path = _xml(tmp_path, body)
    with pytest.raises(SceneError, match=message):
        scenes.load(path)
    out = tmp_path / "out"
    assert main(["reference", str(path), "--out", str(out), "--quiet", "--no-cache"]) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, err) and len(err.splitlines()) == 1 and not out.exists()


def test_an_area_light_on_a_mesh_is_ignored_beside_a_usable_light(tmp_path):
    sun = '<emitter type="directional"><vector name="direction" value="0,-1,0"/></emitter>'
    loaded = scenes.load(_xml(tmp_path, _area("cube", '<translate y="3"/>') + sun))
    assert [lt.kind for lt in loaded.lights] == ["directional"]


def test_punctual_lights_keep_their_indices_before_area_lights(tmp_path):
    sun = '<emitter type="directional"><vector name="direction" value="0,-1,0"/></emitter>'
    loaded = scenes.load(_xml(tmp_path, SPHERE + sun + RECT))
    assert [lt.area for lt in loaded.lights] == ["", "sphere", "rectangle"]


def test_light_paths_refuse_area_lights():
    with pytest.raises(SceneError, match="moves punctual lights.*rectangle area light"):
        scenes.load("soft-contact", width=32, height=18, light_path="moving-point", frame=1)


def test_export_writes_the_area_light_and_loads_back(tmp_path):
    from raster_oracle.scenes.formats.export import export

    loaded = scenes.load("soft-contact", width=48, height=27)
    summary = export(loaded, tmp_path / "exp")
    lights = json.loads((tmp_path / "exp" / "lights.json").read_text())
    area = lights["lights"][0]["area"]
    assert area["shape"] == "rectangle" and area["size"] == [1.0, 1.0]
    np.testing.assert_allclose(area["normal"], (0, -1, 0), atol=1e-12)
    np.testing.assert_allclose(area["centre"], (-2.5, 5.0, -0.5))
    assert area["radiance"] == [40.0] * 3
    assert summary["shapes"]["area_light"]["area_light"] is True
    back = scenes.load(tmp_path / "exp" / "scene.xml")
    lt, orig = back.light, loaded.light
    assert lt.area == "rectangle" and len(back.lights) == 1
    for field in ("position", "direction", "radiance", "color"):
        np.testing.assert_allclose(getattr(lt, field), getattr(orig, field), atol=1e-6)
    np.testing.assert_allclose(lt.axes, orig.axes, atol=1e-6)
    # the emitter is the light's shape alone: no PLY copy of it in scene.xml
    xml = (tmp_path / "exp" / "scene.xml").read_text()
    assert xml.count('type="rectangle"') == 1 and "0005_area_light" not in xml
    assert len(back.shape_names) == len(loaded.shape_names)


def _crosscheck(mi, loaded, spp=64):
    """Per pixel-channel Z-test of our colour against Mitsuba's ``direct`` (four seeds),
    Sidak-corrected at alpha 0.01, as tests/test_mitsuba_crosscheck.py."""
    ch, _ = render_reference(
        loaded, ReferenceSettings(spp=spp, seed=3, channels=("color",)), quiet=True
    )
    ours = np.stack([ch[f"color.{c}"] for c in "RGB"], -1).astype(np.float64)
    ours_se = np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1).astype(np.float64)
    integrator = mi.load_dict({"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})
    runs = np.stack(
        [
            np.array(mi.render(loaded.mi_scene, integrator=integrator, spp=256, seed=k))
            for k in range(4)
        ]
    ).astype(np.float64)
    theirs, theirs_se = runs.mean(0), runs.std(0, ddof=1) / 2.0

    def passing(a):
        z = np.abs(a - theirs) / np.sqrt(ours_se**2 + theirs_se**2 + 1e-8)
        alpha = 1 - (1 - 0.01) ** (1 / z.size)
        return np.mean(erfc(z / np.sqrt(2)) >= alpha)

    return passing(ours), passing(ours * 1.03), ours


def _with_light(light: dict):
    def factory(width, height):
        scene = soft_contact(width, height)
        scene["area_light"] = light
        return scene

    return BuiltinScene("soft-variant", factory, "soft-contact under another light")


@pytest.mark.parametrize("shape", ["rectangle", "disk", "sphere"])
def test_area_light_colour_agrees_with_mitsuba_direct(mi, shape):
    if shape == "rectangle":
        spec = "soft-contact"
    else:
        emitter = {"type": "area", "radiance": {"type": "rgb", "value": [30.0] * 3}}
        if shape == "disk":
            m = np.eye(4)
            m[:3, :3] = 0.6 * np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
            m[:3, 3] = (-2.5, 5.0, -0.5)
            light = {"type": "disk", "to_world": m, "bsdf": diffuse(0.0), "emitter": emitter}
        else:
            light = {"type": "sphere", "center": [-2.0, 3.5, 0.5], "radius": 0.4}
            light.update(bsdf=diffuse(0.0), emitter=emitter)
        spec = _with_light(light)
    loaded = scenes.load(spec, width=48, height=27)
    assert loaded.light.area == shape
    ok, biased, ours = _crosscheck(mi, loaded)
    assert ours.mean() > 0.05
    assert ok >= 0.9975 and biased < 0.9975


def test_sphere_light_colour_matches_its_closed_form():
    """A sphere light over a bare plane, seen straight down: a diffuse receiver wholly above
    whose horizon the sphere lies reflects ``rho L sin^2(alpha) cos(theta)`` (Nusselt: the
    sphere's projected solid angle), ``alpha`` its angular radius, ``theta`` the angle of its
    centre from the normal; soft visibility and light fraction are 1."""
    c, r, rad, rho = np.array([0.3, 1.2, -0.2]), 0.4, 5.0, 0.5

    def factory(width, height):
        emitter = {"type": "area", "radiance": {"type": "rgb", "value": [rad] * 3}}
        return {
            "type": "scene",
            "camera": sensor(
                width,
                height,
                origin=(0, 0.7, 0),
                target=(0, 0, 0),
                up=(0, 0, 1),
                fov=60,
                near=0.01,
                far=10,
            ),
            "ball": {"type": "sphere", "center": list(c), "radius": r, "emitter": emitter},
            "ground": ground(10.0, rho),
        }

    loaded = scenes.load(BuiltinScene("ball-light", factory, "sphere light"), width=48, height=27)
    ch, _ = render_reference(
        loaded, ReferenceSettings(spp=16, channels=("color", "soft", "position")), quiet=True
    )
    p = np.stack([ch[f"position.{a}"] for a in "XYZ"], -1).astype(np.float64)
    to = c - p
    d = np.linalg.norm(to, axis=-1)
    expect = rho * rad * (r / d) ** 2 * to[..., 1] / d
    got = ch["color.R"].astype(np.float64)
    se = ch["color_stderr.R"].astype(np.float64)
    # the pixel-centre closed form against the pixel mean: equal to the curvature over a
    # pixel (< 1e-3 relative here) and the sampling noise
    assert np.mean(np.abs(got - expect) <= 4 * se + 1e-3 * expect) >= 0.999
    assert np.median(se / expect) < 0.01
    assert np.all(ch["soft_visibility"] == 1.0) and np.all(ch["light_fraction"] == 1.0)


def test_an_unnamed_sphere_light_does_not_shadow_itself(tmp_path):
    """Rays near a sphere light's silhouette graze it: their end points' rounding exceeds the
    shadow ray's margin, so the light's own shape is found (by geometry: this one has no id)
    and ignored; over a bare plane both soft channels are then exactly 1."""
    body = (
        '<shape type="sphere"><point name="center" x="0" y="6.5" z="2"/>'
        '<float name="radius" value="0.4"/><emitter type="area"/></shape>'
    )
    loaded = scenes.load(_xml(tmp_path, body))
    assert loaded.light.area == "sphere" and loaded.light.name == "emitter_0"
    ch, _ = render_reference(loaded, ReferenceSettings(spp=8, channels=("soft",)), quiet=True)
    assert np.all(ch["light_fraction"] == 1.0) and np.all(ch["soft_visibility"] == 1.0)


def test_a_punctual_lights_soft_channels_are_its_visibility():
    loaded = scenes.load("plate", width=48, height=27)
    ch, stats = render_reference(
        loaded, ReferenceSettings(spp=16, channels=("visibility", "soft")), quiet=True
    )
    for name in ("soft_visibility", "light_fraction"):
        np.testing.assert_array_equal(ch[name], ch["visibility"])
        penumbra = (ch["visibility"] > 0) & (ch["visibility"] < 1)
        np.testing.assert_array_equal(
            ch[f"{name}_stderr"][~penumbra], ch["visibility_stderr"][~penumbra]
        )
    assert "light_samples_per_sample" not in stats


def test_soft_channels_do_not_depend_on_chunking():
    loaded = scenes.load("soft-contact", width=40, height=24)
    settings = ReferenceSettings(spp=8, channels=("soft", "color"))
    a, stats = render_reference(loaded, settings, quiet=True)
    b, _ = render_reference(loaded, settings, quiet=True, samples_per_launch=16 * 37)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert stats["light_samples_per_sample"] == 16
    assert stats["shadow_rays"] > 8 * 40 * 24 * 4  # the light samples are counted


def test_adaptive_sampling_refines_the_penumbrae():
    loaded = scenes.load("soft-contact", width=64, height=36)
    settings = ReferenceSettings(
        spp=8, adaptive=True, adaptive_spp=8, max_spp=512, target_stderr=0.02, channels=("soft",)
    )
    ch, stats = render_reference(loaded, settings, quiet=True)
    ad = stats["adaptive"]
    soft = ch["soft_visibility"]
    penumbra = (soft > 0.05) & (soft < 0.95)
    assert ad["pixels_refined"] >= penumbra.sum() > 100
    # a few times the first pass on average, a small fraction of uniform sampling's rays
    assert ad["mean_spp"] < 8 * settings.adaptive_spp
    assert ad["rays_ratio_vs_uniform"] < 0.2
    # the target is met near features, up to the pixels that used every sample (edges of
    # the casters, where samples on the caster and on the ground differ by up to 1)
    assert ad["achieved_max_stderr_near_features"] < 1.5 * settings.target_stderr
    se = ch["soft_visibility_stderr"][penumbra]
    assert np.median(se) <= settings.target_stderr


def test_the_area_light_reference_traces_one_scene_per_kernel():
    from raster_oracle.scenes import backend
    from raster_oracle.scenes.backend import kernels

    if not backend.active().variant.startswith("llvm"):
        pytest.skip("the audit reads the LLVM backend's IR")
    loaded = scenes.load("soft-contact", width=32, height=18)
    with kernels.audit() as seen:
        render_reference(loaded, ReferenceSettings(spp=2, channels=("soft", "color")), quiet=True)
    assert seen.scenes and seen.worst == 1


def test_converge_measures_the_soft_channels_under_an_area_light():
    from raster_oracle.oracle.studies.converge import run_converge
    from raster_oracle.reports.sections import converge_section

    data = run_converge("soft-contact", width=40, height=24, max_spp=16, truth_spp=64)
    assert data["channels"] == ["visibility", "coverage", "soft_visibility", "light_fraction"]
    rms = [r["soft_visibility"]["rms"] for r in data["ladder"]]
    assert rms[-1] < 0.5 * rms[0]
    for r in data["ladder"]:
        # the reported standard error bounds the true error
        assert r["light_fraction"]["rms"] <= r["light_fraction"]["stderr_rms"]
    assert data["fit"]["soft_visibility"]["true_rms"]["slope"] < -0.4
    assert "soft_visibility" in converge_section(data)["rows"][0]
    plate = run_converge("plate", width=16, height=9, max_spp=4, truth_spp=16, adaptive=False)
    assert "soft_visibility" not in plate["ladder"][0]
