"""IZB grids: one light-space grid of ``R x R`` texels per partition, fit tightly around its
receivers' samples, and the lists of the receivers inserted in them.

Texel ids are global: ``cascade * R^2 + j * R + i`` (:mod:`raster_models.izb.build` for the
texel of a light-frame point). Orthographic grids with 32 samples take their bounds, centre
texels and nodes from :class:`raster_models.izb.build.Ortho32Build` (Dr.Jit kernels: the
grids and the depth cull only need boxes containing each receiver's points); the other grids
(the pixel centres, or a spot light's perspective grid) from the samples themselves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .build import Ortho32Build, grid, texel
from .lists import IzbLists, build_lists, list_nodes
from .samples import Samples

__all__ = ["POINT_CHUNK", "Grids", "build_grids"]

#: Receivers per chunk of a spot light's samples (32 samples each: about 50 MiB of float64
#: coordinates).
POINT_CHUNK = 1 << 16


@dataclass
class Grids:
    """The grids of a frame and their lists.

    Attributes
    ----------
    boxes : per partition, the light-frame box ``(x0, x1, y0, y1)`` of its grid (``x``,
        ``y`` divided by ``z`` for a spot light), or ``None`` for a partition without
        receivers.
    zmax : ``(k,)`` the largest light depth of each grid's samples (``-inf``: no grid).
    lists : the lists of every grid (:class:`raster_models.izb.lists.IzbLists`).
    centre_texel : ``(M,)`` int64 global texel of each receiver's pixel centre.
    """

    boxes: list
    zmax: np.ndarray
    lists: IzbLists
    centre_texel: np.ndarray


def build_grids(smp: Samples, part: np.ndarray, *, cascades: int, resolution: int) -> Grids:
    """Grids and lists of the receivers ``smp`` split into ``cascades`` partitions ``part``,
    ``resolution`` texels per side."""
    k, r, m = cascades, resolution, len(smp.rec)
    ortho32 = smp.samples == 32 and not smp.spot
    build = Ortho32Build(smp.lc, smp.ldx, smp.ldy, smp.a, smp.b) if ortho32 else None
    boxes: list = []
    zmax = np.full(k, -np.inf)
    nodes: list = []
    centre_texel = np.empty(m, dtype=np.int64)
    for c in range(k):  # cascades
        sel = np.flatnonzero(part == c) if k > 1 else np.arange(m)
        if len(sel) == 0:
            boxes.append(None)
            continue
        whole = len(sel) == m  # one grid: no gathers
        if ortho32:
            box, top, centre, grid_nodes = _ortho32_grid(build, None if whole else sel, c, r)
        else:
            box, top, centre, grid_nodes = _sample_grid(smp, sel, whole, c, r)
        boxes.append(box)
        zmax[c] = top
        if whole:
            centre_texel[:] = centre
        else:
            centre_texel[sel] = centre
        nodes += grid_nodes
    return Grids(boxes, zmax, build_lists(nodes), centre_texel)


def _ortho32_grid(build: Ortho32Build, sel, c: int, r: int):
    """Orthographic grid ``c`` of the 32-sample receivers ``sel`` (all: ``None``): box,
    largest depth, global centre texels and nodes."""
    lo, hi = build.bounds(sel)
    box = grid(lo[:2], hi[:2])
    ctex, node_texel, node_recv = build.nodes(sel, box, r)
    nodes = [(c * r * r + node_texel if c else node_texel, node_recv)]
    return box, hi[2], c * r * r + ctex, nodes


def _sample_grid(smp: Samples, sel: np.ndarray, whole: bool, c: int, r: int):
    """Grid ``c`` of the receivers ``sel`` from their samples: the pixel centres of a
    directional light's 1-sample receivers, or a spot light's perspective samples (chunks of
    :data:`POINT_CHUNK` receivers). Box, largest depth, global centre texels and nodes."""
    chunks = [sel[i : i + POINT_CHUNK] for i in range(0, len(sel), POINT_CHUNK)]
    lcs = smp.lc if whole else smp.lc[sel]
    if smp.spot:
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for ch in chunks:  # chunks of receivers
            pts = smp.light_points(ch)
            lo = np.minimum(lo, [v.min() for v in pts])
            hi = np.maximum(hi, [v.max() for v in pts])
    else:
        # one sample: the pixel centres (per column: an axis-0 reduction over (n, 3) is
        # several times slower)
        lo = np.array([lcs[:, q].min() for q in range(3)])
        hi = np.array([lcs[:, q].max() for q in range(3)])
    box = grid(lo[:2], hi[:2])
    cx, cy, cz = lcs[:, 0], lcs[:, 1], lcs[:, 2]
    if smp.spot:
        # the centre may lie outside the cone (32 samples): its texel is diagnostic only
        cz = np.maximum(cz, 1e-300)
        cx, cy = cx / cz, cy / cz
    ci, cj = texel(cx, cy, box, r)
    ctex = c * r * r + cj * r + ci
    if not smp.spot:
        return box, hi[2], ctex, [(ctex, sel)]  # one sample: the pixel centre is the sample
    nodes = []
    for ch in chunks:  # chunks of receivers
        gx, gy, _ = smp.light_points(ch)
        i, j = texel(gx, gy, box, r)
        nodes.append(list_nodes(c * r * r + j * r + i, ch))
    return box, hi[2], ctex, nodes
