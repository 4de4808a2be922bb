"""IZB sample-triangle tests in Dr.Jit kernels: the join of fragments with their lists.

A join takes fragments (triangle, first node, list length) and tests every (triangle,
receiver) pair of their lists: per pair the shadowed flag (1 sample) or the 32-bit mask of
the tangent-plane points inside the triangle's shadow volume (32 samples), and the flag/mask
of the samples in the epsilon band (see :class:`PairTester`: samples whose exact shadow ray,
from the pixel's exact hit, may meet the triangle; those the volume does not shadow are lit
by the epsilon or by the rounding of the G-buffer position), OR-ed into the receivers' state
(an OR is order-free: the same bits however the pairs are split).

Plane values are computed in one fixed order, ``((n0 p0 + n1 p1) + n2 p2) + c`` and
``(base + da a) + db b``, in float64 without fused multiply-adds: every product is rounded
explicitly (:func:`scenes.backend.kernels.product_rounder`), since ``ptxas`` contracts a
multiply and an add on CUDA (IZB on a spot light disagreed with the oracle's centre ray and
tangent-plane reference on an H200, within the float rounding of these planes).
``tests/_izb_reference.py`` holds a NumPy version of the same tests, the reference
``tests/test_izb.py`` compares the kernels with (exactly: masks and flags).

Launches: a join costs a few kernel launches and a synchronisation, whatever its size; the
traversal therefore joins the fragments of many rounds at once
(:class:`raster_models.izb.lists.Joins`), and a join returns the pairs whose receiver it
left fully shadowed (:class:`DeadPairs`), from which the traversal tells the tests made
after a receiver would have left the lists. The receivers' rows are packed once per frame,
in the order of the lists' nodes as built; the lists shortened by the traversal name their
nodes' places in it (``IzbLists.node_id``).

32 samples, two launches per chunk: the first bounds each plane over the pixel's points
(affine in the offsets ``(a, b)``) and decides most pairs (all points outside one plane,
band included: both masks 0; all inside every plane: mask full); the second evaluates the 32
points of the remaining pairs only.

Memory layout (the join is bound by fetching receivers, not by arithmetic): each receiver's
values are one row in arrays of power-of-two widths (``p``, ``dP/dx``, ``dP/dy``, floor,
exact hit and a pad: 8 + 2 + 4 float64; ``p``, floor, exact hit, pad: 4 + 4), rows stored in
the order the pairs read them (list-node order as built), and rows and triangle planes are
fetched as packet loads (``JitFlag.PacketOps``).
The values and the arithmetic are unchanged: the same bits.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np

from ...scenes.backend.kernels import product_rounder
from .geometry import chunks_by_total

__all__ = [
    "BAND_FLOOR",
    "BAND_FLOOR_ON_PLANE",
    "DRJIT_PAIR_CHUNK",
    "FULL_MASK",
    "DeadPairs",
    "PairTester",
    "band_floor",
    "vectorized",
]

#: Distances to a triangle's plane below ``BAND_FLOOR * (1 + max|p|)`` are float32 rounding
#: (a receiver on its own triangle or a coplanar neighbour; the G-buffer position is float32,
#: 2^-24 relative): they do not count in the epsilon band. 2^-18: 64 ulps. The floor of a
#: receiver whose position was not put on its own triangle's plane (a sphere, a cylinder).
BAND_FLOOR = 2.0**-18

#: The floor of a receiver put on its own triangle's plane in float64
#: (:func:`raster_models.izb.geometry.onto_own_planes`): its distance to that plane, and the
#: plane values of the kernels, are float64 rounding (about 2^-50 of ``1 + max|p|``); 2^-40
#: leaves a thousand times that. Any gap above it, at any distance from the origin, is in
#: the band: 1,000 units away, 3.8e-3 with :data:`BAND_FLOOR` (above a 1e-3 epsilon: no band
#: at all) and 9.1e-10 with this one.
BAND_FLOOR_ON_PLANE = 2.0**-40

#: Pairs per Dr.Jit launch (bounded memory: about 40 bytes of inputs and outputs per pair).
DRJIT_PAIR_CHUNK = 1 << 21

#: All 32 bits of an FTIZB mask.
FULL_MASK = np.uint32(0xFFFFFFFF)


def band_floor(p, eps: float, scale=BAND_FLOOR):
    """Lower end of the epsilon band below the pushed plane, per point ``p (P, 3)``:
    ``scale (1 + max|p|) - eps`` (the same operations on NumPy and Dr.Jit columns);
    ``scale``: :data:`BAND_FLOOR` or :data:`BAND_FLOOR_ON_PLANE`, one or per point."""
    if isinstance(p, np.ndarray):
        p, maximum = (p[:, 0], p[:, 1], p[:, 2]), np.maximum
    else:
        import drjit as dr

        maximum = dr.maximum
    big = maximum(maximum(abs(p[0]), abs(p[1])), abs(p[2]))
    return scale * (1.0 + big) - eps


def vectorized() -> bool:
    """Whether the active Mitsuba variant is vectorized (LLVM or CUDA): Dr.Jit kernels run."""
    from ...scenes import backend

    return not backend.active().variant.startswith("scalar")


@dataclass(frozen=True)
class DeadPairs:
    """The pairs of a join whose receiver it left fully shadowed (not fully shadowed before
    it).

    Attributes
    ----------
    frag : ``(P,)`` int64 fragment of each pair (index into the join's fragments).
    recv : ``(P,)`` int64 receiver of each pair.
    result : ``(P,)`` uint32 what the pair's test gave: its mask (32 samples) or its
        shadowed flag, 0 or 1 (1 sample).
    """

    frag: np.ndarray
    recv: np.ndarray
    result: np.ndarray


def _pair(frags, idx, f_idx):
    """Dr.Jit triangle, receiver and built node of pairs ``idx`` of fragments ``f_idx``;
    ``frags``: per fragment triangle, first node and first pair of the chunk, then the
    built node of each node (``None``: the lists as built) and the built nodes' receivers."""
    import drjit as dr

    tri, lo, first, ids, built_recv = frags
    u32 = type(idx)
    node = dr.gather(u32, lo, f_idx) + (idx - dr.gather(u32, first, f_idx))
    if ids is not None:
        node = dr.gather(u32, ids, node)
    return dr.gather(u32, tri, f_idx), dr.gather(u32, built_recv, node), node


class PairTester:
    """Sample-triangle tests of (triangle, receiver) pairs in Dr.Jit kernels.

    Parameters
    ----------
    planes : ``(K, 4, 4)`` float64 shadow-volume planes
        (:func:`raster_models.izb.geometry.shadow_volumes`).
    recv : ``p`` ``(M, 3)``, optionally ``floor_scale`` ``(M,)`` (the ``scale`` of each
        receiver's :func:`band_floor`; :data:`BAND_FLOOR` without it), ``hit`` ``(M, 3)``
        (the pixel's exact hit, :func:`raster_models.izb.geometry.ray_hits`; ``p``
        without it) and, for 32 samples, ``dpdx``, ``dpdy`` ``(M, 3)`` and the tangent-plane
        offsets ``a``, ``b`` ``(32,)``.
    node_recv : ``(N,)`` receiver of each node of the lists as built; a join's lists are
        these nodes or a subset of them (``node_id``, see :meth:`join`).
    epsilon : the shadow volumes' epsilon (world units); each receiver's band floor is
        :func:`band_floor` of its ``p``, computed where needed.

    A sample (``p``, or ``p + a dP/dx + b dP/dy``) is shadowed by a triangle inside every
    edge plane (``>= 0``) and beyond the pushed plane (``> 0``). Its band bit says that an
    exact shadow ray from the same sample of the pixel's exact hit (``hit`` in place of
    ``p``) may meet the triangle: that point inside every edge plane up to the rounding of
    the plane values (``>= -(floor + epsilon)``: the unit-normal edge planes of
    :func:`raster_models.izb.geometry.shadow_volumes` give distances) and beyond the
    triangle's plane by more than that rounding (``> floor``). The output keeps the band
    bits of the samples the model lights: lit by the epsilon (the gap to the occluder below
    it), or by the G-buffer's float32 position lying outside an edge its exact hit is
    inside (a grazing light turns 1e-4 units of rounding 1,000 units out into a 2-cm strip).

    Attributes
    ----------
    keys : the state arrays a join updates: ``("mask", "band")`` (32 samples, uint32) or
        ``("shadowed", "band")`` (1 sample, bool).
    full : the value of ``state[keys[0]]`` of a fully shadowed receiver.
    """

    def __init__(self, planes: np.ndarray, recv: dict, *, node_recv: np.ndarray, epsilon: float):
        self.planes = planes
        self.recv = recv
        self.node_recv = node_recv
        self.epsilon = float(epsilon)
        self.thirty_two = "dpdx" in recv
        self.keys = ("mask", "band") if self.thirty_two else ("shadowed", "band")
        self.full = FULL_MASK if self.thirty_two else 1
        self._dr = None
        self._built = None

    def join(self, frag_tri, lo, n, node_id, state: dict, *, dead: bool) -> DeadPairs | None:
        """Every pair of the fragments ``(frag_tri, lo, n)`` (triangle, first node, list
        length, every length at least 1) with their lists' nodes, tested and OR-ed into
        ``state`` (the arrays :attr:`keys`, updated in place). ``node_id``: the built node
        (index into :attr:`node_recv`) of each node of the lists, or ``None`` for the lists
        as built (the receivers' rows are packed once, in built node order).

        Chunks of at most :data:`DRJIT_PAIR_CHUNK` pairs (a longer list is a chunk of its
        own). Returns, where ``dead``, the pairs whose receiver the join left fully shadowed
        (not fully shadowed before it), found in a second pass over the pairs."""
        mi, _ = self._inputs()
        u32 = mi.UInt32
        nodes = self._nodes(node_id)
        acc = {k: u32(np.asarray(state[k], dtype=np.uint32)) for k in self.keys}
        chunks = list(chunks_by_total(n, DRJIT_PAIR_CHUNK))
        for sl in chunks:  # chunks of fragments
            self._test_chunk(self._chunk(frag_tri[sl], lo[sl], n[sl]), nodes, acc)
        was = (state[self.keys[0]] == self.full) if dead else None
        for k in self.keys:
            out = acc[k].numpy()
            state[k][:] = out.astype(state[k].dtype) if state[k].dtype == bool else out
        if not dead:
            return None
        newly = (state[self.keys[0]] == self.full) & ~was  # by this join, not before it
        found = [(np.zeros(0, dtype=np.int64),) * 2 + (np.zeros(0, dtype=np.uint32),)]
        newly_dr = mi.Bool(newly) if newly.any() else None
        for sl in chunks if newly_dr is not None else ():  # again: the dead receivers' pairs
            frag, recv, result = self._dead_chunk(
                self._chunk(frag_tri[sl], lo[sl], n[sl]), nodes, newly_dr
            )
            found.append((frag + sl.start, recv, result))
        return DeadPairs(*(np.concatenate([x[i] for x in found]) for i in range(3)))

    # ---- inputs
    def _inputs(self):
        if self._dr is None:
            import drjit as dr

            from ...scenes import backend

            mi = backend.mitsuba()
            f64 = mi.Float64
            planes = f64(np.ascontiguousarray(self.planes, dtype=np.float64).ravel())
            # a copy in Dr.Jit's own (aligned) memory: packet loads need it (NumPy-backed
            # arrays are gathered value by value)
            d = {"planes": dr.gather(f64, planes, dr.arange(mi.UInt32, dr.width(planes)))}
            dr.eval(d["planes"])
            keys = ("p", "dpdx", "dpdy") if self.thirty_two else ("p",)
            # NumPy-backed (no copy) sources of the receivers' rows
            keys += ("hit" if "hit" in self.recv else "p",)
            d["sources"] = [
                f64(np.ascontiguousarray(self.recv[k], dtype=np.float64).ravel()) for k in keys
            ]
            scale = self.recv.get("floor_scale")
            d["scale"] = None if scale is None else f64(np.asarray(scale, dtype=np.float64))
            # row arrays of power-of-two widths (packet loads, see _plane_terms): p, dP/dx,
            # dP/dy, the floor, the exact hit and a pad (14 values) as 8 + 2 + 4; p, the
            # floor, the exact hit and a pad as 4 + 4
            d["widths"] = (8, 2, 4) if self.thirty_two else (4, 4)
            d["array"] = importlib.import_module(f64.__module__).ArrayXf64
            self._dr = (mi, d)
        return self._dr

    def _nodes(self, node_id):
        """Dr.Jit ``(ids, built receivers, rows)``: the built node of each node (``None``:
        the lists as built), the built nodes' receivers and their rows (:meth:`_rows`),
        packed once in built node order (a fragment's pairs read consecutive rows; removed
        nodes leave holes)."""
        mi, _ = self._inputs()
        if self._built is None:
            recv_dr = mi.UInt32(np.asarray(self.node_recv, dtype=np.uint32))
            self._built = (recv_dr, self._rows(recv_dr))
        ids = None if node_id is None else mi.UInt32(np.asarray(node_id, dtype=np.uint32))
        return (ids, *self._built)

    def _rows(self, recv) -> list:
        """Row arrays of receivers ``recv`` (Dr.Jit UInt32), one row each: ``p``,
        [``dpdx``, ``dpdy``,] the floor, split into arrays of power-of-two widths; packed by
        a Dr.Jit kernel, so that a pair's receiver is a few packet loads in pair order."""
        import drjit as dr

        mi, d = self._inputs()
        f64 = mi.Float64
        n = dr.width(recv)
        cols = [dr.gather(f64, src, recv * 3 + j) for src in d["sources"] for j in range(3)]
        hit = cols[-3:]
        cols = cols[:-3]
        scale = BAND_FLOOR if d["scale"] is None else dr.gather(f64, d["scale"], recv)
        cols.append(band_floor(cols[:3], self.epsilon, scale))
        cols += [*hit, dr.zeros(f64, n)]
        out, lane = [], dr.arange(mi.UInt32, n)
        for w in d["widths"]:  # packet stores
            arr = dr.empty(f64, n * w)
            dr.scatter(arr, d["array"](cols[:w]), lane)
            out.append(arr)
            cols = cols[w:]
        dr.eval(*out)
        return out

    def _chunk(self, tri, lo, n):
        """A chunk's fragments on Dr.Jit: ``(frags, f, n_pairs)``, ``frags`` as
        :func:`_pair` reads them (the nodes' receivers added by the callers), ``f`` the
        fragment of each of the ``n_pairs`` pairs."""
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        first_np = (np.cumsum(n) - n).astype(np.uint32)
        n_pairs = int(first_np[-1]) + int(n[-1])
        # fragment of each pair: 1 at every later fragment's first pair, summed (lists are
        # never empty: the firsts are distinct)
        marks = dr.zeros(u32, n_pairs)
        if len(n) > 1:
            dr.scatter(marks, u32(1), u32(first_np[1:]))
        f = dr.prefix_sum(marks) + marks  # inclusive
        frags = (u32(tri.astype(np.uint32)), u32(lo.astype(np.uint32)), u32(first_np))
        return frags, f, n_pairs

    # ---- the tests
    def _plane_terms(self, tri, rows, row):
        """Dr.Jit ``base``, ``da``, ``db`` (lists of 4), ``floor`` and ``exact`` (the plane
        values at the exact hit, a list of 4) of pairs: triangles ``tri``, receivers at
        ``row`` of ``rows`` (:meth:`_rows`)."""
        import drjit as dr

        mi, d = self._inputs()
        # Packet gathers (JitFlag.PacketOps): a triangle's 16 plane values and a receiver's
        # row are contiguous, loaded as packets instead of one gather per value.
        pl = dr.gather(d["array"], d["planes"], tri, shape=(16, dr.width(tri)))
        rv = []
        for arr, w in zip(rows, d["widths"], strict=True):  # the row's arrays
            rv += list(dr.gather(d["array"], arr, row, shape=(w, dr.width(row))))
        rows = [[pl[4 * k + j] for j in range(4)] for k in range(4)]
        p = [rv[0], rv[1], rv[2]]
        mul = product_rounder(mi.Float64)

        def dot(n, v):
            return mul(n[0], v[0]) + mul(n[1], v[1]) + mul(n[2], v[2])

        base = [dot(row, p) + row[3] for row in rows]
        floor, hit = rv[-5], rv[-4:-1]
        exact = [dot(row, hit) + row[3] for row in rows]
        if not self.thirty_two:
            return base, None, None, floor, exact
        dx, dy = [rv[3], rv[4], rv[5]], [rv[6], rv[7], rv[8]]
        da = [dot(row, dx) for row in rows]
        db = [dot(row, dy) for row in rows]
        return base, da, db, floor, exact

    def _classes(self, base, da, db, floor, exact):
        """Dr.Jit 32 samples: ``none`` (no point inside, none in the band) and ``full`` (every
        point inside) from bounds of the planes over the pixel's points."""
        import drjit as dr

        mi, _ = self._inputs()
        mul = product_rounder(mi.Float64)
        a, b = self.recv["a"], self.recv["b"]
        amax, bmax = float(np.abs(a).max()), float(np.abs(b).max())
        spread = [mul(dr.abs(da[k]), amax) + mul(dr.abs(db[k]), bmax) for k in range(4)]
        hi = [base[k] + spread[k] for k in range(4)]
        lo = [base[k] - spread[k] for k in range(4)]
        top = [exact[k] + spread[k] for k in range(4)]
        slack = -(floor + self.epsilon)
        none = ((hi[0] < 0) | (hi[1] < 0) | (hi[2] < 0) | (hi[3] <= 0)) & (
            (top[0] < slack) | (top[1] < slack) | (top[2] < slack) | (top[3] <= floor)
        )
        full = (lo[0] >= 0) & (lo[1] >= 0) & (lo[2] >= 0) & (lo[3] > 0)
        return none, full

    def _points(self, base, da, db, floor, exact):
        """Dr.Jit 32 samples, point by point: the mask and the band mask (without the mask)."""
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        mul = product_rounder(mi.Float64)
        a, b = self.recv["a"], self.recv["b"]
        slack = -(floor + self.epsilon)
        m = u32(0)
        bm = u32(0)
        for q in range(32):  # the 32 fixed points (unrolled into the kernel)
            aq, bq = float(a[q]), float(b[q])
            v = [(base[k] + mul(da[k], aq)) + mul(db[k], bq) for k in range(4)]
            w = [(exact[k] + mul(da[k], aq)) + mul(db[k], bq) for k in range(4)]
            edges = (v[0] >= 0) & (v[1] >= 0) & (v[2] >= 0)
            near = (w[0] >= slack) & (w[1] >= slack) & (w[2] >= slack)
            bit = u32(1 << q)
            m = m | dr.select(edges & (v[3] > 0), bit, u32(0))
            bm = bm | dr.select(near & (w[3] > floor), bit, u32(0))
        return m, bm & ~m

    def _single(self, base, floor, exact):
        """Dr.Jit 1 sample: the shadowed flag and the band flag (without the flag)."""
        slack = -(floor + self.epsilon)
        edges = (base[0] >= 0) & (base[1] >= 0) & (base[2] >= 0)
        near = (exact[0] >= slack) & (exact[1] >= slack) & (exact[2] >= slack)
        hit = edges & (base[3] > 0)
        return hit, near & (exact[3] > floor) & ~hit

    def _test_chunk(self, chunk, nodes, acc: dict) -> None:
        """Every pair of a chunk (:meth:`_chunk`) with the lists' ``nodes`` (:meth:`_nodes`)
        tested and OR-ed into ``acc``."""
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        (tri, lo, first), f, n_pairs = chunk
        frags = (tri, lo, first, *nodes[:2])
        ti, ri, node = _pair(frags, dr.arange(u32, n_pairs), f)
        base, da, db, floor, exact = self._plane_terms(ti, nodes[2], node)
        if not self.thirty_two:
            hit, near = self._single(base, floor, exact)
            dr.scatter_reduce(dr.ReduceOp.Or, acc["shadowed"], u32(1), ri, hit)
            dr.scatter_reduce(dr.ReduceOp.Or, acc["band"], u32(1), ri, near)
            dr.eval(acc["shadowed"], acc["band"])
            return
        none, full = self._classes(base, da, db, floor, exact)
        mixed = ~none & ~full
        dr.scatter_reduce(dr.ReduceOp.Or, acc["mask"], u32(FULL_MASK), ri, full & ~none)
        dr.eval(acc["mask"], mixed)
        idx = dr.compress(mixed)
        if dr.width(idx):
            ti, ri, node = _pair(frags, idx, dr.gather(u32, f, idx))
            m, bm = self._points(*self._plane_terms(ti, nodes[2], node))
            dr.scatter_reduce(dr.ReduceOp.Or, acc["mask"], m, ri, m != 0)
            dr.scatter_reduce(dr.ReduceOp.Or, acc["band"], bm, ri, bm != 0)
            dr.eval(acc["mask"], acc["band"])

    def _dead_chunk(self, chunk, nodes, dead):
        """The pairs of a chunk whose receiver is ``dead`` (Dr.Jit Bool per receiver): their
        fragment (index in the chunk), receiver and result (mask or flag, as
        :meth:`_test_chunk` ORs it), as NumPy arrays."""
        import drjit as dr

        mi, _ = self._inputs()
        u32 = mi.UInt32
        (tri, lo, first), f, n_pairs = chunk
        frags = (tri, lo, first, *nodes[:2])
        _, ri, _ = _pair(frags, dr.arange(u32, n_pairs), f)
        idx = dr.compress(dr.gather(mi.Bool, dead, ri))
        if dr.width(idx) == 0:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, np.zeros(0, dtype=np.uint32)
        fi = dr.gather(u32, f, idx)
        ti, ri, node = _pair(frags, idx, fi)
        base, da, db, floor, exact = self._plane_terms(ti, nodes[2], node)
        if self.thirty_two:
            none, full = self._classes(base, da, db, floor, exact)
            m, _ = self._points(base, da, db, floor, exact)
            result = dr.select(none, u32(0), dr.select(full, u32(FULL_MASK), m))
        else:
            hit, _ = self._single(base, floor, exact)
            result = dr.select(hit, u32(1), u32(0))
        dr.eval(fi, ri, result)
        return fi.numpy().astype(np.int64), ri.numpy().astype(np.int64), result.numpy()
