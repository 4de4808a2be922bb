"""IZB samples: the receivers of a frame, their samples in the light frame, and the view-depth
partitions of cascaded IZB.

A receiver is a G-buffer pixel a light reaches: valid and N.L > 0 (``gbuf.receiver``), or,
under a spot light with 32 samples, a valid pixel with at least one of its 32 tangent-plane
points facing the light inside the cone (each point's N.L and cone test are its own, as in
the oracle's tangent-plane reference). Its samples are the pixel centre (1 sample) or the
32 points ``P + a dP/dx + b dP/dy`` (:data:`scenes.geometry.tangent32.TANGENT_POINTS_32`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scenes.geometry.tangent32 import tangent_offsets
from .. import splits as _splits
from .lists import FULL_MASK

__all__ = ["UNLIT_CHUNK", "Samples", "frame_samples", "partitions", "unlit_bits"]

#: Pixels per chunk of the spot light's per-point N.L and cone tests (32 points, a few
#: (n, 32, 3) temporaries: small chunks stay in cache, about 1.5x faster than 2^16).
UNLIT_CHUNK = 1 << 10


@dataclass
class Samples:
    """The receivers of a frame and their samples.

    Attributes
    ----------
    rec : ``(M,)`` pixel index of each receiver (into the flattened G-buffer).
    init : ``(M,)`` uint32 bits of the points no light reaches before any occluder (spot
        light, 32 samples; 0 otherwise).
    lc : ``(M, 3)`` float64 light-frame position of each receiver's pixel centre.
    ldx, ldy : ``(M, 3)`` light-frame ``dP/dx``, ``dP/dy`` (32 samples; ``None`` for 1).
    a, b : ``(32,)`` tangent-plane offsets (pixels).
    recv : world-space ``p`` ``(M, 3)`` and, for 32 samples, ``dpdx``, ``dpdy``, ``a``,
        ``b``: what :class:`raster_models.izb.kernel.PairTester` tests.
    samples : 1 or 32.
    spot : perspective grids (a spot light at the frame's origin).
    """

    rec: np.ndarray
    init: np.ndarray
    lc: np.ndarray
    ldx: np.ndarray | None
    ldy: np.ndarray | None
    a: np.ndarray
    b: np.ndarray
    recv: dict
    samples: int
    spot: bool

    def light_points(self, sel: np.ndarray):
        """Grid x, y and light depth z ``(n, S)`` of the samples of receivers ``sel``:
        light-frame x, y (orthographic) or x / z, y / z (perspective). A spot light's
        samples that no light reaches (set in ``init``: outside the cone, possibly behind
        the light) take the place of the receiver's first lit sample: never tested, they
        must not stretch the grid or reach a texel of their own."""
        lc, a, b = self.lc, self.a, self.b
        if self.samples == 1:
            x, y, z = lc[sel, 0, None], lc[sel, 1, None], lc[sel, 2, None]
        else:
            ldx, ldy = self.ldx, self.ldy
            x, y, z = (
                lc[sel, q, None] + ldx[sel, q, None] * a + ldy[sel, q, None] * b for q in range(3)
            )
        if not self.spot:
            return x, y, z
        if self.samples == 32:
            ok = ((self.init[sel, None] >> np.arange(32, dtype=np.uint32)) & 1) == 0
            first = np.argmax(ok, axis=1)[:, None]
            x, y, z = (np.where(ok, v, np.take_along_axis(v, first, axis=1)) for v in (x, y, z))
        return x / z, y / z, z


def unlit_bits(light, gbuf, cand: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Spot light, 32 samples: per pixel of ``cand``, the bits of the points that face away
    from the light (N.L <= 0 with the pixel's normal) or lie outside the cone: unlit before
    any occluder, as in the oracle's tangent-plane reference."""
    out = np.empty(len(cand), dtype=np.uint32)
    pos = np.asarray(light.position, dtype=np.float64)
    axis = np.asarray(light.direction, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    cos_cut = np.cos(np.radians(light.cutoff_angle))
    bits = np.left_shift(np.uint64(1), np.arange(32, dtype=np.uint64))
    for i0 in range(0, len(cand), UNLIT_CHUNK):  # chunks of pixels
        ch = cand[i0 : i0 + UNLIT_CHUNK]
        q = (
            gbuf.position[ch, None, :]
            + gbuf.dpdx[ch, None, :] * a[:, None]
            + gbuf.dpdy[ch, None, :] * b[:, None]
        )
        wl = pos - q
        wl /= np.linalg.norm(wl, axis=-1, keepdims=True)
        ok = (np.einsum("nkj,nj->nk", wl, gbuf.normal[ch]) > 0) & (-(wl @ axis) > cos_cut)
        out[i0 : i0 + len(ch)] = ((~ok).astype(np.uint64) @ bits).astype(np.uint32)
    return out


def frame_samples(
    gbuf, light, frame, *, samples: int, position=None, floor_scale=None, hit=None
) -> Samples:
    """The receivers of G-buffer ``gbuf`` under ``light`` and their samples in light frame
    ``frame`` (``samples``: 1 or 32). ``position`` ``(N, 3)``: the pixels' positions to use
    instead of ``gbuf.position`` (on their own triangles' planes), with ``floor_scale``
    ``(N,)`` the band floor's scale of each and ``hit`` ``(N, 3)`` the pixels' exact hits,
    where the band is judged (see :class:`raster_models.izb.kernel.PairTester`)."""
    spot = light.kind == "spot"
    a, b = tangent_offsets()
    if spot and samples == 32:
        cand = np.flatnonzero(gbuf.valid)
        unlit = unlit_bits(light, gbuf, cand, a, b)
        rec, init = cand[unlit != FULL_MASK], unlit[unlit != FULL_MASK]
    else:
        rec = np.flatnonzero(gbuf.receiver)
        init = np.zeros(len(rec), dtype=np.uint32)
    rot = frame.rotation()
    # np.take: the same rows as fancy indexing, about twice as fast on (N, 3)
    pos = np.take(gbuf.position if position is None else position, rec, axis=0)
    # a directional light's frame has its origin at 0: p - 0 is p, no temporary needed
    lc = frame.to_light(pos) if frame.origin.any() else pos @ rot.T
    recv = {"p": pos}
    if floor_scale is not None:
        recv["floor_scale"] = np.take(floor_scale, rec)
    if hit is not None:
        recv["hit"] = np.take(hit, rec, axis=0)
    ldx = ldy = None
    if samples == 32:
        recv.update(dpdx=np.take(gbuf.dpdx, rec, axis=0), dpdy=np.take(gbuf.dpdy, rec, axis=0))
        recv.update(a=a, b=b)
        ldx, ldy = recv["dpdx"] @ rot.T, recv["dpdy"] @ rot.T
    return Samples(rec, init, lc, ldx, ldy, a, b, recv, samples, spot)


def partitions(depth: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """SDSM log partitioning of the receivers' view depths ``depth`` (camera units) into
    ``k`` partitions over ``[min, max]``: the ``k + 1`` split depths and each receiver's
    partition (all 0 for one grid; zeros when there is no receiver)."""
    m = len(depth)
    if not m:
        return np.zeros(k + 1), np.zeros(0, dtype=np.int64)
    splits = _splits.log_splits(float(depth.min()), float(depth.max()), k)
    if k > 1:
        part = np.searchsorted(splits[1:-1], depth, side="right")
    else:  # one grid: every receiver in partition 0
        part = np.zeros(m, dtype=np.intp)
    return splits, part
