"""Cascaded shadow maps (parallel-split / z-partitioned shadow maps) for directional lights.

The view frustum is cut into ``partitions`` depth slices (uniform, logarithmic, practical
split with ``split_lambda``, or manual). Each slice gets an orthographic map:

- ``fit="corners"``: the AABB of the slice's 8 corners in light space, x/y enlarged about
  the centre by ``(R + K) / R`` for a ``K``-texel filter kernel (MJP), depth range from the
  corners (casters nearer to the light rely on ``depth_clamp``);
- ``fit="stable"``: a cube around the slice's bounding sphere, radius rounded up to 1/16
  (``ceil(16 r) / 16``), fixed up vector, and the light box snapped so that the world
  origin falls on a texel corner (MJP's rounding matrix): the texel grid is fixed in world
  space while the camera translates, so shadows do not shimmer.

A pixel picks its cascade by view depth (``selection="depth"``: MJP's split-depth test; a
pixel past the last split uses the last cascade) or by projection (the first cascade whose
texture contains it). ``blend_band`` blends with the next cascade over that fraction of a
cascade's depth range with a smoothstep (MJP's ``FilterAcrossCascades``, 0.1 there).

References
----------
.. [1] W. Engel, "Cascaded Shadow Maps", ShaderX5, 2006.
.. [2] F. Zhang, H. Sun, L. Xu, L. K. Lun, "Parallel-Split Shadow Maps for Large-scale
   Virtual Environments", VRCIA 2006. DOI: 10.1145/1128923.1128975
.. [3] D. Lloyd, N. Govindaraju, S. Molnar, D. Manocha, "Practical logarithmic rasterization
   for low-error shadow maps", Graphics Hardware 2007.
.. [4] M. Pettineo, "A Sampling of Shadow Techniques", 2013; TheRealMJP/Shadows (code).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from .. import params as _params
from .. import splits as _splits
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..light_frame import Projection
from ..params import param
from .common import CommonParams
from .engine import execute
from .fit import aabb, filter_kernel_texels, light_frame_for
from .frustum import frustum_slice
from .records import Partition, Setup

__all__ = ["LIGHTS", "NAME", "CsmParams", "build", "cascade_projection", "run", "split_depths"]

NAME = "csm"

#: Light kinds the technique supports.
LIGHTS = ("directional",)


@dataclass(frozen=True)
class CsmParams(CommonParams):
    """Parameters of ``csm`` (shared ones in :class:`CommonParams`)."""

    partitions: int = param(
        4,
        source="TheRealMJP/Shadows NumCascades 4; Falcor cascadeCount 4",
        help="number of cascades",
        lo=1,
        hi=8,
    )
    split: str = param(
        "practical",
        source="Falcor PartitionMode PSSM (MJP defaults to manual)",
        help="split scheme: uniform, log, practical (lambda blend of log and uniform), manual",
        choices=("uniform", "log", "practical", "manual"),
    )
    split_lambda: float = param(
        0.5,
        source="Falcor pssmLambda 0.5 (Intel sample 0.8, MJP 1.0, Ogre 0.95)",
        help="practical split weight of the logarithmic scheme",
        lo=0.0,
        hi=1.0,
    )
    splits: tuple = param(
        (0.05, 0.15, 0.5, 1.0),
        source="TheRealMJP/Shadows SplitDistance0..3",
        help="manual: end of each cascade as a fraction of [near, far] (one per cascade)",
        lo=0.0,
        hi=1.0,
    )
    min_distance: float = param(
        0.0,
        source="TheRealMJP/Shadows MinCascadeDistance 0",
        help="start of the first cascade as a fraction of [near, far]",
        lo=0.0,
        hi=1.0,
    )
    max_distance: float = param(
        1.0,
        source="TheRealMJP/Shadows MaxCascadeDistance 1",
        help="end of the last cascade as a fraction of [near, far]",
        lo=0.0,
        hi=1.0,
    )
    fit: str = param(
        "corners",
        source="TheRealMJP/Shadows StabilizeCascades false",
        help="corners: AABB of the slice corners; stable: rounded bounding sphere, "
        "texel-snapped origin, fixed up vector",
        choices=("corners", "stable"),
    )
    selection: str = param(
        "depth",
        source="TheRealMJP/Shadows CascadeSelectionMode SplitDepth",
        help="cascade selection by split depth or by projection (first map containing the pixel)",
        choices=("depth", "projection"),
    )
    blend_band: float = param(
        0.0,
        source="TheRealMJP/Shadows FilterAcrossCascades false (BlendThreshold 0.1 when on)",
        help="fraction of a cascade's depth range blended with the next cascade",
        lo=0.0,
        hi=1.0,
    )
    light_up: str = param(
        "world",
        source="MJP / Falcor LookAt up (0, 1, 0)",
        help="light frame up vector: world (+Y) or camera_right (align to frustum; ignored "
        "with fit=stable, which needs a fixed up vector)",
        choices=("world", "camera_right"),
    )

    def check(self, technique: str) -> None:
        super().check(technique)
        if self.split == "manual":
            if len(self.splits) != self.partitions:
                raise ModelError(
                    f"{technique}: split=manual needs one split per cascade "
                    f"(partitions={self.partitions}), got {len(self.splits)}: "
                    f"{list(self.splits)}"
                )
            if any(b <= a for a, b in pairwise((self.min_distance, *self.splits))):
                raise ModelError(
                    f"{technique}: splits must increase and exceed min_distance="
                    f"{self.min_distance}, got {list(self.splits)}"
                )
        if self.max_distance <= self.min_distance:
            raise ModelError(
                f"{technique}: max_distance must exceed min_distance, got "
                f"{self.max_distance} <= {self.min_distance}"
            )


def split_depths(camera, p: CsmParams) -> np.ndarray:
    """View-depth boundaries ``z_0 .. z_k`` of the cascades."""
    n, f = camera.near, camera.far
    lo = n + p.min_distance * (f - n)
    hi = n + p.max_distance * (f - n)
    k = p.partitions
    if p.split == "uniform":
        return _splits.uniform_splits(lo, hi, k)
    if p.split == "log":
        return _splits.log_splits(lo, hi, k)
    if p.split == "practical":
        return _splits.practical_splits(lo, hi, k, p.split_lambda)
    z = _splits.manual_splits(n, f, p.splits)
    z[0] = lo
    return z


def cascade_projection(scene, p: CsmParams, z_a: float, z_b: float, frame) -> tuple:
    """Orthographic projection of one cascade covering the view-depth slice [z_a, z_b]."""
    cam = scene.camera
    dtype = np.float32 if p.matrix_precision == "float32" else np.float64
    corners = frustum_slice(
        cam, z_a, z_b, precision=p.matrix_precision, inverse=p.view_projection_inverse
    )
    centre = corners.mean(axis=0, dtype=dtype).astype(dtype)
    r = p.resolution
    info: dict = {}
    if p.fit == "stable":
        radius = dtype(np.max(np.linalg.norm(corners - centre, axis=1)))
        radius = dtype(np.ceil(radius * dtype(16)) / dtype(16))
        rot = frame.rotation().astype(dtype)
        c = (rot @ centre).astype(dtype)
        texel = dtype(2) * radius / dtype(r)
        # MJP's rounding matrix: the world origin (light-frame 0) must land on a texel corner.
        x0 = c[0] - radius
        y1 = c[1] + radius
        origin_texels_x = (dtype(0) - x0) / texel
        origin_texels_y = (y1 - dtype(0)) / texel
        x0 = x0 - (np.round(origin_texels_x) - origin_texels_x) * texel
        y1 = y1 + (np.round(origin_texels_y) - origin_texels_y) * texel
        extent = (
            float(x0),
            float(x0 + dtype(2) * radius),
            float(y1 - dtype(2) * radius),
            float(y1),
            float(c[2] - radius),
            float(c[2] + radius),
        )
        info.update(sphere_centre=centre.astype(np.float64).tolist(), sphere_radius=float(radius))
    else:
        bmin, bmax = aabb(frame, corners.astype(np.float64))
        k = filter_kernel_texels(p)
        mid = 0.5 * (bmin + bmax)
        half = 0.5 * (bmax - bmin)
        half[:2] *= (r + k) / r
        extent = (
            mid[0] - half[0],
            mid[0] + half[0],
            mid[1] - half[1],
            mid[1] + half[1],
            bmin[2],
            bmax[2],
        )
    return Projection("ortho", frame, extent, r, p.matrix_precision), info


def build(scene, gbuf, p: CsmParams) -> Setup:
    """One orthographic map per cascade."""
    light = scene.light
    if light.kind not in LIGHTS:
        raise ModelError(
            f"{NAME} needs a directional light; the scene's light is a {light.kind} light "
            "(use shadow-map)"
        )
    cam = scene.camera
    z = split_depths(cam, p)
    # Stable cascades need a fixed up vector: a camera-aligned frame would rotate the texel
    # grid with the camera (MJP uses world up; the Intel sample drops alignment likewise).
    frame = light_frame_for(light, cam, "world" if p.fit == "stable" else p.light_up)
    parts = []
    for i in range(p.partitions):
        proj, info = cascade_projection(scene, p, float(z[i]), float(z[i + 1]), frame)
        parts.append(Partition(proj, float(z[i]), float(z[i + 1]), info))
    diag = {
        "split": p.split,
        "split_lambda": p.split_lambda,
        "light": light.to_json(),
        "light_up_used": frame.up_used,
    }
    return Setup(
        parts,
        selection=p.selection,
        outside="clamp",
        blend_band=p.blend_band,
        diagnostics=diag,
    )


def run(scene, params: CsmParams | None = None, **kwargs):
    """Run ``csm`` on a loaded scene; see :func:`raster_models.run`."""
    t0 = time.perf_counter()
    p = params or _params.make(NAME, CsmParams, kwargs)
    gbuf = trace_gbuffer(scene)
    setup = build(scene, gbuf, p)
    return execute(NAME, scene, gbuf, setup, p, _params.as_dict(p), t0)
