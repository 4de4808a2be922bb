"""Standard shadow mapping: one map (six for a point light), depth compare at each pixel.

- Directional light: an orthographic map fit to the scene's bounds (``fit="scene"``) or to
  the AABB of the whole view frustum in light space (``fit="frustum"``).
- Spot light: a perspective map on the light's axis covering its cutoff cone.
- Rectangle or disk area light (its punctual proxy is a point light): one perspective map
  along the light's normal, its field of view fit to the visible points in front of it, as
  an engine shadows a one-sided area light (a cube would put flat ground at grazing angles
  in its side faces); a sphere light is shadowed as its point proxy.
- Point light: six 90-degree perspective cube faces; a pixel uses the face of the major axis
  of its direction from the light (normal offset included). Not seamless: filter taps near
  a face edge clamp to that face's edge texels (``address_mode``) instead of reading the
  neighbouring face, as D3D10+/GL seamless cube filtering would; the difference is
  confined to a filter width at the seams.
- Spot and point maps bias in linear light depth (``perspective_bias`` texel footprints at
  the receiver) and offset along the normal (``perspective_normal_offset``), after Unity
  URP's texel-scaled depth and normal bias; the constant ``bias`` on hyperbolic depth with
  the near plane at far/1000 (the fallback near when the light is inside the scene bounds)
  would erase every spot shadow (``perspective_bias=0`` reproduces that configuration).

References
----------
.. [1] L. Williams, "Casting curved shadows on curved surfaces", SIGGRAPH 1978.
   DOI: 10.1145/965139.807402
.. [2] D. Scherzer, M. Wimmer, W. Purgathofer, "A Survey of Real-Time Hard Shadow Mapping
   Methods", Computer Graphics Forum 30(1), 2011. DOI: 10.1111/j.1467-8659.2010.01841.x
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from ..gbuffer import trace_gbuffer
from ..light_frame import Projection, make_frame
from ..params import param
from .common import CommonParams
from .engine import execute
from .fit import box_corners, filter_kernel_texels, light_box, light_frame_for
from .records import Partition, Setup

__all__ = ["LIGHTS", "NAME", "ShadowMapParams", "build", "build_area", "run"]

NAME = "shadow-map"

#: Light kinds the technique supports.
LIGHTS = ("directional", "spot", "point")

#: Relative margin added around fitted boxes so that geometry on the boundary stays inside.
BOX_MARGIN = 1e-4

#: Cube faces: (travel direction of the face, up hint).
CUBE_FACES = (
    ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
)


@dataclass(frozen=True)
class ShadowMapParams(CommonParams):
    """Parameters of ``shadow-map`` (shared ones in :class:`CommonParams`)."""

    fit: str = param(
        "scene",
        source="raster-oracle default (Falcor's single cascade fits the frustum's sphere)",
        help="directional lights: fit the map to the scene bounds or to the view frustum",
        choices=("scene", "frustum"),
    )
    light_up: str = param(
        "world",
        source="MJP / Falcor LookAt up (0, 1, 0)",
        help="light frame up vector: world (+Y) or camera_right (Intel's align to frustum)",
        choices=("world", "camera_right"),
    )
    perspective_bias: float = param(
        1.0,
        source="Unity URP ShadowUtils.GetShadowBias: depth bias 1 shadow texel in world units "
        "(URP light default Depth Bias 1); here per receiver, at its own distance",
        help="spot/point maps: receiver-side bias in linear light-view depth of this many "
        "texel footprints at the receiver (2 tan(fov/2) tau / R), replacing 'bias'; 0 = the "
        "constant 'bias' on hyperbolic depth (a GL/D3D default that erases spot shadows "
        "when near = far/1000)",
        lo=0.0,
        hi=1e3,
    )
    perspective_normal_offset: float = param(
        1.0,
        source="Unity URP ShadowUtils.GetShadowBias / ApplyShadowBias: normal bias 1 shadow "
        "texel, scaled by 1 - N.L (URP light default Normal Bias 1)",
        help="spot/point maps: normal offset in texel footprints at the receiver, times "
        "saturate(1 - N.L) (replaces normal_offset, which applies to orthographic maps)",
        lo=0.0,
        hi=1e3,
    )
    light_near: float = param(
        0.0,
        source="Falcor createShadowMatrix: near = max(d - r, ...) of the scene's sphere",
        help="near plane of spot/point maps in scene units (0 = from the scene bounds)",
        lo=0.0,
    )


def _perspective_range(scene, position, forward, light_near: float):
    """Near/far of a perspective map at ``position`` covering the scene bounds."""
    lo, hi = scene.bounds()
    corners = box_corners(lo, hi)
    if forward is None:
        far = float(np.max(np.linalg.norm(corners - position, axis=1)))
    else:
        far = float(np.max((corners - position) @ forward))
    far = max(far, 1e-6) * (1.0 + BOX_MARGIN)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    near = (
        light_near
        if light_near > 0
        else max(float(np.linalg.norm(centre - position)) - radius, 1e-3 * far)
    )
    return min(near, 0.5 * far), far


#: Widest half-angle of an area light's map: tan(80 degrees).
MAX_TAN_HALF = math.tan(math.radians(80.0))


def build_area(scene, gbuf, p: ShadowMapParams) -> Setup | None:
    """One perspective map along a rectangle or disk light's normal (as an engine shadows a
    one-sided area light), its field of view fit to the G-buffer's points in front of the
    light (half-angle at most 80 degrees); ``None`` for other lights (a sphere light is its
    point proxy: a cube)."""
    light = scene.light
    if getattr(light, "area", "") not in ("rectangle", "disk"):
        return None
    tangent, _, normal = light.frame
    origin = np.asarray(light.position, dtype=np.float64)
    frame = make_frame(normal, [("light_tangent", tangent)], origin)
    d = gbuf.position[gbuf.valid] - origin
    depth = d @ frame.z
    front = depth > 1e-9
    lateral = np.maximum(np.abs(d[front] @ frame.x), np.abs(d[front] @ frame.y))
    tan_half = float(np.max(lateral / depth[front])) * 1.01 if front.any() else 1.0
    tan_half = min(max(tan_half, 1e-3), MAX_TAN_HALF)
    lo, hi = scene.bounds()
    corners = box_corners(lo, hi)
    far = max(float(np.max((corners - origin) @ frame.z)), 1e-6) * (1.0 + 1e-4)
    near = p.light_near if p.light_near > 0 else 1e-3 * far
    proj = Projection("persp", frame, (tan_half, near, far), p.resolution, p.matrix_precision)
    diag = {"light": light.to_json(), "area_map": {"tan_half": tan_half, "near": near}}
    return Setup([Partition(proj)], selection="single", diagnostics=diag)


def build(scene, gbuf, p: ShadowMapParams) -> Setup:
    """Partitions (one map, or six cube faces) for the scene's light; one map along a
    rectangle or disk area light's normal (:func:`build_area`)."""
    area = build_area(scene, gbuf, p)
    if area is not None:
        return area
    light = scene.light
    cam = scene.camera
    diag: dict = {"light": light.to_json()}
    if light.kind == "directional":
        frame = light_frame_for(light, cam, p.light_up)
        bmin, bmax = light_box(
            frame,
            scene,
            cam,
            whole_scene=p.fit == "scene",
            precision=p.matrix_precision,
            inverse=p.view_projection_inverse,
        )
        size = bmax - bmin
        pad = BOX_MARGIN * np.maximum(size, 1e-9)
        if p.fit == "frustum":
            # MJP's margin for the filter kernel: scale x/y about the centre by (R + K) / R.
            k = filter_kernel_texels(p)
            centre = 0.5 * (bmin + bmax)
            half = 0.5 * size * (p.resolution + k) / p.resolution
            bmin[:2], bmax[:2] = centre[:2] - half[:2], centre[:2] + half[:2]
        extent = (
            bmin[0] - pad[0],
            bmax[0] + pad[0],
            bmin[1] - pad[1],
            bmax[1] + pad[1],
            bmin[2] - pad[2],
            bmax[2] + pad[2],
        )
        proj = Projection("ortho", frame, extent, p.resolution, p.matrix_precision)
        diag["fit"] = p.fit
        return Setup([Partition(proj)], selection="single", diagnostics=diag)
    position = np.asarray(light.position, dtype=np.float64)
    if light.kind == "spot":
        forward = np.asarray(light.direction, dtype=np.float64)
        frame = make_frame(forward, [("world_y", (0.0, 1.0, 0.0))], position)
        near, far = _perspective_range(scene, position, frame.z, p.light_near)
        tan_half = math.tan(math.radians(light.cutoff_angle))
        proj = Projection("persp", frame, (tan_half, near, far), p.resolution, p.matrix_precision)
        return Setup([Partition(proj)], selection="single", diagnostics=diag)
    near, far = _perspective_range(scene, position, None, p.light_near)
    parts = []
    for face, (fwd, up) in enumerate(CUBE_FACES):
        frame = make_frame(fwd, [("cube", up)], position)
        proj = Projection("persp", frame, (1.0, near, far), p.resolution, p.matrix_precision)
        parts.append(Partition(proj, info={"face": ["+x", "-x", "+y", "-y", "+z", "-z"][face]}))
    return Setup(parts, selection="cube", diagnostics=diag)


def run(scene, params: ShadowMapParams | None = None, **kwargs):
    """Run ``shadow-map`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, ShadowMapParams, kwargs)
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, p)
    return execute(NAME, scene, gbuf, setup, p, _params.as_dict(p), t0)
