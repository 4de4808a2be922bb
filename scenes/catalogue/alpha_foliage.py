"""``alpha-foliage``: alpha-tested leaf cards (glTF ``alphaMode: MASK``) at distances from 2 to
200 m, the workload where foliage dissolves with distance and shadows of cut-out cards go
wrong.

The name: ``foliage`` is taken by the anti-aliasing scene of thin grass blades
(:mod:`.aa_scenes`), and ``pbr-foliage`` and ``city-foliage`` by scenes whose leaves are
geometry; this family is the one whose leaves are an alpha test, hence ``alpha-foliage``.

The scene (GLB bytes, read by the glTF loader like ``pbr-foliage``):

- ``n`` square cards (two triangles each, one mesh), in :data:`BANDS` five distance bands
  2-5, 5-12.6, 12.6-31.7, 31.7-79.6 and 79.6-200 m (edges ``2 x 100^(k/5)``), an equal share
  in each; band ``k`` fills the ``k``-th of five columns of the view (near on the left), so
  every band is seen whole, and depth within a band is log-uniform. A card's half size is
  :data:`LAYERS`-dependent times its distance (the cards of a band overlap
  :data:`LAYERS` deep on average at any ``n``: more cards are smaller cards), it faces the
  camera within 50 degrees of yaw and 25 of tilt;
- one material, ``MASK`` with ``alphaCutoff`` 0.5 (``alpha=0``: ``OPAQUE``, the same scene
  without the alpha test, the cost baseline), double-sided, whose base colour texture
  (:func:`leaf_texture`, 256 x 256 RGBA, tileable) holds a wavy stem two texels wide,
  leaves with serrated margins, and one-texel petioles: thin features that box-filtered mips
  average away. The texture repeats every :data:`TILE` metres on every card whatever its
  size, so the texels a pixel covers grow with distance alone (about 1.5 texels a pixel at
  2 m, 150 at 200 m at the default 320 x 180 film), as on real foliage; the sampler repeats,
  magnifies ``LINEAR`` and minifies ``LINEAR_MIPMAP_LINEAR`` (what an engine does; the truth
  samples the base level);
- a sun from behind the camera's left shoulder, travelling forward and down, so cards shadow
  the cards behind them in their band; no ground (coverage is measured against the sky);
- the camera 2 m up looking horizontally along +Z, 36 degrees of vertical field of view; the
  camera pan is any path of :mod:`scenes.paths` (``subpixel-pan`` for flicker: the columns
  have a 5 % margin at the sides).
"""

from __future__ import annotations

import math

import numpy as np

from ..formats.gltf_write import GltfLight, GltfMesh, glb_bytes, light_matrix, png_bytes
from .pbr_scenes import _camera, _srgb_encode

__all__ = [
    "ALPHA_FOLIAGE_N",
    "BANDS",
    "CUTOFF",
    "LAYERS",
    "TILE",
    "alpha_foliage",
    "band_edges",
    "camera_pose",
    "leaf_cards",
    "leaf_texture",
    "texture_alpha",
]

#: Default card count (small: tests and the catalogue's default resolution;
#: ``alpha-foliage:n=100000`` for content of real size).
ALPHA_FOLIAGE_N = 1000
#: Distance bands.
BANDS = 5
#: Nearest and farthest card distance (metres along the view axis).
NEAR, FAR = 2.0, 200.0
#: Mean depth complexity of the cards in each band's column.
LAYERS = 2.5
#: World size of one repeat of the leaf texture on a card (metres).
TILE = 0.12
#: The material's ``alphaCutoff`` (glTF's default, written out).
CUTOFF = 0.5
#: Vertical field of view (degrees) and the eye's height (metres).
FOV_Y = 36.0
EYE = np.array([0.0, 2.0, 0.0])
#: Side margin of the columns for a camera pan (fraction of the horizontal half-angle).
PAN_MARGIN = 0.05
#: The sun's direction of travel (from behind the camera's left shoulder, forward and down).
SUN = (0.35, -0.6, 0.72)


def band_edges() -> np.ndarray:
    """The ``BANDS + 1`` distance band edges, ``NEAR (FAR / NEAR)^(k / BANDS)`` metres."""
    return NEAR * (FAR / NEAR) ** (np.arange(BANDS + 1) / BANDS)


