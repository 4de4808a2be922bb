"""Motion vectors and disocclusion between a frame and the previous one (temporal truth).

Convention (the reference's ``motion`` group, docs/conventions.md): for a film position
``(x, y)`` of frame ``k`` (pixels, x right, y down, row 0 at the top), the motion vector is
the film position in frame ``k - 1``'s image of the surface point seen through ``(x, y)`` in
frame ``k``, minus ``(x, y)``. The point moves with its shape's object path
(:mod:`scenes.object_paths`) and is projected with frame ``k - 1``'s camera. Where the film
position sees the sky, the "point" is the ray's direction (perspective: its motion is the
camera's rotation alone) or the ray's point on the far plane (orthographic).

The point is *disoccluded* when frame ``k - 1``'s camera did not see it: its previous film
position lies outside the image, behind the camera, or the previous frame's ray through that
position meets a surface nearer than the point (by more than :data:`HIDDEN_REL` of its
distance plus :data:`HIDDEN_ABS`). A sky direction is disoccluded when that ray meets any
surface.
"""

from __future__ import annotations

import numpy as np

from ..backend.raycast import intersect, trace_film

__all__ = ["HIDDEN_ABS", "HIDDEN_REL", "film_motion", "previous_points"]

#: A previous-frame hit nearer than the point by more than this fraction of its distance
#: (plus :data:`HIDDEN_ABS`) hides it: above float32 intersection error (about 1e-6 of the
#: distance), below the nearest distinct layers of the built-in scenes (1e-4 of it).
HIDDEN_REL = 1e-5
HIDDEN_ABS = 1e-6


def previous_points(scene, previous, points: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """World positions ``(N, 3)`` at ``previous``'s frame of the points ``points`` of
    ``scene``'s frame lying on shapes ``shapes`` (index into ``scene.shape_names``, -1 sky):
    moving shapes carry their points along their object paths, others stay."""
    out = np.array(points, dtype=np.float64, copy=True)
    for name in scene.object_motion:
        sel = shapes == scene.shape_names.index(name)
        if not np.any(sel):
            continue
        m = previous.shape_transform(name) @ np.linalg.inv(scene.shape_transform(name))
        out[sel] = out[sel] @ m[:3, :3].T + m[:3, 3]
    return out


def film_motion(
    scene, x: np.ndarray, y: np.ndarray, *, previous=None, disocclusion: bool = True
) -> dict:
    """Motion vectors and disocclusion at film positions ``x``, ``y`` of ``scene``'s frame.

    Parameters
    ----------
    scene : scenes.LoadedScene of frame ``k``.
    x, y : film positions (pixels), any shape (flattened).
    previous : the scene of frame ``k - 1`` (default ``scene.previous()``).
    disocclusion : also trace the previous frame's rays for ``disoccluded`` (else it holds the
        off-screen test alone).

    Returns
    -------
    dict of ``(N,)`` arrays: ``motion_x``, ``motion_y`` (float64 pixels), ``disoccluded``
    (bool), ``valid`` (bool: a surface is seen), ``shape`` (int32), ``position`` ((N, 3)
    float32, world, frame k), ``depth`` (float32 view depth, 0 sky), ``depth_previous``
    (float64 view depth of the point in frame k - 1, inf sky).
    """
    previous = scene.previous() if previous is None else previous
    x = np.asarray(x, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    hit = trace_film(scene, x, y)
    valid = hit["valid"].astype(bool)
    shapes = hit["shape"].astype(np.int32)
    cam, pcam = scene.camera, previous.camera
    o, d, tmax = cam.rays(x, y)
    pts = np.asarray(hit["position"], dtype=np.float64)
    if cam.kind == "perspective":
        # the sky as a direction: a point one unit along the ray from either camera
        sky_now, sky_before = cam.position + d, pcam.position + d
    else:
        sky_now = sky_before = o + d * tmax[:, None]
    now = np.where(valid[:, None], pts, sky_now)
    prev = previous_points(scene, previous, now, np.where(valid, shapes, -1))
    prev = np.where(valid[:, None], prev, sky_before)
    film = pcam.project(prev)
    u, v = film[:, 0], film[:, 1]
    # minus the film position of the same (float32) point in this frame rather than (x, y):
    # the hit's rounding then cancels, and a still scene has exactly zero motion
    here = cam.project(now)
    depth_prev = pcam.view_depth(prev)
    behind = depth_prev <= (pcam.near if pcam.kind == "perspective" else -np.inf)
    outside = behind | ~((u >= 0) & (u < pcam.width) & (v >= 0) & (v < pcam.height))
    hidden = np.zeros_like(valid)
    inside = np.flatnonzero(~outside)
    if inside.size and disocclusion:
        po, pd, ptmax = pcam.rays(u[inside], v[inside])
        back = intersect(previous, po, pd, tmax=ptmax)
        want = np.einsum("ij,ij->i", prev[inside] - po, pd)
        near = back["t"] < want * (1.0 - HIDDEN_REL) - HIDDEN_ABS
        hidden[inside] = np.where(valid[inside], near, back["valid"])
    return {
        "motion_x": u - here[:, 0],
        "motion_y": v - here[:, 1],
        "disoccluded": outside | hidden,
        "valid": valid,
        "shape": shapes,
        "position": hit["position"],
        "depth": hit["depth"],
        "depth_previous": np.where(valid, depth_prev, np.inf),
    }
