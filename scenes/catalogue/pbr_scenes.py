"""Built-in glTF scenes, written by the project's own code (:mod:`scenes.formats.gltf_write`)
and read back through the glTF loader (:mod:`scenes.formats.gltf`), so the default sweep and
the main job
exercise the glTF path and the glTF BRDF (:mod:`scenes.shading.pbr`):

- ``pbr-spheres``: a 3 x 4 grid of tessellated spheres (metallic 0, 0.5 and 1 by row,
  roughness 0.1 to 1 by column, one emissive) on a textured ground (sRGB checker base colour,
  a roughness/metallic texture and a bumpy normal texture), under a sun (light 0) and a spot
  light (light 1; KHR cone attenuation and a ``range``);
- ``pbr-foliage``: about 400 leaf cards (alpha-free: each leaf is its own triangle fan, so the
  silhouette is geometry, not an alpha test) on stems over a ground, textured leaves with
  normals bent by a normal texture, under a low sun: many thin surfaces per pixel and fine
  shadows.

Each factory takes the film size and returns GLB bytes (``BuiltinScene.kind == "gltf"``).
"""

from __future__ import annotations

import math

import numpy as np

from ..formats.gltf_write import (
    GltfCamera,
    GltfLight,
    GltfMesh,
    glb_bytes,
    light_matrix,
    png_bytes,
)

__all__ = ["PBR_SCENES", "pbr_foliage", "pbr_spheres", "uv_sphere"]


def uv_sphere(center, radius: float, *, n_theta: int = 24, n_phi: int = 48):
    """A UV sphere: vertices (V, 3), faces (F, 3), unit normals (V, 3), texcoords (V, 2)."""
    theta = np.linspace(0.0, math.pi, n_theta + 1)
    phi = np.linspace(0.0, 2.0 * math.pi, n_phi + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    nrm = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    verts = np.asarray(center, dtype=np.float64) + radius * nrm
    uv = np.stack([p / (2 * math.pi), t / math.pi], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_phi), indexing="ij")
    a = i * (n_phi + 1) + j
    b, c = a + 1, a + n_phi + 1
    d = c + 1
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).reshape(-1, 3)
    return verts, faces.astype(np.uint32), nrm, uv


def _camera(eye, target, *, fov_y_deg: float, near: float, far: float, aspect: float):
    fwd = np.asarray(target, float) - np.asarray(eye, float)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -fwd, eye
    return GltfCamera(m, near, far, yfov=math.radians(fov_y_deg), aspect=aspect)


