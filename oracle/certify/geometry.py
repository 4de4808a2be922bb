"""Closed forms of the self-check's scenes: a square plate above a ground plane, seen from
above and lit by a sun, a spot or a point light, and a straight edge's pixel coverage.

Everything here is NumPy float64 and independent of Mitsuba: the camera rays come from
:meth:`scenes.camera.Camera.rays`, the surfaces are planes, and the answers are exact up to
a margin (points closer than :data:`MARGIN` to a boundary are not scored).
"""

from __future__ import annotations

import math

import numpy as np

from ...scenes.camera import look_at
from ...scenes.catalogue.factories import ground, mesh, sensor, sun
from ...scenes.geometry import meshes

__all__ = [
    "MARGIN",
    "PLATE_HALF",
    "PLATE_HEIGHT",
    "half_plane_coverage",
    "plate_scene",
    "plate_truth",
]

#: The plate: the square ``|x|, |z| <= PLATE_HALF`` at height ``PLATE_HEIGHT`` over y = 0.
PLATE_HALF, PLATE_HEIGHT = 1.0, 1.5
#: World units: points (or shadow-ray crossings) nearer a boundary than this are not scored
#: (float32 hit positions are exact to ~1e-6 units at these distances).
MARGIN = 2e-3
#: Spot cone used by the self-check (degrees): wide enough to light the plate and its shadow.
SPOT_CUTOFF, SPOT_BEAM = 50.0, 40.0


def plate_scene(light: str, *, with_ground: bool = True):
    """Scene factory ``(width, height) -> dict``: ground (unless not ``with_ground``), plate
    and a ``light`` (``sun``, ``spot`` or ``point``), camera looking down at the plate and
    its shadow."""

    def factory(width: int, height: int) -> dict:
        scene = {
            "type": "scene",
            "camera": sensor(
                width, height, origin=(0, 6, 6), target=(0.6, 0, 0), fov=55, near=0.1, far=100
            ),
            "ground": ground(30.0, 0.6),
            "plate": mesh(
                meshes.quad(
                    [
                        [-PLATE_HALF, PLATE_HEIGHT, -PLATE_HALF],
                        [-PLATE_HALF, PLATE_HEIGHT, PLATE_HALF],
                        [PLATE_HALF, PLATE_HEIGHT, PLATE_HALF],
                        [PLATE_HALF, PLATE_HEIGHT, -PLATE_HALF],
                    ]
                ),
                (0.7, 0.3, 0.2),
            ),
        }
        if not with_ground:
            del scene["ground"]
        if light == "sun":
            scene["sun"] = sun((0.55, -1.0, 0.2))
        elif light == "spot":
            scene["spot"] = {
                "type": "spot",
                "to_world": look_at((-0.6, 4.5, 0.3), (0.8, 0.0, 0.0), (0, 0, 1)),
                "intensity": {"type": "rgb", "value": [60.0] * 3},
                "cutoff_angle": SPOT_CUTOFF,
                "beam_width": SPOT_BEAM,
            }
        else:
            scene["lamp"] = {
                "type": "point",
                "position": [-0.5, 4.0, 0.2],
                "intensity": {"type": "rgb", "value": [40.0] * 3},
            }
        return scene

    return factory


def _inside(x, z, margin):
    """+1 inside the plate square by more than ``margin``, -1 outside by more, 0 between."""
    d = PLATE_HALF - np.maximum(np.abs(x), np.abs(z))
    return np.where(d > margin, 1, np.where(d < -margin, -1, 0))