def _segment_distance(px, py, ax, ay, bx, by):
    """Distance of points ``(px, py)`` to the segment ``a-b`` (texel units)."""
    vx, vy = bx - ax, by - ay
    t = np.clip(((px - ax) * vx + (py - ay) * vy) / (vx * vx + vy * vy), 0.0, 1.0)
    return np.hypot(px - ax - t * vx, py - ay - t * vy)


def leaf_texture(size: int = 256, *, leaves: int = 10, seed: int = 7) -> np.ndarray:
    """The leaf texture, (size, size, 4) float64: linear RGB and alpha in [0, 1], tileable.

    Two wavy stems (at a quarter and three quarters of the width; alpha ``1.5 - distance``
    texels: two texels wide), each with ``leaves`` leaves on alternating sides (lanceolate,
    0.2-0.3 of the tile long, serrated margins with teeth of a 6-texel period) on one-texel
    petioles (alpha ``1 - distance``); every edge a one-texel ramp (``0.5 - signed
    distance``). Distances are taken on the torus, so the texture repeats without seams.
    Colour: darker green along each leaf's midrib.
    """
    rng = np.random.default_rng([int(seed), 44])
    y, x = (np.mgrid[0:size, 0:size] + 0.5).astype(np.float64)
    half = size / 2.0

    def wrap(d):
        return (d + half) % size - half

    def stem(yy, k):
        return (0.25 + 0.5 * k) * size + 0.025 * size * np.sin(2 * np.pi * (yy / size + 0.3 * k))

    alpha = np.maximum(*(np.clip(1.5 - np.abs(wrap(x - stem(y, k))), 0.0, 1.0) for k in (0, 1)))
    vein = np.zeros_like(alpha)
    for j in range(2 * leaves):  # twenty leaves, each over the whole texel grid at once
        k, i = j % 2, j // 2
        by = (i + rng.uniform(0.2, 0.8) + 0.5 * k) * size / leaves
        sx = stem(by, k)
        side = 1.0 if (i + k) % 2 else -1.0
        theta = math.radians(rng.uniform(30.0, 60.0))
        ux, uy = side * math.sin(theta), -math.cos(theta)  # away from the stem, upwards
        petiole = rng.uniform(0.025, 0.045) * size
        length, width = rng.uniform(0.2, 0.3) * size, rng.uniform(0.36, 0.5)
        dx, dy = wrap(x - (sx + petiole * ux)), wrap(y - (by + petiole * uy))
        s = dx * ux + dy * uy
        t = -dx * uy + dy * ux
        inside = (s >= 0.0) & (s <= length)
        hw = 0.5 * width * length * np.sin(np.pi * np.clip(s / length, 0.0, 1.0)) ** 0.7
        hw *= 1.0 + 0.08 * np.sin(2 * np.pi * s / 6.0)
        leaf = np.where(inside, np.clip(0.5 - (np.abs(t) - hw), 0.0, 1.0), 0.0)
        pet = np.clip(1.0 - _segment_distance(dx, dy, -petiole * ux, -petiole * uy, 0, 0), 0, 1)
        alpha = np.maximum(alpha, np.maximum(leaf, pet))
        vein = np.maximum(vein, np.where(inside, np.exp(-((t / 1.2) ** 2)), 0.0) * leaf)
    rgb = np.stack([0.06 + 0.1 * vein, 0.22 + 0.2 * vein, 0.04 + 0.04 * vein], -1)
    return np.concatenate([rgb, alpha[..., None]], -1)


def _png_rgba(rgba: np.ndarray) -> bytes:
    """An 8-bit RGBA PNG: RGB sRGB-encoded (a colour texture), alpha stored linear."""
    return png_bytes(np.concatenate([_srgb_encode(rgba[..., :3]), rgba[..., 3:]], -1))


