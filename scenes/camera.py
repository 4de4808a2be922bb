"""Pinhole and orthographic cameras in float64, matching Mitsuba's sensors exactly.

Conventions
-----------
- Image pixel ``(x, y)`` covers ``[x, x+1) x [y, y+1)``, row 0 at the top; its centre is
  ``(x + 0.5, y + 0.5)``. Film positions are continuous pixel coordinates.
- Camera-local frame (Mitsuba's): +Z forward, +Y up, +X to the *left* of the image.
- View depth is the distance along the camera's forward axis from the camera position
  (perspective) or from the camera plane through ``to_world``'s origin (orthographic).
- Perspective rays start on the near plane and end on the far plane, as Mitsuba's
  ``perspective`` sensor does; orthographic rays start at local ``z = near``.

The same formulas run on NumPy arrays (models, export) and Dr.Jit arrays (the oracle), so
both sample the image plane identically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Camera", "look_at"]


def look_at(origin, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Mitsuba's look_at as a float64 ``to_world`` matrix: +Z forward, +Y up, +X left."""
    o, t, u = (np.asarray(a, float) for a in (origin, target, up))
    d = t - o
    d /= np.linalg.norm(d)
    left = np.cross(u, d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, o
    return m


@dataclass(frozen=True)
class Camera:
    """A camera: ``kind`` is ``"perspective"`` or ``"orthographic"``.

    Attributes
    ----------
    to_world : (4, 4) float64 camera-to-world matrix (Mitsuba's ``to_world``).
    fov_x : horizontal field of view in degrees (perspective only).
    width, height : film size in pixels.
    near, far : clip distances along the view axis, camera units.
    """

    kind: str
    to_world: np.ndarray
    width: int
    height: int
    near: float
    far: float
    fov_x: float = 0.0

    # ------------------------------------------------------------------ frames
    @property
    def aspect(self) -> float:
        return self.width / self.height

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.to_world, dtype=np.float64)[:3, 3].copy()

    @property
    def forward(self) -> np.ndarray:
        f = np.asarray(self.to_world, dtype=np.float64)[:3, 2]
        return f / np.linalg.norm(f)

    @property
    def up(self) -> np.ndarray:
        u = np.asarray(self.to_world, dtype=np.float64)[:3, 1]
        return u / np.linalg.norm(u)

    @property
    def right(self) -> np.ndarray:
        left = np.asarray(self.to_world, dtype=np.float64)[:3, 0]
        return -left / np.linalg.norm(left)

    @property
    def tan_half_x(self) -> float:
        return math.tan(math.radians(self.fov_x) / 2.0)

    @property
    def fov_y(self) -> float:
        """Vertical field of view in degrees (perspective)."""
        return math.degrees(2.0 * math.atan(self.tan_half_x / self.aspect))

    def with_resolution(self, width: int, height: int) -> Camera:
        return replace(self, width=int(width), height=int(height))

    def with_to_world(self, to_world: np.ndarray) -> Camera:
        return replace(self, to_world=np.asarray(to_world, dtype=np.float64))

    @property
    def pixel_angle(self) -> float:
        """Angle subtended by one pixel at the image centre, radians (perspective)."""
        return 2.0 * self.tan_half_x / self.width

    # ------------------------------------------------------------------ rays
    def local_ray(self, x, y):
        """Camera-local ray for film positions ``x, y`` (pixels): (origin, direction).

        Works for NumPy and Dr.Jit arrays; returns tuples of three components each. The
        direction is unnormalized with local z = 1.
        """
        u = x * (1.0 / self.width)
        v = y * (1.0 / self.height)
        sx = 1.0 - 2.0 * u
        sy = (1.0 - 2.0 * v) / self.aspect
        if self.kind == "perspective":
            t = self.tan_half_x
            return (0.0 * sx, 0.0 * sy, 0.0 * sx), (sx * t, sy * t, 1.0 + 0.0 * sx)
        return (sx, sy, self.near + 0.0 * sx), (0.0 * sx, 0.0 * sy, 1.0 + 0.0 * sx)

    def film_derivatives(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """World-space derivatives of :meth:`local_ray` with respect to film ``x`` and ``y``
        (pixels): ``(d_dir/dx, d_dir/dy, d_origin/dx, d_origin/dy)``, float64 ``(3,)`` each
        (the direction unnormalized, as in :meth:`local_ray`)."""
        rot = np.asarray(self.to_world, dtype=np.float64)[:3, :3]
        # sx = 1 - 2x/W, sy = (1 - 2y/H)/aspect
        dsx, dsy = -2.0 / self.width, -2.0 / (self.height * self.aspect)
        zero = np.zeros(3)
        if self.kind == "perspective":
            t = self.tan_half_x
            return rot @ np.array([dsx * t, 0, 0]), rot @ np.array([0, dsy * t, 0]), zero, zero
        return zero, zero, rot @ np.array([dsx, 0, 0]), rot @ np.array([0, dsy, 0])

    def rays(self, x: np.ndarray, y: np.ndarray):
        """World-space rays through film positions (NumPy, float64).

        Returns ``origins (N, 3)``, unit ``directions (N, 3)``, ``tmax (N,)``: perspective
        rays start on the near plane, as in Mitsuba.
        """
        x = np.asarray(x, dtype=np.float64).ravel()
        y = np.asarray(y, dtype=np.float64).ravel()
        (ox, oy, oz), (dx, dy, dz) = self.local_ray(x, y)
        m = np.asarray(self.to_world, dtype=np.float64)
        o_local = np.stack([ox, oy, oz], axis=-1)
        d_local = np.stack([dx, dy, dz], axis=-1)
        d = d_local @ m[:3, :3].T
        o = o_local @ m[:3, :3].T + m[:3, 3]
        norm = np.linalg.norm(d, axis=-1, keepdims=True)
        d = d / norm
        if self.kind == "perspective":
            # local z of d_local is 1: distance to near plane along the unit ray
            scale = norm[:, 0] / np.linalg.norm(m[:3, 2])
            o = o + d * (self.near * scale)[:, None]
            tmax = (self.far - self.near) * scale
        else:
            tmax = np.full(x.shape, self.far - self.near)
        return o, d, tmax

    # ------------------------------------------------------------------ projection
    def view_depth(self, points: np.ndarray) -> np.ndarray:
        """View-space depth of world points ``(..., 3)`` along the forward axis."""
        return (np.asarray(points, dtype=np.float64) - self.position) @ self.forward

    def project(self, points: np.ndarray) -> np.ndarray:
        """Film position ``(..., 2)`` in pixels of world points ``(..., 3)``."""
        p = np.asarray(points, dtype=np.float64)
        inv = np.linalg.inv(np.asarray(self.to_world, dtype=np.float64))
        local = p @ inv[:3, :3].T + inv[:3, 3]
        if self.kind == "perspective":
            sx = local[..., 0] / (local[..., 2] * self.tan_half_x)
            sy = local[..., 1] / (local[..., 2] * self.tan_half_x)
        else:
            sx, sy = local[..., 0], local[..., 1]
        u = (1.0 - sx) / 2.0
        v = (1.0 - sy * self.aspect) / 2.0
        return np.stack([u * self.width, v * self.height], axis=-1)

    # ------------------------------------------------------------------ matrices
    def world_to_view(self, convention: str = "opengl") -> np.ndarray:
        """World-to-view matrix (column vectors, ``p_view = M @ p_world``).

        ``"opengl"``: right-handed, +X right, +Y up, camera looks down -Z.
        ``"direct3d"``: left-handed, +X right, +Y up, camera looks down +Z.
        Scale in ``to_world`` is removed (orthonormal view frame).
        """
        frame = np.eye(4)
        frame[:3, 0] = self.right
        frame[:3, 1] = self.up
        frame[:3, 2] = -self.forward if convention == "opengl" else self.forward
        frame[:3, 3] = self.position
        if convention not in ("opengl", "direct3d"):
            raise ValueError(f"convention must be 'opengl' or 'direct3d', got {convention!r}")
        return np.linalg.inv(frame)

    def half_extent(self) -> tuple[float, float]:
        """Orthographic half width and half height in world units."""
        m = np.asarray(self.to_world, dtype=np.float64)
        return float(np.linalg.norm(m[:3, 0])), float(np.linalg.norm(m[:3, 1]) / self.aspect)

    def projection(self, convention: str = "opengl") -> np.ndarray:
        """Projection matrix (column vectors) for the view matrix of the same convention.

        OpenGL: clip z in [-w, w] (NDC z in [-1, 1]); Direct3D: NDC z in [0, 1]. Both map
        the near plane to the low end and the far plane to the high end.
        """
        n, f = self.near, self.far
        p = np.zeros((4, 4))
        if self.kind == "perspective":
            sx = 1.0 / self.tan_half_x
            sy = self.aspect / self.tan_half_x
            p[0, 0], p[1, 1] = sx, sy
            if convention == "opengl":
                p[2, 2], p[2, 3], p[3, 2] = -(f + n) / (f - n), -2 * f * n / (f - n), -1.0
            else:
                p[2, 2], p[2, 3], p[3, 2] = f / (f - n), -f * n / (f - n), 1.0
        else:
            hw, hh = self.half_extent()
            p[0, 0], p[1, 1], p[3, 3] = 1.0 / hw, 1.0 / hh, 1.0
            if convention == "opengl":
                p[2, 2], p[2, 3] = -2.0 / (f - n), -(f + n) / (f - n)
            else:
                p[2, 2], p[2, 3] = 1.0 / (f - n), -n / (f - n)
        return p

    def to_json(self) -> dict:
        """Plain record for ``camera.json``."""
        out = {
            "kind": self.kind,
            "width": self.width,
            "height": self.height,
            "near": self.near,
            "far": self.far,
            "fov_x_deg": self.fov_x if self.kind == "perspective" else None,
            "fov_y_deg": self.fov_y if self.kind == "perspective" else None,
            "position": self.position.tolist(),
            "forward": self.forward.tolist(),
            "up": self.up.tolist(),
            "right": self.right.tolist(),
            "to_world_mitsuba": np.asarray(self.to_world).tolist(),
            "matrix_convention": "column vectors: p_clip = projection @ world_to_view @ p_world",
            "pixel_centre": "pixel (x, y) covers [x, x+1) x [y, y+1), row 0 at the top; "
            "its centre is (x + 0.5, y + 0.5)",
        }
        for conv in ("opengl", "direct3d"):
            out[conv] = {
                "world_to_view": self.world_to_view(conv).tolist(),
                "projection": self.projection(conv).tolist(),
            }
        if self.kind == "orthographic":
            out["half_extent"] = list(self.half_extent())
        return out