def plate_truth(loaded) -> dict:
    """What the pixel-centre rays of a :func:`plate_scene` see, in closed form.

    Returns ``{"shape": (N,) int (index into loaded.shape_names, -1 sky), "lit": (N,) bool
    (True for sky, as the oracle), "scored": (N,) bool}``, pixels in row-major order;
    ``scored`` leaves out pixels within :data:`MARGIN` of a silhouette, a shadow edge or a
    spot cone's edge.
    """
    cam, light = loaded.camera, loaded.light
    yy, xx = np.mgrid[0 : cam.height, 0 : cam.width]
    o, d, tmax = cam.rays(xx.ravel() + 0.5, yy.ravel() + 0.5)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_plate = (PLATE_HEIGHT - o[:, 1]) / d[:, 1]
        t_ground = -o[:, 1] / d[:, 1]
    p_plate = o + d * t_plate[:, None]
    in_front = (t_plate > 0) & (t_plate < tmax)
    side = np.where(in_front, _inside(p_plate[:, 0], p_plate[:, 2], MARGIN), -1)
    on_ground = (side < 0) & (t_ground > 0) & (t_ground < tmax)
    point = np.where((side > 0)[:, None], p_plate, o + d * t_ground[:, None])
    names = list(loaded.shape_names)
    shape = np.where(side > 0, names.index("plate"), np.where(on_ground, names.index("ground"), -1))
    scored = side != 0
    if light.is_directional:
        wl = np.broadcast_to(-np.asarray(light.direction, np.float64), point.shape)
        dist = np.full(len(point), np.inf)
    else:
        delta = np.asarray(light.position, np.float64) - point
        dist = np.linalg.norm(delta, axis=1)
        wl = delta / dist[:, None]
    receives = wl[:, 1] > 0.0  # both surfaces face up; the lights are above them
    if light.kind == "spot":
        axis = np.asarray(light.direction, np.float64)
        angle = np.degrees(np.arccos(np.clip(-(wl @ axis), -1.0, 1.0)))
        receives &= angle < light.cutoff_angle
        scored &= np.abs(angle - light.cutoff_angle) > math.degrees(MARGIN / 10.0)
    # a ground point is shadowed where its ray to the light crosses the plate
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (PLATE_HEIGHT - point[:, 1]) / wl[:, 1]
    q = point + wl * s[:, None]
    crossing = on_ground & (s > 0) & (s < dist)
    blocked = np.where(crossing, _inside(q[:, 0], q[:, 2], MARGIN), -1)
    scored &= ~(on_ground & (blocked == 0))
    lit = np.where(shape < 0, True, receives & (blocked < 0))
    return {"shape": shape, "lit": lit, "scored": scored}


def half_plane_coverage(a: float, b: float, c: float, width: int, height: int) -> np.ndarray:
    """Fraction of each pixel square ``[x, x+1) x [y, y+1)`` where ``a x + b y + c >= 0``:
    the square clipped by the line (Sutherland-Hodgman, one edge), area by the shoelace
    formula; ``(height, width)`` float64."""
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    corners = np.stack(
        [
            np.stack([xx, yy], -1),
            np.stack([xx + 1, yy], -1),
            np.stack([xx + 1, yy + 1], -1),
            np.stack([xx, yy + 1], -1),
        ],
        axis=-2,
    )  # (H, W, 4, 2) counter-clockwise in (x, y)
    f = a * corners[..., 0] + b * corners[..., 1] + c
    nxt = np.roll(corners, -1, axis=-2)
    fn = np.roll(f, -1, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(f != fn, f / (f - fn), 0.0)
    cross = corners + t[..., None] * (nxt - corners)
    # candidate vertices in order: each corner if inside, then the crossing if the edge
    # changes side; the others repeat the previous kept vertex (zero-area steps)
    cand = np.stack([corners, cross], axis=-2).reshape(height, width, 8, 2)
    keep = np.stack([f >= 0, (f >= 0) != (fn >= 0)], axis=-1).reshape(height, width, 8)
    first = np.argmax(keep, axis=-1)
    pts = np.take_along_axis(cand, first[..., None, None].repeat(2, -1), axis=-2)[..., 0, :]
    filled = np.empty_like(cand)
    for k in range(8):  # eight candidate slots (a fixed, tiny loop)
        pts = np.where(keep[..., k, None], cand[..., k, :], pts)
        filled[..., k, :] = pts
    x, y = filled[..., 0], filled[..., 1]
    area = 0.5 * np.abs(np.sum(x * np.roll(y, -1, -1) - np.roll(x, -1, -1) * y, axis=-1))
    return np.where(keep.any(-1), area, 0.0)
