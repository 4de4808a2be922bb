"""ACAA's tie rule and tie groups: which depths can tie in a depth format, which shapes can
never tie with each other, and the Mitsuba scenes of those groups.

Two fragments tie at a sample when their depths store equal values in the prepass's format
(:func:`normalized_depth` quantized); :func:`tie_distance` bounds how far apart along a ray
such points can lie, and :func:`tie_groups` puts shapes whose bounding boxes are never that
close into one group, traced together (:func:`group_scenes`).

Memoized in ``scene.memo`` (:class:`scenes.loaded.LoadedScene`): the group scenes (geometry
only) and the groups of the last camera (they depend on its position and depth range).
"""

from __future__ import annotations

import numpy as np

from ... import depth as _depth

__all__ = [
    "TIE_QUANTA",
    "TIE_SLACK",
    "camera_key",
    "group_scenes",
    "normalized_depth",
    "tie_distance",
    "tie_groups",
]


def normalized_depth(camera, view_depth) -> np.ndarray:
    """D3D-style window depth in [0, 1] of view depths (float64)."""
    z = np.asarray(view_depth, np.float64)
    n, f = camera.near, camera.far
    if camera.kind == "perspective":
        return f / (f - n) * (1.0 - n / np.maximum(z, 1e-300))
    return (z - n) / (f - n)


#: Depth quanta of slack on each side of a tie window (covers rounding and the float32 view
#: depth of the hits; a tie needs the two stored values equal: one quantum apart at most).
TIE_QUANTA = 4.0
#: World-unit slack added to every tie distance (float32 hit positions of the shapes).
TIE_SLACK = 1e-3


def tie_distance(camera, view_depth, fmt: str) -> np.ndarray:
    """Largest distance along a camera ray between two points that can store equal depths
    in ``fmt`` when the farther has view depth at most ``view_depth`` (inf: unbounded).

    :data:`TIE_QUANTA` quanta of normalized depth, as view depth (the inverse of
    :func:`normalized_depth`), over the smallest cosine between a film ray and the view axis.
    """
    z = np.clip(np.asarray(view_depth, np.float64), camera.near, camera.far)
    kind, bits = _depth.FORMATS[fmt]
    q = 1.0 / ((1 << bits) - 1) if kind == "unorm" else 2.0**-23  # float32 ulp below 2
    d = normalized_depth(camera, z) + TIE_QUANTA * q
    n, f = camera.near, camera.far
    if camera.kind == "perspective":
        den = 1.0 - d * (f - n) / f
        far = np.where(den > 0, n / np.where(den > 0, den, 1.0), np.inf)
        t = camera.tan_half_x
        cos_min = 1.0 / np.sqrt(1.0 + t * t + (t / camera.aspect) ** 2)
    else:
        far = n + d * (f - n)
        cos_min = 1.0
    return (far - z) / cos_min + TIE_SLACK


def tie_groups(scene, fmt: str) -> list[list[int]]:
    """Shapes in groups whose members can never tie with each other (memoized per camera).

    Two shapes may tie at a sample only if points of both lie on the sample's ray within
    :func:`tie_distance` of each other, so only if their bounding boxes are that close
    (the distance taken at the larger of the two boxes' farthest view depths). Shapes are
    coloured greedily, in scene order, so that no two close shapes share a group. Within a
    group, the nearest hit on a ray at a tie depth is the hit of the one member that can be
    there: a trace of the group gives every member's tie test of a trace of that member
    alone.
    """
    key = (fmt, camera_key(scene.camera))
    slot = scene.memo.get("acaa.tie_groups")
    if slot is not None and slot[0] == key:
        return slot[1]
    cam = scene.camera
    boxes = [sh.bbox() for sh in scene.mi_scene.shapes()]
    lo = np.array([[float(c) for c in b.min] for b in boxes], np.float64).reshape(-1, 3)
    hi = np.array([[float(c) for c in b.max] for b in boxes], np.float64).reshape(-1, 3)
    corners = np.stack(
        [np.where(np.array(m, bool), hi, lo) for m in np.ndindex(2, 2, 2)], axis=1
    )  # (S, 8, 3)
    zfar = ((corners - cam.position) @ cam.forward).max(axis=1)
    gap = np.sqrt(
        np.sum(
            np.maximum(np.maximum(lo[:, None] - hi[None], lo[None] - hi[:, None]), 0.0) ** 2,
            axis=2,
        )
    )
    close = gap <= tie_distance(cam, np.maximum(zfar[:, None], zfar[None]), fmt)
    groups: list[list[int]] = []
    for k in range(len(boxes)):  # one round per shape (a list-length loop)
        for g in groups:
            if not close[k, g].any():
                g.append(k)
                break
        else:
            groups.append([k])
    scene.memo["acaa.tie_groups"] = (key, groups)
    return groups


def camera_key(camera) -> tuple:
    """A hashable key of everything the tie rule reads from ``camera`` (memo keys)."""
    return (
        camera.kind,
        np.asarray(camera.to_world, np.float64).tobytes(),
        camera.width,
        camera.height,
        camera.near,
        camera.far,
        camera.fov_x,
    )


def group_scenes(scene, groups: list[list[int]]) -> list:
    """One Mitsuba scene per group of ``scene``'s shapes (a group of one: that shape alone),
    memoized in ``scene.memo`` (they depend on the geometry only)."""
    from ....scenes import backend

    mi = backend.mitsuba()
    cache = scene.memo.setdefault("acaa.group_scenes", {})
    shapes = scene.mi_scene.shapes()
    out = []
    for members in groups:  # one scene per group (a list-length loop)
        key = tuple(members)
        if key not in cache:
            if len(members) == 1:
                cache[key] = mi.load_dict({"type": "scene", "shape": shapes[members[0]]})
            else:
                named = {f"shape_{k}": shapes[k] for k in members}
                cache[key] = mi.load_dict({"type": "scene", **named})
        out.append(cache[key])
    return out
