"""Light frames and shadow-map projections (orthographic and perspective).

Conventions
-----------
- A light frame is D3D's ``LookAtLH``: ``z`` is the direction the light travels (from the
  light into the scene), ``x = normalize(up x z)``, ``y = z x x``. Light-frame coordinates are
  ``(x . (P - origin), y . (P - origin), z . (P - origin))``; ``origin`` is the world origin for
  directional lights and the light position for spot and point lights.
- A projection maps world points to homogeneous shadow-texture coordinates with one 4x4 matrix
  ``M`` (rows ``u, v, z, w``): ``u, v = (M P)[:2] / w`` in ``[0, 1]`` (texel ``(i, j)`` covers
  ``[i, i+1) / R x [j, j+1) / R``, row 0 at ``v = 0``, which is the light frame's top ``+y``),
  depth ``z = (M P)[2] / w`` in ``[0, 1]`` (D3D: 0 at the near plane). Orthographic maps have
  ``w = 1``; perspective maps ``w`` = light-view depth and D3D's hyperbolic depth.
- ``precision="float32"`` keeps a float32 copy of the matrix and evaluates lookups in float32,
  as a GPU shader does; the map's texel grid is then defined by that rounded matrix too
  (a rasterizer transforms vertices with it).
- A degenerate up vector (parallel to the light) never produces NaN: the next hint of the
  list is used and the frame records which one (``up_used``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PARALLEL_TOLERANCE", "LightFrame", "Projection", "make_frame"]

#: Up hints closer than this (sine of the angle) to the light direction count as parallel:
#: the frame would be numerically meaningless (0.057 degrees).
PARALLEL_TOLERANCE = 1e-3


@dataclass(frozen=True)
class LightFrame:
    """Orthonormal light frame (see module docstring); ``up_used`` names the up hint used."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    origin: np.ndarray
    up_used: str = "world"

    def rotation(self) -> np.ndarray:
        """(3, 3) world-to-light rotation, rows ``x, y, z``."""
        return np.stack([self.x, self.y, self.z])

    def to_light(self, points: np.ndarray) -> np.ndarray:
        """Light-frame coordinates of world points ``(..., 3)`` (float64)."""
        p = np.asarray(points, dtype=np.float64) - self.origin
        return p @ self.rotation().T

    def to_json(self) -> dict:
        return {
            "x": self.x.tolist(),
            "y": self.y.tolist(),
            "z": self.z.tolist(),
            "origin": self.origin.tolist(),
            "up_used": self.up_used,
        }


def make_frame(forward, hints, origin=(0.0, 0.0, 0.0)) -> LightFrame:
    """Light frame looking along ``forward`` with the first usable ``(name, up)`` of ``hints``.

    A hint is unusable when it is zero or within :data:`PARALLEL_TOLERANCE` of ``forward``;
    world X, Y and Z are always appended as last resorts, so a frame always exists.
    """
    f = np.asarray(forward, dtype=np.float64)
    f = f / np.linalg.norm(f)
    candidates = list(hints) + [
        ("world_y", (0.0, 1.0, 0.0)),
        ("world_z", (0.0, 0.0, 1.0)),
        ("world_x", (1.0, 0.0, 0.0)),
    ]
    for name, up in candidates:
        u = np.asarray(up, dtype=np.float64)
        norm = np.linalg.norm(u)
        if not np.isfinite(norm) or norm == 0.0:
            continue
        u = u / norm
        c = np.cross(u, f)
        if np.linalg.norm(c) < PARALLEL_TOLERANCE:
            continue
        x = c / np.linalg.norm(c)
        y = np.cross(f, x)
        return LightFrame(x, y, f, np.asarray(origin, dtype=np.float64), name)
    raise AssertionError("unreachable: world axes cannot all be parallel to one direction")


