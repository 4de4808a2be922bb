"""Built-in anti-aliasing scenes: decal, stripes, glossy, foliage and hdr-edge.

Each is a dictionary factory like those of :mod:`scenes.catalogue.builtin`
(``factory(width, height)``)
built to stress one weakness of an anti-aliasing technique (see ``TECHNIQUES.md``, "Test
content that stresses these"):

- ``decal``: surfaces that tie in depth. A decal quad lies exactly on a wall (same plane,
  same albedo) and a panel is duplicated (two shapes with identical vertices): a depth test
  with LEQUAL passes both, so accumulative AA (ACAA) counts them twice (2x too bright) where
  MSAA and the reference see one colour.
- ``stripes``: a zigzag of vertical strips whose albedo and normal are correlated (bright red
  strips face the sun, dark blue strips face away), :data:`STRIPE_PERIOD_PX` pixels a period
  at any film width: one aggregate per pixel (AGAA, K = 1) averages albedo and normal
  separately and loses the correlation.
- ``glossy``: a grid of small glossy beads and a large glossy sphere lit so that every bead
  carries a highlight smaller than a pixel: specular aliasing inside surfaces (Toksvig).
  The scene switches on the shared normalized Blinn-Phong lobe of :mod:`scenes.shading.phong`
  (``ks`` = :data:`GLOSSY_KS`, exponent :data:`GLOSSY_SHININESS`) for every surface, which the
  oracle's ``color`` channel and the models' shading both use (``LoadedScene.specular``).
- ``foliage``: four layers of thin grass blades (0.2-0.6 px wide) at several depths before a
  backdrop, one shape per layer: many pixels hold three or more surfaces, more than AGAA's
  K = 2 aggregates.
- ``hdr-edge``: bright strips (albedo 0.9) 0.5-6 px wide and slightly off-axis in front of a
  near-black backdrop (albedo :data:`HDR_BACKDROP_ALBEDO`), so the radiance ratio across
  their edges is :data:`HDR_CONTRAST` (180:1): box, wide and inverse-luminance-weighted
  resolves differ most here.

A factory may add the top-level key ``"ro_specular"`` (the keyword arguments of
:class:`scenes.shading.phong.Specular`); :func:`scenes.loader.load` takes it out of the dictionary
(after hashing it into the scene's content hash) and sets ``LoadedScene.specular``.
"""

from __future__ import annotations

import math

import numpy as np

from ..camera import look_at
from ..geometry import meshes
from ..shading.materials import diffuse
from .factories import mesh, sensor, sun

__all__ = [
    "AA_SCENES",
    "DECAL_ALBEDO",
    "GLOSSY_KS",
    "GLOSSY_SHININESS",
    "HDR_BACKDROP_ALBEDO",
    "HDR_CONTRAST",
    "HDR_STRIP_ALBEDO",
    "STRIPE_PERIOD_PX",
    "decal",
    "foliage",
    "glossy",
    "hdr_edge",
    "ortho_camera",
    "stripes",
]

#: Albedo of the decal scene's wall, decal and duplicated panel's wall side (one colour).
DECAL_ALBEDO = 0.5
#: Stripe period (one red + one blue strip) in pixels at the scene's film width.
STRIPE_PERIOD_PX = 1.0
#: Blinn-Phong weight and exponent of the glossy scene (a polished plastic-like lobe).
GLOSSY_KS = 0.5
GLOSSY_SHININESS = 256.0
#: hdr-edge albedos: bright strips and near-black backdrop, both facing the same sun.
HDR_STRIP_ALBEDO = 0.9
HDR_BACKDROP_ALBEDO = 0.005
HDR_CONTRAST = HDR_STRIP_ALBEDO / HDR_BACKDROP_ALBEDO

# The wall-facing camera of decal, stripes and hdr-edge: at (0, 0, -10) looking down +Z with a
# 40 degree horizontal field of view; the plane z = 0 is 10 units away, so one pixel there spans
# 2 * 10 * tan(20 deg) / width units.
_WALL_DISTANCE = 10.0
_WALL_FOV = 40.0


def _wall_pixel(width: int) -> float:
    """World size of one pixel on the plane z = 0 seen by the wall-facing camera."""
    return 2.0 * _WALL_DISTANCE * math.tan(math.radians(_WALL_FOV / 2)) / width


def _wall_camera(width: int, height: int) -> dict:

    return sensor(
        width,
        height,
        origin=(0, 0, -_WALL_DISTANCE),
        target=(0, 0, 0),
        fov=_WALL_FOV,
        near=0.1,
        far=100,
    )


def _rect_z(x0, x1, y0, y1, z=0.0):
    """An axis-aligned rectangle in the plane ``z`` (two triangles)."""
    return meshes.quad([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])


