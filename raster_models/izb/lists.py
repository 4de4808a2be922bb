"""IZB lists and traversal: the grid of per-texel sample lists, built by sorting, and the join
of conservative fragments with those lists, chunk by chunk.

A GPU IZB keeps a head pointer per texel and a next pointer per node; here the lists are the
nodes sorted by texel (``node_texel`` increasing, ties in insertion order), a list being the
run of one texel: the same lists in the same order. A fragment ``(triangle, texel)`` walks
its texel's list and tests each node's sample(s) against the triangle's shadow volume
(:func:`raster_models.izb.geometry.shadow_volumes`). Fully shadowed receivers are removed
from the lists after each round of triangles (the seed's "remove fully shadowed pixels",
which gradually shortens the lists over the frame).

One sample per pixel: a node is a receiver's G-buffer point. 32 samples (FTIZB): a node is a
receiver inserted once in each texel that at least one of its 32 tangent-plane points falls
in (duplicates removed, "avoid duplicate nodes"); a node's test is one frustum-triangle test
covering the 32 points and yields a 32-bit mask, OR-ed into the receiver's mask. Inserting
into the texels of the points is exact for those points (a triangle can shadow a point only
if it touches the point's texel).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import chunks_by_total
from .kernel import PairTester, use_drjit

__all__ = [
    "FULL_MASK",
    "PAIR_CHUNK",
    "IzbLists",
    "JoinStats",
    "build_lists",
    "head_offsets",
    "join",
    "list_nodes",
]

#: (fragment, node) pairs tested per chunk: bounds memory at about 250 MiB for 32 samples
#: ((pairs, 4, 32) float64 working arrays are only made for pairs that straddle a plane).
PAIR_CHUNK = 1 << 18

#: All 32 bits of an FTIZB mask.
FULL_MASK = np.uint32(0xFFFFFFFF)


@dataclass
class IzbLists:
    """Grid-of-lists: ``node_texel`` (sorted, global texel id = cascade * R^2 + j * R + i)
    and ``node_recv`` (receiver index) per node (int32 where the ids fit); ``heads``: the
    head offsets of :func:`head_offsets` for these nodes, or ``None`` until :meth:`span`
    needs them (reset by :meth:`compact`)."""

    node_texel: np.ndarray
    node_recv: np.ndarray
    heads: np.ndarray | None = field(default=None, repr=False)

    def lengths(self) -> np.ndarray:
        """Lengths of the non-empty lists."""
        if len(self.node_texel) == 0:
            return np.zeros(0, dtype=np.int64)
        edges = np.flatnonzero(np.diff(self.node_texel)) + 1
        bounds = np.concatenate([[0], edges, [len(self.node_texel)]])
        return np.diff(bounds)

    def length_at(self, texels: np.ndarray) -> np.ndarray:
        """List length of each of ``texels``."""
        return self.span(texels)[1]

    def span(self, texels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First node and length of the list of each of ``texels`` (head offsets: a counting
        sort of the nodes by texel, computed once per list state)."""
        heads = self.heads
        if heads is None:
            count = np.bincount(self.node_texel) if len(self.node_texel) else np.zeros(0, int)
            heads = self.heads = head_offsets(count)
        t = np.minimum(texels, len(heads) - 2)
        lo = heads[t]
        return lo, heads[t + 1] - lo

    def compact(self, dead: np.ndarray) -> int:
        """Remove the nodes of ``dead`` receivers; returns how many nodes were removed."""
        keep = ~dead[self.node_recv]
        removed = int(len(keep) - keep.sum())
        if removed:
            self.node_texel = self.node_texel[keep]
            self.node_recv = self.node_recv[keep]
            self.heads = None
        return removed


