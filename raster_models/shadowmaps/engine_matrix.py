"""An engine's own light matrix (``light_matrix=FILE``): the model renders and samples the
map the engine fitted, instead of fitting its own light box.

The file is JSON: ``{"matrix": [[...], [...], [...], [...]], "texture_origin": "top-left"}``,
the 4x4 row-major matrix taking world points (Mitsuba's world, as ``export`` writes it) to
shadow-texture coordinates ``(u, v, depth, 1)`` in ``[0, 1]^3`` (three.js: ``shadow.matrix``,
which already includes the 0.5 scale and bias; Direct3D: light view x projection x texture
scale and bias). ``texture_origin``: ``top-left`` (Direct3D and this model: ``v`` grows
down the light's ``+y``) or ``bottom-left`` (OpenGL/WebGL: ``v`` grows up; converted with
``v -> 1 - v``). Only an orthographic (affine) matrix of one directional-light map is taken:
its three rows must be orthogonal directions (a light view that is a rotation).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..light_frame import LightFrame, Projection

__all__ = ["ORTHOGONALITY_TOLERANCE", "load_light_matrix", "projection_from_matrix"]

#: Largest |cos| between two rows' directions accepted as orthogonal (float32 matrices).
ORTHOGONALITY_TOLERANCE = 1e-4


def load_light_matrix(path: str) -> np.ndarray:
    """The matrix of a ``light_matrix`` file in this model's convention (top-left origin);
    a :class:`ModelError` naming the file and what is wrong."""
    label = f"light_matrix {path}"
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise ModelError(f"{label}: cannot read it ({exc.strerror or exc})") from None
    except ValueError as exc:
        raise ModelError(f"{label}: not JSON ({exc})") from None
    if not isinstance(data, dict) or "matrix" not in data:
        raise ModelError(f'{label}: expected an object with "matrix" (4x4 row-major)')
    try:
        m = np.asarray(data["matrix"], dtype=np.float64)
    except (TypeError, ValueError):
        raise ModelError(f"{label}: matrix must be 4x4 numbers") from None
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ModelError(f"{label}: matrix must be 4x4 finite numbers, got shape {m.shape}")
    origin = data.get("texture_origin", "top-left")
    if origin not in ("top-left", "bottom-left"):
        raise ModelError(f"{label}: texture_origin must be top-left or bottom-left, got {origin!r}")
    if origin == "bottom-left":
        m = m.copy()
        m[1] = m[3] - m[1]
    return m


def projection_from_matrix(m: np.ndarray, resolution: int, precision: str) -> Projection:
    """The orthographic :class:`Projection` whose world-to-texture matrix is ``m`` (top-left
    origin): light frame axes and extent recovered from the rows."""
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ModelError(
            "light_matrix: only an orthographic map (last row 0 0 0 1) is taken, got "
            f"{m[3].tolist()}"
        )
    rows = m[:3, :3]
    lengths = np.linalg.norm(rows, axis=1)
    if np.any(lengths <= 0.0):
        raise ModelError("light_matrix: a row of the matrix is zero")
    axes = rows / lengths[:, None]
    cos = np.abs(axes @ axes.T - np.eye(3))
    if cos.max() > ORTHOGONALITY_TOLERANCE:
        raise ModelError(
            f"light_matrix: rows are not orthogonal directions (|cos| up to {cos.max():.2g})"
        )
    size = 1.0 / lengths  # world extent of u, v and depth
    # u = x.p / sx - x0 / sx; v = -y.p / sy + y1 / sy; z = z.p / sz - z0 / sz
    x_axis, y_axis, z_axis = axes[0], -axes[1], axes[2]
    x0 = -m[0, 3] * size[0]
    y1 = m[1, 3] * size[1]
    z0 = -m[2, 3] * size[2]
    extent = (x0, x0 + size[0], y1 - size[1], y1, z0, z0 + size[2])
    frame = LightFrame(x_axis, y_axis, z_axis, np.zeros(3), up_used="engine_matrix")
    return Projection("ortho", frame, extent, int(resolution), precision)