def decal(width: int, height: int) -> dict:
    """A wall with a coplanar decal and a duplicated panel: depth ties (ACAA counts twice)."""

    a = np.radians(20.0)
    c, s = np.cos(a), np.sin(a)
    corners = np.array([[-1.2, -0.7], [1.2, -0.7], [1.2, 0.7], [-1.2, 0.7]]) @ np.array(
        [[c, s], [-s, c]]
    )
    decal_quad = np.column_stack([corners[:, 0] - 0.9, corners[:, 1] + 0.3, np.zeros(4)])
    panel = _rect_z(1.3, 2.9, -1.6, 0.2, z=-1.0)
    return {
        "type": "scene",
        "camera": _wall_camera(width, height),
        # from behind the camera, slightly from above and from the image's left (world +X)
        "sun": sun((-0.25, -0.3, 1.0)),
        "wall": mesh(_rect_z(-8, 8, -5, 5), DECAL_ALBEDO),
        "decal": mesh(meshes.quad(decal_quad), DECAL_ALBEDO),
        "panel": mesh(panel, (0.8, 0.5, 0.2)),
        "panel_copy": mesh((panel[0].copy(), panel[1].copy()), (0.8, 0.5, 0.2)),
    }


#: Half width (world units) of the stripes scene's orthographic view.
_STRIPES_HALF_WIDTH = 3.6


def ortho_camera(width: int, height: int, half_width: float) -> dict:
    """Orthographic view down +Z of ``2 half_width`` units across (Mitsuba's scaled frame)."""
    cam = sensor(width, height, origin=(0, 0, -10), target=(0, 0, 0), fov=1, near=0.1, far=100)
    del cam["fov"], cam["fov_axis"]
    cam["type"] = "orthographic"
    cam["to_world"] = look_at((0, 0, -10), (0, 0, 0)) @ np.diag([half_width, half_width, 1, 1])
    return cam


def stripes(width: int, height: int) -> dict:
    """Zigzag strips, red facing the sun and blue facing away, one period a pixel.

    The view is orthographic, so every strip projects to exactly half a period wherever it is
    on the screen (a perspective view would see the zigzag obliquely towards the sides).
    """

    period = STRIPE_PERIOD_PX * 2 * _STRIPES_HALF_WIDTH / width
    half = period / 2
    # strips tilted +-45 deg about Y: each spans half a period in x and half a period in depth
    n = int(np.ceil(2 * (_STRIPES_HALF_WIDTH + 0.5) / period))
    # phase 0.2371 of a period: no pixel centre or standard sample position (multiples of
    # 1/16 px) falls on a strip's edge, where a ray could slip through the crack
    x0 = (np.arange(n) - n / 2 + 0.2371) * period
    y0, y1 = -2.6137, 2.5829

    def strips(xa, za, xb, zb):
        verts = np.stack(
            [
                np.column_stack([xa, np.full(n, y0), za]),
                np.column_stack([xb, np.full(n, y0), zb]),
                np.column_stack([xb, np.full(n, y1), zb]),
                np.column_stack([xa, np.full(n, y1), za]),
            ],
            axis=1,
        ).reshape(-1, 3)
        base = (np.arange(n, dtype=np.uint32) * 4)[:, None]
        faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
        return verts, faces.astype(np.uint32)

    zeros = np.zeros(n)
    # red: from (x0, 0) back to (x0 + half, half): normal (+0.71, 0, -0.71) faces the sun;
    # blue: from (x0 + half, half) forward to (x0 + period, 0): normal (-0.71, 0, -0.71).
    red = strips(x0, zeros, x0 + half, zeros + half)
    blue = strips(x0 + half, zeros + half, x0 + period, zeros)
    return {
        "type": "scene",
        "camera": ortho_camera(width, height, _STRIPES_HALF_WIDTH),
        # to-light (0.6, 0.3, -0.75): n.l = 0.94 on red, 0.10 on blue; the light's rays fall
        # more steeply in depth than the strips do, so no strip shadows another
        "sun": sun((-0.6, -0.3, 0.75)),
        "stripes_red": mesh(red, (0.8, 0.15, 0.1)),
        "stripes_blue": mesh(blue, (0.1, 0.2, 0.8)),
    }


