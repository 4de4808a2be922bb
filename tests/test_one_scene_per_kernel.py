"""One Mitsuba scene per Dr.Jit kernel (issue 24, family "ACAA traces silently disabled").

On CUDA, OptiX disables a trace of a second scene in one kernel and returns no hits: ACAA
traced its tie-group scenes and then the whole scene's shadow rays in one kernel, and
stripes came out fully lit. The LLVM backend traces both, so the audit reads the kernels'
IR instead (:mod:`raster_oracle.scenes.backend.kernels`): every kernel of every model and of the
oracle traces at most one scene.
"""

from __future__ import annotations

import pytest
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.raster_models.errors import ModelError
from raster_oracle.raster_models.rtshadows.model import clear_shared_frames
from raster_oracle.scenes import backend
from raster_oracle.scenes.backend import kernels

from raster_oracle import raster_models as rm
from raster_oracle import scenes


@pytest.fixture(autouse=True)
def _llvm_only(_backend):
    if not backend.active().variant.startswith("llvm"):
        pytest.skip("the audit reads the LLVM backend's IR")


#: Scenes that exercise every light kind, ACAA's tie groups (decal), the AA models'
#: sub-scenes (stripes) and analytic shapes (curved).
SCENES = ("stripes", "decal", "spot", "point", "curved")


def test_the_audit_sees_two_scenes_traced_in_one_kernel(mi):
    import drjit as dr

    a = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    b = mi.load_dict({"type": "scene", "s": {"type": "rectangle"}})
    o = mi.Point3f(dr.linspace(mi.Float, -1, 1, 64), 0.0, -5.0)
    with kernels.audit() as mixed:
        hit = a.ray_test(mi.Ray3f(o, mi.Vector3f(0, 0, 1)))
        shifted = mi.Ray3f(o + mi.Vector3f(0, 0, dr.select(hit, 1.0, 0.0)), mi.Vector3f(0, 0, 1))
        dr.eval(b.ray_test(shifted))
    assert mixed.checked and mixed.worst == 2
    with kernels.audit() as apart:
        hit = a.ray_test(mi.Ray3f(o, mi.Vector3f(0, 0, 1)))
        kernels.evaluate_trace(hit)
        shifted = mi.Ray3f(o + mi.Vector3f(0, 0, dr.select(hit, 1.0, 0.0)), mi.Vector3f(0, 0, 1))
        dr.eval(b.ray_test(shifted))
    assert apart.worst == 1 and apart.scenes == [1, 1]


@pytest.mark.parametrize("name", SCENES)
def test_every_model_traces_one_scene_per_kernel(name):
    loaded = scenes.load(name, width=48, height=27)
    ran = 0
    for technique in (t["name"] for t in rm.list_techniques()):
        clear_shared_frames()  # each rtshadows model traces its own frames here
        with kernels.audit() as seen:
            try:
                rm.run(technique, loaded)
            except ModelError as exc:  # csm/sdsm need a directional light
                assert "directional" in str(exc)
                continue
        ran += 1
        assert seen.scenes, technique  # it traced something
        assert seen.worst == 1, (technique, seen.scenes)
    assert ran >= 8  # csm, sdsm and coherent-shadow-map need a sun


def test_acaa_shades_its_tie_groups_apart_from_the_shadow_rays():
    """The decal's tie groups are separate scenes: the fragments' surfaces are found in them,
    their shadow rays in the whole scene, in different kernels."""
    loaded = scenes.load("decal", width=48, height=27)
    with kernels.audit() as seen:
        rm.run("acaa", loaded)
    assert len(loaded.memo["acaa.group_scenes"]) >= 2  # sub-scenes were traced
    assert seen.worst == 1


@pytest.mark.parametrize("technique", ["msaa", "acaa", "agaa"])
def test_aa_models_with_a_shadow_technique_trace_one_scene_per_kernel(technique):
    """With a shadow map for the visibility, the fragments' attributes come from the
    sub-scenes and the map's rays from the whole scene: still apart."""
    loaded = scenes.load("decal", width=48, height=27)
    with kernels.audit() as seen:
        rm.run(technique, loaded, shadows="shadow-map")
    assert seen.scenes and seen.worst == 1


def test_the_oracle_traces_one_scene_per_kernel():
    loaded = scenes.load("curved", width=32, height=18)
    with kernels.audit() as seen:
        render_reference(loaded, ReferenceSettings(spp=4), quiet=True)
    assert seen.scenes and seen.worst == 1