@dataclass
class Projection:
    """One shadow map's projection: ``kind`` ``"ortho"`` or ``"persp"`` (square, D3D depth).

    ``extent`` is ``(x0, x1, y0, y1, z0, z1)`` in light-frame units for ``ortho`` and
    ``(tan_half, near, far)`` for ``persp``.
    """

    kind: str
    frame: LightFrame
    extent: tuple
    resolution: int
    precision: str = "float64"
    matrix: np.ndarray = field(init=False)
    matrix_used: np.ndarray = field(init=False)

    def __post_init__(self):
        rot = self.frame.rotation()
        t = -rot @ self.frame.origin
        view = np.eye(4)
        view[:3, :3] = rot
        view[:3, 3] = t
        if self.kind == "ortho":
            x0, x1, y0, y1, z0, z1 = (float(v) for v in self.extent)
            proj = np.array(
                [
                    [1.0 / (x1 - x0), 0.0, 0.0, -x0 / (x1 - x0)],
                    [0.0, -1.0 / (y1 - y0), 0.0, y1 / (y1 - y0)],
                    [0.0, 0.0, 1.0 / (z1 - z0), -z0 / (z1 - z0)],
                    [0.0, 0.0, 0.0, 1.0],
                ]
            )
        elif self.kind == "persp":
            tan_half, n, f = (float(v) for v in self.extent)
            a, b = f / (f - n), f * n / (f - n)
            proj = np.array(
                [
                    [0.5 / tan_half, 0.0, 0.5, 0.0],
                    [0.0, -0.5 / tan_half, 0.5, 0.0],
                    [0.0, 0.0, a, -b],
                    [0.0, 0.0, 1.0, 0.0],
                ]
            )
        else:  # pragma: no cover - programming error
            raise ValueError(f"unknown projection kind {self.kind!r}")
        if self.precision == "float32":
            # Matrices are built and multiplied in float32, as on the CPU side of an engine
            # that keeps its math in 32-bit floats.
            m = proj.astype(np.float32) @ view.astype(np.float32)
            self.matrix = m.astype(np.float64)
            self.matrix_used = m
        else:
            self.matrix = proj @ view
            self.matrix_used = self.matrix

    # ------------------------------------------------------------------ lookups
    @property
    def dtype(self):
        return np.float32 if self.precision == "float32" else np.float64

    def project(self, points: np.ndarray):
        """``(u, v, z, w)`` of world points ``(N, 3)``: texture coordinates, depth and ``w``.

        Evaluated in the projection's precision; returned as float64 arrays.
        """
        m = self.matrix_used
        p = np.asarray(points, dtype=self.dtype)
        if self.kind == "ortho":
            # Affine: w = 1 exactly, no division.
            r = p @ m[:3, :3].T + m[:3, 3]
            u, v, z = (r[:, i].astype(np.float64, copy=False) for i in range(3))
            return u, v, z, np.ones(len(p))
        r = p @ m[:, :3].T + m[:, 3]
        w = r[:, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v, z = r[:, 0] / w, r[:, 1] / w, r[:, 2] / w
        return tuple(a.astype(np.float64, copy=False) for a in (u, v, z, w))

    # ------------------------------------------------------------------ rays
    def grid_rays(self, z_start: float, z_end: float) -> dict:
        """Affine description of the rays through texel centres (float64).

        Ray for texture coordinates ``(s, t)``: unnormalized direction
        ``D + s DS + t DT`` and origin ``A + s U + t V + z_start * direction``; ``k`` converts
        a hit distance along the *unit* direction into light depth (``ortho``: light-frame
        ``z``; ``persp``: light-view depth, the direction having view-``z`` 1).
        """
        if self.kind == "ortho":
            inv = np.linalg.inv(self.matrix)
            x0, x1, y0, y1, z0, z1 = (float(v) for v in self.extent)
            a = inv @ np.array([0.0, 0.0, 0.0, 1.0])
            u_vec = inv @ np.array([1.0, 0.0, 0.0, 0.0])
            v_vec = inv @ np.array([0.0, 1.0, 0.0, 0.0])
            zdir = inv @ np.array([0.0, 0.0, 1.0, 0.0])
            depth_axis = zdir[:3] / np.linalg.norm(zdir[:3])
            # Light-frame z of the texture plane z_ndc = 0 is z0; move the origins to z_start.
            origin0 = a[:3] + depth_axis * (z_start - z0)
            return {
                "A": origin0,
                "U": u_vec[:3],
                "V": v_vec[:3],
                "D": depth_axis,
                "DS": np.zeros(3),
                "DT": np.zeros(3),
                "z_start": float(z_start),
                "z_end": float(z_end),
                "origin_along_dir": False,
            }
        tan_half = float(self.extent[0])
        fr = self.frame
        return {
            "A": fr.origin.copy(),
            "U": np.zeros(3),
            "V": np.zeros(3),
            "D": fr.z - tan_half * fr.x + tan_half * fr.y,
            "DS": 2.0 * tan_half * fr.x,
            "DT": -2.0 * tan_half * fr.y,
            "z_start": float(z_start),
            "z_end": float(z_end),
            "origin_along_dir": True,
        }

    def texel_world_size(self, w: np.ndarray | None = None) -> np.ndarray | float:
        """World size of one texel (the larger axis), at light-view depth ``w`` for persp."""
        r = self.resolution
        if self.kind == "ortho":
            x0, x1, y0, y1 = (float(v) for v in self.extent[:4])
            return max(x1 - x0, y1 - y0) / r
        tan_half = float(self.extent[0])
        return 2.0 * tan_half * np.asarray(w, dtype=np.float64) / r

    def to_json(self) -> dict:
        out = {
            "kind": self.kind,
            "resolution": self.resolution,
            "frame": self.frame.to_json(),
            "matrix_world_to_texture": self.matrix.tolist(),
            "precision": self.precision,
        }
        if self.kind == "ortho":
            x0, x1, y0, y1, z0, z1 = (float(v) for v in self.extent)
            out["light_space_bounds"] = {
                "x": [x0, x1],
                "y": [y0, y1],
                "z": [z0, z1],
                "units": "world units along the light frame's x, y, z",
            }
            out["texel_size"] = [(x1 - x0) / self.resolution, (y1 - y0) / self.resolution]
        else:
            tan_half, n, f = (float(v) for v in self.extent)
            out["fov_deg"] = math.degrees(2 * math.atan(tan_half))
            out["near"], out["far"] = n, f
        return out