def glossy(width: int, height: int) -> dict:
    """Glossy beads and a glossy sphere with sub-pixel highlights (Blinn-Phong)."""

    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 1.0, -9), target=(0, 0.6, 0), fov=45, near=0.1, far=100
        ),
        # from just above the camera: every bead is lit across its visible face (shadows fall
        # behind the beads)
        "sun": sun((0.0, -0.35, 1.0)),
        "ro_specular": {"ks": GLOSSY_KS, "shininess": GLOSSY_SHININESS},
        # a ground, not a backdrop: its mirror direction of the sun points behind the camera
        "ground": mesh(_rect_xz(-12, 12, -12, 30, y=-1.4), 0.3),
        "ball": {
            "type": "sphere",
            "center": [1.8, 0.4, 0.5],
            "radius": 1.1,
            "bsdf": diffuse((0.6, 0.1, 0.1)),
        },
    }
    # 7 x 5 glossy beads 0.15 units in radius (6 px across at the default 160 px width): the
    # highlight on each (half vector within 4 deg of the normal, cos^256 > 0.5) is a dot about
    # a tenth of the radius across, under half a pixel, inside the bead. (Spheres, not Mitsuba
    # cylinders: the oracle's shadow-ray offset for analytic shapes, 2^-19, is below a float32
    # cylinder's intersection error and leaves acne on its lit side.)
    for i in range(7):
        for j in range(5):
            scene[f"bead_{i}_{j}"] = {
                "type": "sphere",
                "center": [-0.6 - 0.5 * i, -1.0 + 0.55 * j, 0.0],
                "radius": 0.15,
                "bsdf": diffuse((0.15, 0.3, 0.6)),
            }
    return scene


def foliage(width: int, height: int) -> dict:
    """Four layers of thin blades at 3-7 units before a backdrop: 3+ surfaces a pixel."""

    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 0.45, -3), target=(0, 0.35, 5), fov=50, near=0.05, far=100
        ),
        "sun": sun((0.4, -0.8, 0.45)),
        "ground": mesh(_rect_xz(-30, 30, -5, 30), (0.35, 0.3, 0.2)),
        "backdrop": mesh(_rect_z(-30, 30, -1, 20, z=5.0), (0.3, 0.35, 0.5)),
    }
    rng = np.random.default_rng(17)
    greens = [(0.2, 0.5, 0.15), (0.35, 0.6, 0.1), (0.15, 0.4, 0.25), (0.5, 0.55, 0.15)]
    for k, rgb in enumerate(greens):
        z0 = 0.0 + k
        scene[f"blades_{k}"] = mesh(
            meshes.blades(
                rng, 900, x_range=(-3.6, 3.6), z_range=(z0, z0 + 1.0), height=1.1, width=0.012
            ),
            rgb,
        )
    return scene


def _rect_xz(x0, x1, z0, z1, y=0.0):
    """An axis-aligned rectangle in the plane ``y`` (ground)."""
    return meshes.quad([[x0, y, z0], [x0, y, z1], [x1, y, z1], [x1, y, z0]])


def hdr_edge(width: int, height: int) -> dict:
    """Bright strips 0.5-6 px wide before a near-black backdrop: 180:1 across each edge."""

    px = _wall_pixel(width)
    scene = {
        "type": "scene",
        "camera": _wall_camera(width, height),
        # nearly along the view axis: strips and backdrop both at n.l = 0.98
        "sun": sun((0.1, -0.15, 1.0), irradiance=10.0),
        "backdrop": mesh(_rect_z(-8, 8, -5, 5, z=0.5), HDR_BACKDROP_ALBEDO),
    }
    # vertical strips 1.5 deg off the vertical axis, widths in pixels at the film width
    a = np.radians(1.5)
    for k, w_px in enumerate([0.5, 1.0, 2.0, 4.0, 6.0]):
        w = w_px * px
        xc = -2.6 + 1.2 * k
        h = 3.0
        base = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
        rot = base @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
        pts = np.column_stack([xc + rot[:, 0], rot[:, 1], np.zeros(4)])
        scene[f"strip_{k}"] = mesh(meshes.quad(pts), HDR_STRIP_ALBEDO)
    return scene


#: name -> (factory, description, default width, default height), registered by
#: :mod:`scenes.catalogue.builtin` in ``BUILTIN_SCENES`` (not in the main job's default scenes).
AA_SCENES = {
    "decal": (
        decal,
        "a decal exactly on a wall and a duplicated panel (coplanar ties: ACAA counts twice)",
        160,
        90,
    ),
    "stripes": (
        stripes,
        "1-px zigzag stripes, red facing the sun, blue facing away (AGAA correlation loss)",
        160,
        90,
    ),
    "glossy": (
        glossy,
        "glossy beads and a sphere, Blinn-Phong s=256: sub-pixel highlights (specular aliasing)",
        160,
        90,
    ),
    "foliage": (
        foliage,
        "four layers of sub-pixel grass blades before a backdrop (3+ surfaces a pixel)",
        160,
        90,
    ),
    "hdr-edge": (
        hdr_edge,
        "bright strips 0.5-6 px wide on a near-black wall, 180:1 (HDR resolve)",
        160,
        90,
    ),
}