def _ground(size: float, repeats: float):
    h = size / 2.0
    v = np.array([[-h, 0, -h], [-h, 0, h], [h, 0, h], [h, 0, -h]], dtype=np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    nrm = np.tile([0.0, 1.0, 0.0], (4, 1))
    uv = np.array([[0, 0], [0, 1], [1, 1], [1, 0]], dtype=np.float64) * repeats
    tan = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    return v, f, nrm, uv, tan


def _srgb_encode(lin: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] encoded with the sRGB OETF (colour textures store sRGB)."""
    return np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)


def _ground_textures(n: int = 64):
    """Checker base colour (sRGB), metallic-roughness (G rough, B metal) and a bump normal."""
    y, x = np.mgrid[0:n, 0:n] + 0.5
    check = ((x // (n / 4) + y // (n / 4)) % 2)[..., None]
    base_lin = np.where(check > 0, [0.55, 0.5, 0.42], [0.25, 0.27, 0.3])
    base = _srgb_encode(base_lin)
    mr = np.zeros((n, n, 3))
    mr[..., 1] = np.where(check[..., 0] > 0, 0.35, 0.85)
    mr[..., 2] = np.where(check[..., 0] > 0, 0.0, 0.2)
    # bumps: a height field's slope along u, four periods a tile
    gx = 0.35 * np.cos(8 * math.pi * x / n) * np.sin(8 * math.pi * y / n)
    nz = 1.0 / np.sqrt(1 + gx * gx)
    normal = np.stack([gx * nz, 0.0 * gx, nz], -1) * 0.5 + 0.5
    return [png_bytes(base), png_bytes(mr), png_bytes(normal)]


def pbr_spheres(width: int, height: int) -> bytes:
    """The sphere grid (see the module text), GLB bytes."""
    meshes, materials = [], []
    for row, metallic in enumerate((0.0, 0.5, 1.0)):
        for col, rough in enumerate((0.1, 0.4, 0.7, 1.0)):
            v, f, nrm, uv = uv_sphere((-2.7 + 1.8 * col, 0.7, -1.8 * row), 0.7)
            base = (0.9, 0.45, 0.2) if metallic < 1 else (0.95, 0.8, 0.45)
            mat = {
                "name": f"m{metallic:g}_r{rough:g}",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [*base, 1.0],
                    "metallicFactor": metallic,
                    "roughnessFactor": rough,
                },
            }
            if row == 1 and col == 3:
                mat["emissiveFactor"] = [0.6, 0.3, 0.05]
            meshes.append(GltfMesh(f"sphere_{row}_{col}", v, f, len(materials), nrm, uv))
            materials.append(mat)
    v, f, nrm, uv, tan = _ground(40.0, 20.0)
    meshes.append(GltfMesh("ground", v, f, len(materials), nrm, uv, tan))
    materials.append(
        {
            "name": "ground",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicRoughnessTexture": {"index": 1},
            },
            "normalTexture": {"index": 2, "scale": 1.0},
        }
    )
    sun = GltfLight("sun", "directional", light_matrix((0.45, -1.0, -0.35)), intensity=3.0)
    spot = GltfLight(
        "spot",
        "spot",
        light_matrix((0.3, -1.0, -0.4), (-2.0, 5.0, 1.0)),
        color=(1.0, 0.85, 0.7),
        intensity=60.0,
        range=14.0,
        inner=math.radians(18.0),
        outer=math.radians(32.0),
    )
    return glb_bytes(
        camera=_camera(
            (0.0, 4.2, 7.5),
            (0.0, 0.3, -1.5),
            fov_y_deg=36.0,
            near=0.1,
            far=80.0,
            aspect=width / height,
        ),
        lights=[sun, spot],
        meshes=meshes,
        materials=materials,
        images=_ground_textures(),
        textures=[{"source": i, "sampler": 0} for i in range(3)],
        samplers=[{"magFilter": 9729, "wrapS": 10497, "wrapT": 10497}],
    )


def _leaf(rng, base_pos, size: float):
    """One leaf: a fan of 8 triangles around a mid-rib, randomly oriented, with uv."""
    s = np.linspace(0.0, 1.0, 5)
    w = 0.38 * np.sin(math.pi * s) ** 0.8
    outline = np.concatenate(
        [np.stack([s, w], -1), np.stack([s[::-1], -w[::-1]], -1)[1:-1]]
    )  # (8, 2) leaf-local (along, across)
    yaw, pitch, roll = rng.uniform(0, 2 * math.pi), rng.uniform(-0.9, 0.6), rng.uniform(-0.8, 0.8)
    cy, sy, cp, sp, cr, sr = (f(a) for a in (yaw, pitch, roll) for f in (math.cos, math.sin))
    along = np.array([cy * cp, sp, sy * cp])
    side0 = np.array([-sy, 0.0, cy])
    up0 = np.cross(side0, along)
    side = cr * side0 + sr * up0
    local = outline * size
    verts = base_pos + local[:, :1] * along + local[:, 1:] * side
    centre = base_pos + 0.5 * size * along
    verts = np.concatenate([centre[None], verts])
    k = np.arange(len(outline))
    faces = np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % len(outline)], -1)
    uv = np.concatenate([[[0.5, 0.5]], np.stack([outline[:, 0], 0.5 + outline[:, 1] / 0.76], -1)])
    normal = np.cross(along, side)
    return verts, faces, np.tile(normal, (len(verts), 1)), uv


def _leaf_textures(n: int = 32):
    y, x = np.mgrid[0:n, 0:n] + 0.5
    vein = np.exp(-(((y - n / 2) / 1.5) ** 2))
    lin = np.stack([0.08 + 0.25 * vein, 0.28 + 0.3 * vein, 0.05 + 0.05 * vein], -1)
    srgb = _srgb_encode(lin)
    gy = 0.4 * np.sin(2 * math.pi * 3 * x / n) * (1 - vein)
    nz = 1 / np.sqrt(1 + gy * gy)
    normal = np.stack([0 * gy, gy * nz, nz], -1) * 0.5 + 0.5
    return [png_bytes(srgb), png_bytes(normal)]


def pbr_foliage(width: int, height: int) -> bytes:
    """The leaf cards (see the module text), GLB bytes."""
    rng = np.random.default_rng(29)
    leaves, stems = [], []
    for _ in range(24):
        root = np.array([rng.uniform(-3.5, 3.5), 0.0, rng.uniform(-3.0, 1.5)])
        height_ = rng.uniform(0.8, 2.2)
        stems.append((root, height_))
        for _ in range(rng.integers(12, 22)):
            t = rng.uniform(0.25, 1.0)
            leaves.append(_leaf(rng, root + [0.0, t * height_, 0.0], rng.uniform(0.25, 0.5)))
    parts, offset = [[], [], [], []], 0
    for v, f, n, uv in leaves:
        parts[0].append(v)
        parts[1].append(f + offset)
        parts[2].append(n)
        parts[3].append(uv)
        offset += len(v)
    leaf_mesh = GltfMesh("leaves", *(np.concatenate(p) for p in parts[:2]), material=0)
    leaf_mesh.normals, leaf_mesh.texcoords = np.concatenate(parts[2]), np.concatenate(parts[3])
    tube_v, tube_f = [], []
    for root, h in stems:
        ang = np.linspace(0, 2 * math.pi, 6, endpoint=False)
        ring = np.stack([0.02 * np.cos(ang), 0 * ang, 0.02 * np.sin(ang)], -1)
        v = np.concatenate([root + ring, root + ring + [0.0, h, 0.0]])
        k = np.arange(6)
        f = np.concatenate(
            [
                np.stack([k, 6 + k, (k + 1) % 6], -1),
                np.stack([(k + 1) % 6, 6 + k, 6 + (k + 1) % 6], -1),
            ]
        )
        tube_f.append(f + 12 * len(tube_v))
        tube_v.append(v)
    stem_mesh = GltfMesh("stems", np.concatenate(tube_v), np.concatenate(tube_f), material=1)
    gv, gf, gn, guv, gt = _ground(30.0, 1.0)
    materials = [
        {
            "name": "leaf",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicFactor": 0.0,
                "roughnessFactor": 0.45,
            },
            "normalTexture": {"index": 1, "scale": 1.0},
            "doubleSided": True,
        },
        {
            "name": "stem",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.2, 0.15, 0.08, 1],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.8,
            },
        },
        {
            "name": "soil",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.18, 0.14, 0.1, 1],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.95,
            },
        },
    ]
    sun = GltfLight("sun", "directional", light_matrix((-0.6, -0.55, -0.45)), intensity=4.0)
    return glb_bytes(
        camera=_camera(
            (0.0, 2.0, 6.5),
            (0.0, 0.9, -0.5),
            fov_y_deg=40.0,
            near=0.05,
            far=60.0,
            aspect=width / height,
        ),
        lights=[sun],
        meshes=[leaf_mesh, stem_mesh, GltfMesh("ground", gv, gf, 2, gn, guv, gt)],
        materials=materials,
        images=_leaf_textures(),
        textures=[{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
        samplers=[{"magFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
    )


#: name -> (factory, description, default width, default height)
PBR_SCENES = {
    "pbr-spheres": (
        pbr_spheres,
        "glTF: a 3x4 grid of metallic/rough spheres on a textured ground, sun and spot light "
        "(the glTF BRDF)",
        160,
        90,
    ),
    "pbr-foliage": (
        pbr_foliage,
        "glTF: ~400 alpha-free leaf cards with textured, normal-mapped leaves under a low sun",
        160,
        90,
    ),
}