def list_nodes(texels: np.ndarray, recv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ``(texel, receiver)`` of receivers ``recv`` whose samples fall in ``texels``
    ``(n, S)`` (int64 global texel ids): one node per distinct texel of a row."""
    if texels.shape[1] == 1:
        return texels[:, 0], recv
    srt = np.sort(texels, axis=1)
    first = np.ones_like(srt, dtype=bool)
    first[:, 1:] = srt[:, 1:] != srt[:, :-1]
    return srt[first], np.repeat(recv, first.sum(axis=1))


def build_lists(parts: list[tuple[np.ndarray, np.ndarray]]) -> IzbLists:
    """Lists from the nodes of :func:`list_nodes` (any number of parts).

    Nodes are sorted by texel, ties in insertion order (the parts in order: deterministic, as
    a GPU's lists would be for a fixed insertion order): a stable LSD radix sort on 16-bit
    digits of the texel id, 8 bits for a short top digit (NumPy's stable sort of 8- and
    16-bit keys is a counting sort).
    """
    if not parts:
        return IzbLists(np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    if len(parts) == 1:  # one grid: no copy
        node_texel, node_recv = parts[0]
    else:
        node_texel = np.concatenate([t for t, _ in parts])
        node_recv = np.concatenate([r for _, r in parts])
    node_texel = node_texel.astype(_index_type(node_texel), copy=False)
    node_recv = node_recv.astype(_index_type(node_recv), copy=False)
    if len(node_recv) == 0:
        return IzbLists(node_texel, node_recv)
    order = np.argsort((node_texel & 0xFFFF).astype(np.uint16), kind="stable")
    top, shift = int(node_texel.max()), 16
    while top >> shift:  # the higher digits of the texel id (8 bits where they suffice)
        bits = 8 if top >> shift < 256 else 16
        digit = (node_texel[order] >> shift) & ((1 << bits) - 1)
        order = order[np.argsort(digit.astype(np.uint8 if bits == 8 else np.uint16), kind="stable")]
        shift += bits
    # the sorted texel ids are runs of each id: from the counts, which give the heads too
    count = np.bincount(node_texel)
    node_texel = np.repeat(np.arange(top + 1, dtype=node_texel.dtype), count)
    return IzbLists(node_texel, node_recv[order], head_offsets(count))


def head_offsets(count: np.ndarray) -> np.ndarray:
    """Head offsets ``(len(count) + 2,)`` of lists of ``count`` nodes per texel (the last
    entry repeated: a texel past the end has an empty list)."""
    heads = np.zeros(len(count) + 2, dtype=np.int64)
    np.cumsum(count, out=heads[1:-1])
    heads[-1] = heads[-2]
    return heads


def _index_type(ids: np.ndarray):
    """int32 for non-negative ids below 2^31 (half the memory traffic), else int64."""
    return np.int32 if len(ids) == 0 or int(ids.max()) < 2**31 else np.int64


@dataclass
class JoinStats:
    """Counters of the traversal: fragments, tests, list lengths seen by fragments."""

    fragments: int = 0
    fragments_with_list: int = 0
    tests: int = 0
    list_max: int = 0
    nodes_removed: int = 0


def _pairs(lo: np.ndarray, n: np.ndarray):
    """Node index of every (fragment, node) pair: ``lo[f] + 0 .. n[f] - 1``."""
    first = np.cumsum(n) - n
    f = np.repeat(np.arange(len(n)), n)
    return f, lo[f] + (np.arange(len(f)) - first[f])


def join(
    lists: IzbLists,
    frag_tri: np.ndarray,
    frag_texel: np.ndarray,
    tester: PairTester,
    state: dict,
    stats: JoinStats,
) -> None:
    """Test every node of every fragment's list against the fragment's triangle.

    ``tester``: the sample-triangle tests of the frame (its shadow volumes, receivers and
    epsilon). ``state``: ``shadowed`` ``(M,)`` bool (1 sample) or ``mask`` ``(M,)`` uint32
    (32 samples), and ``band`` (same type: samples inside a volume's edge planes within
    ``epsilon`` of its triangle plane, lit by the epsilon), updated in place.

    Large joins run on Dr.Jit (:meth:`raster_models.izb.kernel.PairTester.join_drjit`:
    pairs expanded, tested and OR-ed in the kernels), and so do small ones once a Dr.Jit
    join has packed the rows of the same lists; other small ones on NumPy
    (:meth:`~raster_models.izb.kernel.PairTester.numpy`, the same bits), in chunks of at
    most :data:`PAIR_CHUNK` pairs (a fragment with a longer list is a chunk of its own): a
    frame's many joins of a few hundred pairs cost a kernel launch and a synchronisation
    each on Dr.Jit, about twice the NumPy time on ``curved`` (measured at 320x180).
    """
    stats.fragments += len(frag_tri)
    if len(frag_tri) == 0 or len(lists.node_texel) == 0:
        return
    lo, n = lists.span(frag_texel)
    has = n > 0
    stats.fragments_with_list += int(has.sum())
    frag_tri, lo, n = frag_tri[has], lo[has], n[has]
    if len(n) == 0:
        return
    stats.tests += int(n.sum())
    stats.list_max = max(stats.list_max, int(n.max()))
    ends = np.cumsum(n)
    if tester.rows_ready(lists.node_recv) or use_drjit(int(ends[-1])):
        tester.join_drjit(frag_tri, lo, n, lists.node_recv, state)
        return
    for sl in chunks_by_total(n, PAIR_CHUNK):  # chunks of fragments
        f, node = _pairs(lo[sl], n[sl])
        r = lists.node_recv[node]
        hit, near = tester.numpy(frag_tri[sl][f], r)
        if "mask" in state:
            hit_i = np.flatnonzero(hit)
            near_i = np.flatnonzero(near)
            np.bitwise_or.at(state["band"], r[near_i], near[near_i])
            np.bitwise_or.at(state["mask"], r[hit_i], hit[hit_i])
        else:
            state["shadowed"][r[hit]] = True
            state["band"][r[near]] = True
