"""glTF files the glTF tests write: a twin of the built-in ``plate`` and flat test planes.

Also an independent NumPy evaluation of the glTF 2.0 Appendix B BRDF (written from the
specification's text, none of the oracle's code), which the closed-form tests and the test
engine use.
"""

from __future__ import annotations

import math

import numpy as np
from raster_oracle.scenes import meshes
from raster_oracle.scenes.gltf_write import (
    GltfCamera,
    GltfLight,
    GltfMesh,
    glb_bytes,
    light_matrix,
)

#: glTF camera axes to Mitsuba's (its own inverse).
GL_TO_MI = np.diag([-1.0, 1.0, -1.0, 1.0])


def spec_brdf(base, metallic, roughness, n, l, v, *, alpha_of=lambda r: r * r):
    """The specification's BRDF (B.3), float64; ``alpha_of`` maps roughness to alpha (a
    wrong engine passes ``lambda r: r``). Vectors ``(N, 3)``, ``base`` ``(N, 3)`` or (3,)."""
    base = np.broadcast_to(np.asarray(base, dtype=np.float64), np.shape(n))
    h = l + v
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    nl = np.abs(np.sum(n * l, -1))
    nv = np.abs(np.sum(n * v, -1))
    nh = np.sum(n * h, -1)
    vh = np.abs(np.sum(v * h, -1))
    a = alpha_of(roughness)
    a2 = a * a
    d = np.where(nh > 0, a2 / (math.pi * (nh * nh * (a2 - 1) + 1) ** 2), 0.0)
    vis = 1.0 / ((nl + np.sqrt(a2 + (1 - a2) * nl**2)) * (nv + np.sqrt(a2 + (1 - a2) * nv**2)))
    spec = (vis * d)[:, None]
    fw = ((1.0 - vh) ** 5)[:, None]
    f_d = 0.04 + 0.96 * fw
    dielectric = (1 - f_d) * base / math.pi + f_d * spec
    metal = spec * (base + (1 - base) * fw)
    m = np.asarray(metallic, dtype=np.float64)
    m = m[:, None] if m.ndim else m
    return (1 - m) * dielectric + m * metal


def pbr_material(base, metallic, roughness) -> dict:
    return {
        "pbrMetallicRoughness": {
            "baseColorFactor": [*(float(c) for c in base), 1.0],
            "metallicFactor": float(metallic),
            "roughnessFactor": float(roughness),
        },
        "doubleSided": True,
    }


def plate_twin(loaded_plate) -> bytes:
    """The built-in ``plate`` as a GLB: the same float32 vertices, the camera of the loaded
    scene (glTF axes), the same sun direction (unnormalized, as the built-in gives it)."""
    from raster_oracle.scenes import shadow_scenes

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
        materials=[pbr_material(c, 0.0, 1.0) for _, c in parts],
    )


def flat_plane(*, lights: list[GltfLight], material: dict, ortho: float | None = None) -> bytes:
    """A 40 x 40 plane at y = 0 (normal +Y), seen from above at an angle (perspective) or
    straight down (orthographic, ``ortho`` = half height), under ``lights``."""
    quad = meshes.quad([[-20, 0, -20], [-20, 0, 20], [20, 0, 20], [20, 0, -20]])
    normals = np.tile([0.0, 1.0, 0.0], (4, 1))
    if ortho is None:
        eye, target = np.array([0.0, 4.0, 6.0]), np.array([0.0, 0.0, 0.0])
        cam = GltfCamera(_gl_look(eye, target), 0.1, 100.0, yfov=math.radians(40.0))
    else:
        m = np.eye(4)
        m[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # looks down -Y, +Y_cam = -Z world
        m[:3, 3] = [0.0, 10.0, 0.0]
        cam = GltfCamera(m, 0.1, 20.0, ymag=ortho)
    return glb_bytes(
        camera=cam,
        lights=lights,
        meshes=[GltfMesh("plane", quad[0], quad[1], material=0, normals=normals)],
        materials=[material],
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
