"""Object paths: rigid motions of named shapes from frame to frame.

A built-in scene declares its moving shapes in a top-level ``"ro_motion"`` entry of its
dictionary, ``{shape_id: spec}``; :mod:`scenes.loader` takes it out (after hashing it into
the scene's content hash) and :meth:`scenes.LoadedScene.with_frame` moves the shapes. A
path is defined for every integer frame, frame -1 included, so frame 0 has a previous frame
(and motion vectors) like any other. Specs:

- ``{"path": "slide", "velocity": (vx, vy, vz)}``: translation by ``k * velocity`` (world
  units) at frame ``k``;
- ``{"path": "spin", "pivot": (x, y, z), "axis": (x, y, z), "degrees": d}``: rotation by
  ``k * d`` degrees about the axis through the pivot (right-handed about ``axis``);
- ``{"path": "step", "offset": (x, y, z), "start": k0, "stop": k1}``: translation by ``offset``
  at frames ``k0 <= k < k1``, none at other frames (a shutter closing and opening: a light
  switched off and on, as the receivers see it).

Frame 0 is the shape as the dictionary gives it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["OBJECT_PATHS", "check_motion", "object_transform"]

OBJECT_PATHS = {
    "slide": "translate by `velocity` world units a frame",
    "spin": "rotate by `degrees` a frame about `axis` through `pivot`",
    "step": "translate by `offset` at frames `start` <= k < `stop`",
}

_NEEDS = {
    "slide": ("velocity",),
    "spin": ("pivot", "axis", "degrees"),
    "step": ("offset", "start", "stop"),
}


def check_motion(motion: dict) -> None:
    """Raise ``ValueError`` naming the shape and field of a malformed ``ro_motion`` entry."""
    for name, spec in motion.items():
        path = spec.get("path")
        if path not in OBJECT_PATHS:
            raise ValueError(
                f"object path of shape {name!r}: unknown path {path!r}; "
                f"choose one of {', '.join(OBJECT_PATHS)}"
            )
        for key in _NEEDS[path]:
            if key not in spec:
                raise ValueError(f"object path {path} of shape {name!r} needs {key!r}")


def object_transform(spec: dict, frame: float) -> np.ndarray:
    """``(4, 4)`` float64 world transform of a shape at ``frame`` relative to frame 0
    (column vectors: ``p_k = M @ p_0``)."""
    m = np.eye(4)
    k = float(frame)
    if spec["path"] == "slide":
        m[:3, 3] = k * np.asarray(spec["velocity"], dtype=np.float64)
        return m
    if spec["path"] == "step":
        if float(spec["start"]) <= k < float(spec["stop"]):
            m[:3, 3] = np.asarray(spec["offset"], dtype=np.float64)
        return m
    axis = np.asarray(spec["axis"], dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    pivot = np.asarray(spec["pivot"], dtype=np.float64)
    a = math.radians(k * float(spec["degrees"]))
    kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * (kx @ kx)
    m[:3, :3] = rot
    m[:3, 3] = pivot - rot @ pivot
    return m
