"""A camera sequence from a file (``--camera-file cameras.json``), as an engine can dump it.

Format (JSON)::

    {"frames": [
        {"to_world": [[...4...] x4], "fov_x_deg": 60.0},          # Mitsuba camera-to-world
        {"world_to_view": [[...] x4], "fov_y_deg": 40.0},         # OpenGL view matrix
        ...
    ]}

Each frame gives either ``to_world`` (Mitsuba's camera-to-world matrix, column vectors: +Z
forward, +Y up, +X image-left) or ``world_to_view`` (an OpenGL view matrix, column vectors:
+X right, +Y up, the camera looking down -Z, as ``export``'s ``camera.json`` writes it) and a
field of view: ``fov_x_deg`` or ``fov_y_deg`` (perspective; the film's aspect ratio links
them). Near/far planes and the resolution stay the scene's. Frame ``k`` of the sequence is the
file's entry ``k``; frame -1 (the previous frame of frame 0) is entry 0, so frame 0 has no
camera motion; frames past the end are an error.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..camera import Camera

__all__ = ["CameraFileError", "load_camera_file"]


class CameraFileError(ValueError):
    """A camera file that cannot be read (one line naming the file, frame and field)."""


def _matrix(value, where: str) -> np.ndarray:
    m = np.asarray(value, dtype=np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise CameraFileError(f"{where}: expected a finite 4x4 matrix, got shape {m.shape}")
    return m


def _frame_camera(entry: dict, base: Camera, where: str) -> Camera:
    if not isinstance(entry, dict):
        raise CameraFileError(f"{where}: expected an object, got {type(entry).__name__}")
    if "to_world" in entry:
        to_world = _matrix(entry["to_world"], f"{where} to_world")
    elif "world_to_view" in entry:
        view = _matrix(entry["world_to_view"], f"{where} world_to_view")
        frame = np.linalg.inv(view)  # columns: right, up, back (OpenGL), position
        to_world = np.eye(4)
        to_world[:3, 0] = -frame[:3, 0]  # Mitsuba +X is image-left
        to_world[:3, 1] = frame[:3, 1]
        to_world[:3, 2] = -frame[:3, 2]  # forward
        to_world[:3, 3] = frame[:3, 3]
    else:
        raise CameraFileError(f"{where}: needs 'to_world' or 'world_to_view'")
    if base.kind != "perspective":
        return base.with_to_world(to_world)
    if "fov_x_deg" in entry:
        fov_x = float(entry["fov_x_deg"])
    elif "fov_y_deg" in entry:
        t = math.tan(math.radians(float(entry["fov_y_deg"])) / 2) * base.aspect
        fov_x = math.degrees(2 * math.atan(t))
    else:
        raise CameraFileError(f"{where}: needs 'fov_x_deg' or 'fov_y_deg'")
    if not 0.0 < fov_x < 180.0:
        raise CameraFileError(f"{where}: field of view must be in (0, 180) degrees, got {fov_x}")
    return Camera(base.kind, to_world, base.width, base.height, base.near, base.far, fov_x=fov_x)


def load_camera_file(path, base: Camera) -> tuple[Camera, ...]:
    """The cameras of a camera file (see the module docstring), one per frame, with
    ``base``'s kind, resolution and clip planes.

    Raises
    ------
    CameraFileError
        A missing or malformed file, naming the frame and field.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CameraFileError(f"camera file not found: {path}") from None
    except (OSError, ValueError) as exc:
        raise CameraFileError(f"camera file {path}: not readable JSON ({exc})") from None
    frames = data.get("frames") if isinstance(data, dict) else None
    if not isinstance(frames, list) or not frames:
        raise CameraFileError(f"camera file {path}: expected {{'frames': [...]}} with >= 1 frame")
    return tuple(
        _frame_camera(e, base, f"camera file {path} frame {i}") for i, e in enumerate(frames)
    )
