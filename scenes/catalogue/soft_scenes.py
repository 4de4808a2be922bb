"""Built-in soft-shadow scenes: ``soft-contact`` (an area light; contact hardening) and
``stacked-casters`` (a sun over casters stacked in depth; light bleeding of filtered maps).

- ``soft-contact``: a 1 m square rectangle light 5 m above a ground plane, facing down; a post
  standing on the ground (its shadow is sharp at the base and widens along its length), a
  sphere 0.1 m above the ground, a low box and a plate 2 m up (a wide penumbra). Blocker to
  receiver distances run from 0 to 2 m, so penumbrae run from 0 to 0.67 m: what PCSS's
  blocker search and penumbra estimate have to follow.
- ``stacked-casters``: a sun over plates stacked above each other, a box and a sphere below
  them: receivers in the shadow of a high caster and at the edge of a lower one's shadow,
  where variance, exponential-variance and moment shadow maps leak light (the two depths in
  one filter region break their single-occluder assumption).

Each is a factory ``factory(width, height) -> dict`` (see :mod:`scenes.builtin`).
"""

from __future__ import annotations

import numpy as np

from ..camera import look_at
from ..geometry import meshes
from ..shading.materials import diffuse
from .factories import ground, mesh, sensor, sun

__all__ = ["SOFT_SCENES", "rectangle_light", "soft_contact", "stacked_casters"]


def rectangle_light(centre, normal, size, radiance, up=(0.0, 0.0, 1.0)) -> dict:
    """A Mitsuba ``rectangle`` with an ``area`` emitter: ``size = (width, height)`` metres,
    centred at ``centre``, emitting towards ``normal`` (one-sided), its width along the
    direction ``up x normal``; grey ``radiance`` (W/m^2/sr)."""
    c = np.asarray(centre, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    m = look_at(c, c + n, up)  # columns: left, up, forward (= normal); Mitsuba's +Z is the normal
    m[:3, 0] *= 0.5 * float(size[0])
    m[:3, 1] *= 0.5 * float(size[1])
    return {
        "type": "rectangle",
        "to_world": m,
        "bsdf": diffuse(0.0),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [float(radiance)] * 3}},
    }


def soft_contact(width: int, height: int) -> dict:
    """A post, a sphere near the ground, a low box and a raised plate under a square area
    light: contact hardening and penumbrae up to 0.67 m."""
    return {
        "type": "scene",
        "camera": sensor(
            width,
            height,
            origin=(1.0, 5.5, 7.5),
            target=(0.6, 0.0, -0.3),
            fov=60,
            near=0.1,
            far=100,
        ),
        "area_light": rectangle_light((-2.5, 5.0, -0.5), (0.0, -1.0, 0.0), (1.0, 1.0), 40.0),
        "ground": ground(40.0, 0.6),
        "post": mesh(meshes.box((-1.3, 0.0, -0.1), (-1.1, 2.2, 0.1)), (0.75, 0.7, 0.6)),
        "ball": {
            "type": "sphere",
            "center": [0.8, 0.7, 1.0],
            "radius": 0.6,
            "bsdf": diffuse((0.8, 0.3, 0.3)),
        },
        "block": mesh(meshes.box((-0.6, 0.0, 1.4), (0.2, 0.3, 1.9)), (0.3, 0.5, 0.8)),
        "plate": mesh(
            meshes.quad([[0.0, 2.0, -2.0], [0.0, 2.0, -1.2], [1.2, 2.0, -1.2], [1.2, 2.0, -2.0]]),
            (0.5, 0.7, 0.4),
        ),
    }


def stacked_casters(width: int, height: int) -> dict:
    """Plates stacked at 0.8, 1.6 and 2.6 m, a box and a sphere below them, under a sun: the
    ground in a high plate's shadow sees a lower caster's shadow edge (light bleeding)."""
    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(5.5, 7.5, 8.5), target=(0.8, 0.6, 0.0), fov=55, near=0.1, far=100
        ),
        "sun": sun((0.35, -1.0, 0.15)),
        "ground": ground(60.0, 0.6),
        "box": mesh(meshes.box((0.6, 0.0, -0.3), (1.2, 0.5, 0.3)), (0.3, 0.5, 0.8)),
        "ball": {
            "type": "sphere",
            "center": [-0.6, 0.35, 0.9],
            "radius": 0.35,
            "bsdf": diffuse((0.8, 0.3, 0.3)),
        },
    }
    # (height, x0, x1, z0, z1, albedo): each lower plate pokes out of the one above's shadow
    plates = [
        (2.6, -1.6, 1.0, -1.4, 1.2, (0.7, 0.3, 0.2)),
        (1.6, -0.8, 1.0, -0.6, 1.8, (0.5, 0.7, 0.4)),
        (0.8, -0.2, 1.6, -1.0, 0.4, (0.75, 0.7, 0.6)),
    ]
    for i, (y, x0, x1, z0, z1, rgb) in enumerate(plates):
        scene[f"plate_{i}"] = mesh(
            meshes.quad([[x0, y, z0], [x0, y, z1], [x1, y, z1], [x1, y, z0]]), rgb
        )
    return scene


#: name -> (factory, description, default width, default height)
SOFT_SCENES = {
    "soft-contact": (
        soft_contact,
        "a post, a sphere near the ground, a box and a raised plate under a 1 m square area "
        "light (contact hardening, penumbrae 0-0.67 m)",
        160,
        90,
    ),
    "stacked-casters": (
        stacked_casters,
        "plates stacked at three heights over a box and a sphere under a sun (light bleeding "
        "of variance and moment shadow maps)",
        160,
        90,
    ),
}
