"""glTF files the glTF tests write: a twin of the built-in ``plate`` and flat test planes.

The hand evaluation of the glTF 2.0 Appendix B BRDF the closed-form tests use is the test
engine's (``engine_raster.gltf_brdf``, written from the specification, none of the oracle's
code), re-exported here as ``spec_brdf``.
"""

from __future__ import annotations

import math

import numpy as np
from engine_raster import gltf_brdf as spec_brdf  # noqa: F401 (the tests' BRDF, re-exported)
from raster_oracle.scenes.formats.gltf_write import (
    GltfCamera,
    GltfLight,
    GltfMesh,
    glb_bytes,
    light_matrix,
)
from raster_oracle.scenes.geometry import meshes

#: glTF camera axes to Mitsuba's (its own inverse).
GL_TO_MI = np.diag([-1.0, 1.0, -1.0, 1.0])


def pbr_material(base, metallic, roughness) -> dict:
    return {
        "pbrMetallicRoughness": {
            "baseColorFactor": [*(float(c) for c in base), 1.0],
            "metallicFactor": float(metallic),
            "roughnessFactor": float(roughness),
        },
        "doubleSided": True,
    }


def plate_twin(loaded_plate, materials: list[dict] | None = None) -> bytes:
    """The built-in ``plate`` as a GLB: the same float32 vertices, the camera of the loaded
    scene (glTF axes), the same sun direction (unnormalized, as the built-in gives it);
    ``materials``: the ground's and the plate's (default: rough dielectrics of the built-in's
    albedos)."""
    from raster_oracle.scenes.catalogue import shadow_scenes

    cam = loaded_plate.camera
    raw = shadow_scenes.plate(cam.width, cam.height)
    yfov = 2.0 * math.atan(math.tan(math.radians(cam.fov_x) / 2.0) / cam.aspect)
    sun = GltfLight("sun", "directional", light_matrix(raw["sun"]["direction"]), intensity=3.0)
    parts = [("ground", (0.6, 0.6, 0.6)), ("plate", (0.7, 0.3, 0.2))]
    return glb_bytes(
        camera=GltfCamera(cam.to_world @ GL_TO_MI, cam.near, cam.far, yfov=yfov),
        lights=[sun],
        meshes=[
            GltfMesh(k, raw[k]["vertices"], raw[k]["faces"], material=i)
            for i, (k, _) in enumerate(parts)
        ],
        materials=materials or [pbr_material(c, 0.0, 1.0) for _, c in parts],
    )


def flat_plane(
    *,
    lights: list[GltfLight],
    material: dict,
    ortho: float | None = None,
    images: list[bytes] = (),
    tangents=None,
    below: bool = False,
) -> bytes:
    """A 40 x 40 plane at y = 0 (normal +Y), seen from above at an angle (perspective) or
    straight down (orthographic, ``ortho`` = half height), under ``lights``. Texture ``k``
    is image ``k`` (``images``: PNG bytes); ``TEXCOORD_0`` runs along +X (u) and +Z (v);
    ``tangents``: a ``TANGENT`` (4,) for every vertex (None: none); ``below``: the
    perspective camera looks at the plane's back (from y < 0)."""
    quad = meshes.quad([[-20, 0, -20], [-20, 0, 20], [20, 0, 20], [20, 0, -20]])
    normals = np.tile([0.0, 1.0, 0.0], (4, 1))
    uv = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    tan = None if tangents is None else np.tile(np.asarray(tangents, float), (4, 1))
    if ortho is None:
        eye, target = np.array([0.0, -4.0 if below else 4.0, 6.0]), np.zeros(3)
        cam = GltfCamera(_gl_look(eye, target), 0.1, 100.0, yfov=math.radians(40.0))
    else:
        m = np.eye(4)
        m[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # looks down -Y, +Y_cam = -Z world
        m[:3, 3] = [0.0, 10.0, 0.0]
        cam = GltfCamera(m, 0.1, 20.0, ymag=ortho)
    return glb_bytes(
        camera=cam,
        lights=lights,
        meshes=[GltfMesh("plane", quad[0], quad[1], 0, normals, uv, tan)],
        materials=[material],
        images=list(images),
        textures=[{"source": k} for k in range(len(images))],
    )


def _gl_look(eye, target) -> np.ndarray:
    """glTF camera matrix at ``eye`` looking at ``target`` (-Z forward, +Y up)."""
    fwd = target - eye
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -fwd, eye
    return m