def leaf_cards(rng: np.random.Generator, n: int, *, aspect: float):
    """The ``n`` cards as a mesh: ``(vertices (4n, 3), faces (2n, 3), normals (4n, 3),
    texcoords (4n, 2), band (n,))`` (see the module text)."""
    edges = band_edges()
    band = np.arange(n) % BANDS
    lo, hi = np.log(edges[band]), np.log(edges[band + 1])
    z = np.exp(rng.uniform(lo, hi))
    tan_v = math.tan(math.radians(FOV_Y) / 2)
    h_ang = math.atan(tan_v * aspect) * (1 + PAN_MARGIN)
    v_ang = math.radians(FOV_Y) / 2
    col = 2 * h_ang / BANDS
    az = -h_ang + (band + rng.uniform(0.0, 1.0, n)) * col
    el = rng.uniform(-v_ang, v_ang, n)
    # camera looks along +Z with +Y up: its right is -X
    centre = EYE + np.stack([-np.tan(az) * z, np.tan(el) * z, z], 1)
    per_band = max(1.0, n / BANDS)
    kappa = math.sqrt(LAYERS * col * 2 * v_ang / (4.0 * per_band))
    half = kappa * z
    yaw = np.radians(rng.uniform(-50.0, 50.0, n)) + az
    tilt = np.radians(rng.uniform(-25.0, 25.0, n))
    e_u = np.stack([-np.cos(yaw), np.zeros(n), -np.sin(yaw)], 1)  # card right (the view's -X)
    facing = np.stack([-np.sin(yaw), np.zeros(n), np.cos(yaw)], 1)  # away from the camera
    e_up = np.cos(tilt)[:, None] * np.array([0.0, 1.0, 0.0]) + np.sin(tilt)[:, None] * facing
    normal = np.cross(e_u, e_up)  # towards the camera, as the winding
    hu, hv = (half[:, None] * e_u), (half[:, None] * e_up)
    corners = np.stack([centre - hu + hv, centre + hu + hv, centre + hu - hv, centre - hu - hv], 1)
    span = 2.0 * half / TILE
    u0, v0 = rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    uv = np.stack(
        [
            np.stack([u0, v0], 1),
            np.stack([u0 + span, v0], 1),
            np.stack([u0 + span, v0 + span], 1),
            np.stack([u0, v0 + span], 1),
        ],
        1,
    )
    base = 4 * np.arange(n, dtype=np.uint32)[:, None]
    faces = np.concatenate([base + [0, 2, 1], base + [0, 3, 2]], 1).reshape(-1, 3)
    normals = np.repeat(normal, 4, axis=0)
    return corners.reshape(-1, 3), faces, normals, uv.reshape(-1, 2), band


def texture_alpha(rgba: np.ndarray) -> np.ndarray:
    """The alpha an 8-bit PNG of ``rgba`` stores (what a reader of the GLB gets), float32."""
    return (np.clip(np.rint(rgba[..., 3] * 255.0), 0, 255) / 255.0).astype(np.float32)


def camera_pose() -> tuple[np.ndarray, np.ndarray]:
    """The camera's eye and target (it looks along +Z)."""
    return EYE.copy(), EYE + np.array([0.0, 0.0, 1.0])


def alpha_foliage(
    width: int, height: int, *, n: int = ALPHA_FOLIAGE_N, seed: int = 1, alpha: int = 1
) -> bytes:
    """The ``alpha-foliage`` scene (see the module text) as GLB bytes; ``alpha=0`` writes the
    material ``OPAQUE`` (the same cards without the alpha test)."""
    rng = np.random.default_rng([int(seed), 44])
    aspect = width / height
    verts, faces, normals, uv, _ = leaf_cards(rng, int(n), aspect=aspect)
    material = {
        "name": "leaf-card",
        "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0},
            "metallicFactor": 0.0,
            "roughnessFactor": 0.6,
        },
        "doubleSided": True,
    }
    if alpha:
        material.update({"alphaMode": "MASK", "alphaCutoff": CUTOFF})
    sun = GltfLight("sun", "directional", light_matrix(SUN), intensity=4.0)
    cards = GltfMesh("cards", verts, faces, 0, normals, uv)
    eye, target = camera_pose()
    return glb_bytes(
        camera=_camera(
            tuple(eye), tuple(target), fov_y_deg=FOV_Y, near=0.05, far=FAR * 1.5, aspect=aspect
        ),
        lights=[sun],
        meshes=[cards] if len(faces) else [],
        materials=[material],
        images=[_png_rgba(leaf_texture())],
        textures=[{"source": 0, "sampler": 0}],
        samplers=[{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
    )
