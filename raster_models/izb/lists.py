"""IZB lists and traversal: the grid of per-texel sample lists, built by sorting, and the joins
of conservative fragments with those lists, rounds of triangles batched into few Dr.Jit joins
(:class:`Joins`).

A GPU IZB keeps a head pointer per texel and a next pointer per node; here the lists are the
nodes sorted by texel (``node_texel`` increasing, ties in insertion order), a list being the
run of one texel: the same lists in the same order. A fragment ``(triangle, texel)`` walks
its texel's list and tests each node's sample(s) against the triangle's shadow volume
(:func:`raster_models.izb.geometry.shadow_volumes`). Fully shadowed receivers are removed
from the lists after each round of triangles (the seed's "remove fully shadowed pixels",
which gradually shortens the lists over the frame); the counters are those of this rule,
however the rounds are batched.

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

from .kernel import FULL_MASK, DeadPairs, PairTester

__all__ = [
    "BATCH_PAIRS",
    "FULL_MASK",
    "IzbLists",
    "JoinStats",
    "Joins",
    "build_lists",
    "head_offsets",
    "late_pairs",
    "list_nodes",
]

#: (fragment, node) pairs from which a batch of rounds is joined (:class:`Joins`): enough
#: that a frame of many small rounds pays few kernel launches, few enough that the tests of
#: receivers fully shadowed early in a batch stay a small share.
BATCH_PAIRS = 1 << 16

#: The round of a receiver (or bit) that no pair of a batch fills.
_NEVER = np.iinfo(np.int64).max


@dataclass
class IzbLists:
    """Grid-of-lists: ``node_texel`` (sorted, global texel id = cascade * R^2 + j * R + i)
    and ``node_recv`` (receiver index) per node (int32 where the ids fit); ``heads``: the
    head offsets of :func:`head_offsets` for these nodes, or ``None`` until :meth:`span`
    needs them (reset by :meth:`compact`); ``node_id``: the index of each node in the
    lists as built, or ``None`` until :meth:`compact` removes one."""

    node_texel: np.ndarray
    node_recv: np.ndarray
    heads: np.ndarray | None = field(default=None, repr=False)
    node_id: np.ndarray | None = field(default=None, repr=False)

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
            if self.node_id is None:
                kept = np.flatnonzero(keep)
                self.node_id = kept.astype(_index_type(kept), copy=False)
            else:
                self.node_id = self.node_id[keep]
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


class Joins:
    """The joins of a frame's traversal, rounds of triangles batched into few Dr.Jit joins.

    The traversal's rule: each round's fragments walk the lists as they are after the
    previous rounds, whose fully shadowed receivers have left them. Here the fragments of
    consecutive rounds are spanned over the lists as they are at the start of a batch and
    joined at once (:meth:`raster_models.izb.kernel.PairTester.join`, a few kernel launches)
    once the batch holds :data:`BATCH_PAIRS` pairs; then the lists lose the receivers
    fully shadowed by the batch. A receiver fully shadowed in an earlier round of the batch
    is tested again in the later ones: those tests change no answer (its mask is full, or
    its flag set, already; the band of a shadowed sample is not reported) and are left out
    of the counters. The join returns the pairs of the receivers it leaves fully shadowed;
    from them, the round of the batch in which each receiver became fully shadowed, and so
    which of its pairs one join per round would not have tested (:func:`late_pairs`). The
    answer and the counters are those of one join per round, whatever the batches
    (``tests/test_izb.py`` checks it).

    Parameters
    ----------
    lists : the frame's lists (compacted in place after each batch).
    tester : the sample-triangle tests of the frame (its shadow volumes, receivers, the
        lists' nodes as built and epsilon).
    state : ``shadowed`` ``(M,)`` bool (1 sample) or ``mask`` ``(M,)`` uint32 (32 samples),
        and ``band`` (same type: samples inside a volume's edge planes within ``epsilon`` of
        its triangle plane, lit by the epsilon), updated in place.
    """

    def __init__(self, lists: IzbLists, tester: PairTester, state: dict):
        if np.any(state[tester.keys[0]] == tester.full):
            raise ValueError("a receiver fully shadowed before the traversal is no receiver")
        self.lists = lists
        self.tester = tester
        self.state = state
        self.stats = JoinStats()
        self._batch: list[tuple] = []
        self._pairs = 0
        self._round = 0
        self._dead = 0

    def add(self, frag_tri: np.ndarray, frag_texel: np.ndarray, counted=None) -> None:
        """Fragments ``(triangle, global texel)`` of the current round; ``counted`` (bool per
        fragment, default all): those of the technique, in the counters. The others (a
        triangle grown for the epsilon band, :func:`raster_models.izb.geometry.
        grown_fragments`) touch no sample of their texel: they set band bits only."""
        counted = np.ones(len(frag_tri), dtype=bool) if counted is None else counted
        self.stats.fragments += int(np.count_nonzero(counted))
        if len(frag_tri) == 0 or len(self.lists.node_texel) == 0:
            return
        lo, n = self.lists.span(frag_texel)
        has = n > 0
        if has.any():
            self._batch.append((frag_tri[has], lo[has], n[has], self._round, counted[has]))
            self._pairs += int(n[has].sum())

    def end_round(self) -> None:
        """Closes a round; joins the batch once it holds :data:`BATCH_PAIRS` pairs."""
        self._round += 1
        if self._pairs >= BATCH_PAIRS:
            self.flush()

    def flush(self) -> None:
        """Joins the batch, counts its tests and removes the fully shadowed receivers from
        the lists."""
        key = self.tester.keys[0]
        if self._batch:
            tri, lo, n = (np.concatenate([b[i] for b in self._batch]) for i in range(3))
            rnd = np.repeat([b[3] for b in self._batch], [len(b[0]) for b in self._batch])
            counted = np.concatenate([b[4] for b in self._batch])
            several = self._batch[-1][3] > self._batch[0][3]
            before = self.state[key].copy() if several else None
            dead = self.tester.join(tri, lo, n, self.lists.node_id, self.state, dead=several)
            live = (n if dead is None else n - late_pairs(dead, rnd, before))[counted]
            st = self.stats
            st.tests += int(live.sum())
            st.fragments_with_list += int(np.count_nonzero(live))
            st.list_max = max(st.list_max, int(live.max(initial=0)))
        self._batch, self._pairs, self._round = [], 0, 0
        done = self.state[key] == self.tester.full
        n_dead = int(np.count_nonzero(done))
        if n_dead > self._dead:  # a receiver stays dead: no new one, no node to remove
            self.stats.nodes_removed += self.lists.compact(done)
            self._dead = n_dead


def late_pairs(dead: DeadPairs, rnd: np.ndarray, before: np.ndarray):
    """Per fragment of a batch: its pairs tested after their receiver became fully shadowed
    (in an earlier round of the batch), which one join per round would not have tested.

    A receiver becomes fully shadowed in the first round by which every bit of its mask
    (its flag, 1 sample) is set, before the batch or by a pair of that round or an earlier
    one: no later than its first pair with a full result, earlier where the partial masks of
    earlier rounds fill it.

    Parameters
    ----------
    dead : the batch's pairs whose receiver it left fully shadowed (not fully shadowed
        before it).
    rnd : ``(F,)`` round of each fragment within the batch.
    before : ``(M,)`` the receivers' masks (uint32) or flags (bool) before the batch.

    Returns
    -------
    ``(F,)`` int64 counts.
    """
    j = rnd[dead.frag]
    if len(j) == 0 or j.min() == j.max():  # one round: none late
        return np.zeros(len(rnd), dtype=np.int64)
    bits = 32 if before.dtype == np.uint32 else 1
    whole = dead.result == (1 << bits) - 1
    died = _first_round(dead.recv[whole], j[whole], len(before))  # per receiver
    part = ~whole & (dead.result != 0) & (j < died[dead.recv])
    if part.any():  # partial masks of rounds before the first full one
        recv, inv = np.unique(dead.recv[part], return_inverse=True)
        died[recv] = np.minimum(died[recv], _filled(recv, inv, dead.result[part], j[part], before))
    late = j > died[dead.recv]
    return np.bincount(dead.frag[late], minlength=len(rnd))


def _filled(recv, inv, result, j, before):
    """Per receiver ``recv``: the first round by which its bits set before (``before``) and
    by the partial masks ``result`` of rounds ``j`` (receiver ``recv[inv]``) fill its mask
    (:data:`_NEVER` where they do not)."""
    q = np.arange(32, dtype=np.uint32)
    k, b = np.nonzero((result[:, None] >> q) & 1)  # every set bit of every mask
    first = _first_round(inv[k] * 32 + b, j[k], len(recv) * 32).reshape(len(recv), 32)
    first[(before[recv][:, None] >> q) & 1 != 0] = 0
    return first.max(axis=1)


def _first_round(slot: np.ndarray, j: np.ndarray, size: int) -> np.ndarray:
    """``(size,)`` the smallest round ``j`` of the entries of each ``slot`` (:data:`_NEVER`
    where none)."""
    first = np.full(size, _NEVER)
    np.minimum.at(first, slot, j)
    return first
