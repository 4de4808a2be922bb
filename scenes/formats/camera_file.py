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

The file is untrusted (:mod:`scenes.base.untrusted`): a regular file of at most 64 MiB of
strict JSON (no NaN), at most :data:`MAX_FRAMES` frames; a matrix is 4 rows of 4 JSON
numbers of magnitude at most :data:`MAX_ENTRY`, its last row ``0 0 0 1``, its 3x3 part of
full rank (singular values within :data:`MAX_CONDITION` of each other); a field of view a
number in (0, 180) degrees. Anything else: one line naming the file, frame and field.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..base.untrusted import read_json
from ..camera import Camera

__all__ = ["MAX_CONDITION", "MAX_ENTRY", "MAX_FRAMES", "CameraFileError", "load_camera_file"]

#: Most frames of a camera file.
MAX_FRAMES = 100_000
#: Largest magnitude of a matrix entry (world units; a camera 1e8 units out is nonsense).
MAX_ENTRY = 1e8
#: Largest ratio of the 3x3 part's largest to smallest singular value.
MAX_CONDITION = 1e6


class CameraFileError(ValueError):
    """A camera file that cannot be read (one line naming the file, frame and field)."""


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _matrix(value, where: str) -> np.ndarray:
    """A 4x4 list of JSON numbers: finite, bounded, an affine transform of full rank."""
    rows = value if isinstance(value, list) else None
    if rows is None or len(rows) != 4 or not all(isinstance(r, list) and len(r) == 4 for r in rows):
        raise CameraFileError(f"{where}: expected a 4x4 matrix (4 lists of 4 numbers)")
    if not all(_is_number(v) for r in rows for v in r):
        raise CameraFileError(f"{where}: every entry must be a number")
    m = np.array(rows, dtype=np.float64)
    if not np.isfinite(m).all() or np.abs(m).max() > MAX_ENTRY:
        raise CameraFileError(f"{where}: entries must be finite, at most {MAX_ENTRY:g} in size")
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise CameraFileError(f"{where}: the last row must be 0 0 0 1 (an affine transform)")
    sv = np.linalg.svd(m[:3, :3], compute_uv=False)
    if not sv[-1] > 0 or sv[0] / sv[-1] > MAX_CONDITION:
        raise CameraFileError(f"{where}: the 3x3 part is singular or nearly (rank < 3)")
    return m


def _fov(entry: dict, key: str, where: str) -> float:
    value = entry[key]
    if not _is_number(value) or not 0.0 < value < 180.0:
        raise CameraFileError(f"{where} {key}: expected a number in (0, 180), got {value!r}")
    return float(value)


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
        fov_x = _fov(entry, "fov_x_deg", where)
    elif "fov_y_deg" in entry:
        t = math.tan(math.radians(_fov(entry, "fov_y_deg", where)) / 2) * base.aspect
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
    if not path.exists():
        raise CameraFileError(f"camera file not found: {path}")
    data = read_json(path, what="camera file", error=CameraFileError)
    frames = data.get("frames") if isinstance(data, dict) else None
    if not isinstance(frames, list) or not frames:
        raise CameraFileError(f"camera file {path}: expected {{'frames': [...]}} with >= 1 frame")
    if len(frames) > MAX_FRAMES:
        raise CameraFileError(
            f"camera file {path}: {len(frames)} frames (the limit is {MAX_FRAMES})"
        )
    return tuple(
        _frame_camera(e, base, f"camera file {path} frame {i}") for i, e in enumerate(frames)
    )
