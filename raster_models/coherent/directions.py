"""Coherent shadow maps' directions: the maps' travel directions numbered along a Hilbert
curve, the id texture, and each map's orthographic projection over the bounding sphere.

Directions: a ``g x g`` grid (``g = sqrt(N)``) over ``[0, 1]^2``, ``u = phi / 2pi``,
``v = (1 - cos(theta)) / 2`` (equal-area: every cell covers ``4 pi / N`` steradians; theta
from +Y), each cell's centre giving the map's travel direction. Map ids run along the
Hilbert curve over the grid (:mod:`raster_models.coherent.hilbert`): consecutive ids,
neighbouring directions.

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
"""

from __future__ import annotations

import math

import numpy as np

from ..light_frame import Projection, make_frame
from .hilbert import hilbert_cell, hilbert_index

__all__ = ["SPHERE_MARGIN", "Projections", "direction", "map_directions", "uv"]

#: Relative margin on the bounding sphere's radius (geometry on the sphere stays inside).
SPHERE_MARGIN = 1e-4


def map_directions(n_maps: int) -> tuple[np.ndarray, np.ndarray]:
    """Travel directions of the maps, by map id, and the id texture.

    Returns ``(directions, id_texture)``: ``(N, 3)`` unit vectors (map ``m`` looks along
    ``directions[m]``) and the ``(g, g)`` int64 id texture (row = v cell, column = u cell).
    """
    g = math.isqrt(n_maps)
    cx, cy = hilbert_cell(g, np.arange(n_maps))
    u = (cx + 0.5) / g
    v = (cy + 0.5) / g
    ids = hilbert_index(g, *np.meshgrid(np.arange(g), np.arange(g)))
    return direction(u, v), ids


def direction(u, v) -> np.ndarray:
    """Unit vectors of ``(u, v)`` in ``[0, 1]^2``: ``phi = 2 pi u``, ``cos(theta) = 1 - 2 v``
    (theta from +Y; equal-area, see the module docstring)."""
    phi = 2.0 * math.pi * np.asarray(u, dtype=np.float64)
    cos_t = 1.0 - 2.0 * np.asarray(v, dtype=np.float64)
    sin_t = np.sqrt(np.clip(1.0 - cos_t * cos_t, 0.0, 1.0))
    return np.stack([sin_t * np.cos(phi), cos_t, sin_t * np.sin(phi)], axis=-1)


def uv(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u, v)`` of unit vectors ``(M, 3)`` (inverse of :func:`direction`)."""
    u = np.mod(np.arctan2(w[:, 2], w[:, 0]) / (2.0 * math.pi), 1.0)
    v = 0.5 * (1.0 - np.clip(w[:, 1], -1.0, 1.0))
    return u, v


class Projections:
    """The orthographic projection of each map over the bounding sphere, built on demand
    (a map's matrix, the paper's matrix texture entry).

    Parameters
    ----------
    scene : the loaded scene (its bounds give the sphere: centre and radius, world units,
        the radius widened by :data:`SPHERE_MARGIN`).
    dirs : ``(N, 3)`` travel directions by map id (:func:`map_directions`).
    resolution : texels per side of every map.
    """

    def __init__(self, scene, dirs: np.ndarray, resolution: int):
        lo, hi = scene.bounds()
        self.centre = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo)) * (1.0 + SPHERE_MARGIN)
        self.radius = max(radius, 1e-9)
        self.resolution = int(resolution)
        self._dirs = dirs
        self._cache: dict[int, Projection] = {}

    @property
    def directions(self) -> np.ndarray:
        """``(N, 3)`` travel directions by map id."""
        return self._dirs

    def __getitem__(self, m) -> Projection:
        m = int(m)
        if m not in self._cache:
            frame = make_frame(self._dirs[m], [("world_y", (0.0, 1.0, 0.0))])
            c = frame.to_light(self.centre[None, :])[0]
            rad = self.radius
            extent = (c[0] - rad, c[0] + rad, c[1] - rad, c[1] + rad, c[2] - rad, c[2] + rad)
            self._cache[m] = Projection("ortho", frame, extent, self.resolution)
        return self._cache[m]
