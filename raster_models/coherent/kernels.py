"""Dr.Jit kernels of the coherent-shadow-map compression analysis: visibility intervals
computed inside the map-rendering kernel and the greedy run compression of every ordering.

Every value is computed in float64 in a fixed order, rounded to float32 once, and the
float32 step below a value is taken on its bit pattern as ``np.nextafter`` does: the
results are those of a plain NumPy evaluation, bit for bit. ``tests/_coherent_reference.py``
holds that evaluation (the paper's definitions, written directly), and
``tests/test_coherent_dr.py`` compares the kernels with it on random input, exactly (float32
bounds and decoded values, integer run counts). At the defaults (1024 maps of 128^2) the
NumPy version walks sixteen million texels several times over.

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scenes import backend

__all__ = [
    "MAX_CAPTURED",
    "PACKET",
    "below_f32",
    "intervals",
    "launch_compression",
    "launch_rows",
]

#: Bit pattern of the float32 just below +0 (``np.nextafter(0, -inf)``: -1 subnormal step).
_NEG_TINY_BITS = 0x80000001

#: Most contiguous texels one lane of :func:`launch_compression` walks (one packet load
#: each of ``lo`` and ``hi`` per map instead of one gather per texel).
PACKET = 16

#: Most looked-up maps whose decoded values :func:`launch_compression` follows during its
#: walk (each adds a value and a flag per texel to the loop state); more take the backward
#: pass over every map's stored run prefix.
MAX_CAPTURED = 8


def below_f32(x):
    """Largest float32 strictly below each Float64 ``x`` (``inf`` stays ``inf``), as a
    Float32 array (``np.nextafter(float32(x), -inf)`` where the rounding is not below
    ``x``)."""
    mi = backend.mitsuba()
    import drjit as dr

    f = mi.Float(x)
    bits = dr.reinterpret_array(mi.UInt32, f)
    down_bits = dr.select(f > 0, bits - 1, dr.select(f < 0, bits + 1, _NEG_TINY_BITS))
    down = dr.reinterpret_array(mi.Float, mi.UInt32(down_bits))
    f = dr.select(mi.Float64(f) >= x, down, f)
    return dr.select(dr.isinf(x), dr.inf, f)


def intervals(z1, z2, bias: float, guard: float, *, dz1=None, dz2=None):
    """Per texel, the stored values ``[lo, hi]`` (Float32, inclusive) that give the
    uncompressed map's answer to every receiver on the texel's first or second surface.

    ``z1``, ``z2``: first and second surface depths (Float64, normalized; ``inf``: none);
    ``dz1``, ``dz2``: their depth spreads from the texel centre to its corners (Float64;
    ``None``: texel centres only, spreads 0), multiplied by ``guard``
    (:data:`raster_models.coherent.surfaces.SPREAD_GUARD`).

    ``lo`` is the stored first depth ``s1``. A receiver is compared as ``z - bias <=
    stored``; on a surface of depth ``z`` at the texel centre and spread ``dz`` its
    reference lies in ``[z - dz - bias, z + dz - bias]``. First surface: if any of its
    references exceeds ``s1`` (acne: the uncompressed map shadows it there) no other value
    is safe, ``hi = s1``. Second surface: its references must stay above the stored value,
    ``hi`` = the largest float32 below ``z2 - dz2 - bias`` (``s1`` when that is not above
    ``s1``). No first surface: the map is cleared to 1, every receiver inside the sphere is
    lit by any value >= 1 (``hi = inf``).
    """
    mi = backend.mitsuba()
    import drjit as dr

    f64 = mi.Float64
    bias_k = dr.opaque(f64, float(bias))
    lo = mi.Float(dr.select(dr.isfinite(z1), z1, 1.0))
    s1 = f64(lo)
    if dz1 is None:
        ref1 = z1 - bias_k
        h2 = z2 - bias_k
    else:
        guard_k = dr.opaque(f64, float(guard))
        ref1 = z1 + dz1 * guard_k - bias_k
        h2 = z2 - dz2 * guard_k - bias_k
    acne = dr.isfinite(z1) & (ref1 > s1)
    h2 = dr.select(dr.isfinite(z2), h2, dr.inf)
    hi = dr.select(h2 > s1, below_f32(h2), lo)
    hi = dr.select(acne, lo, hi)
    return lo, dr.maximum(hi, lo)


def _packet(t_count: int) -> int:
    """Texels per lane of :func:`launch_compression`: the largest power of two up to
    :data:`PACKET` dividing the texel count (their values are contiguous: one packet load)."""
    p = PACKET
    while t_count % p:
        p //= 2
    return p


@dataclass
class _Lanes:
    """The lanes of the compression walk: lane ``g * k + o`` walks ordering ``o`` over the
    packet ``g`` of :func:`_packet` contiguous texels (neighbouring lanes walk the same
    texels in the ``k`` orderings: each packet's texels stay in the cache for all orderings
    instead of being read from memory ``k`` times)."""

    mi: object
    n: int  # maps
    t_count: int  # texels per map
    pk: int  # texels per packet
    g_count: int  # packets per map
    order_all: object  # UInt32: the orderings, concatenated
    grp: object  # UInt32 packet of each lane
    which: object  # UInt32 ordering of each lane
    base: object  # UInt32 first position of each lane's ordering in order_all
    g_u: object  # opaque UInt32 g_count
    n_u: object  # opaque UInt32 n
    width: int  # lanes

    def load(self, src, m, grp, width: int):
        """Float32 packets (``pk`` values) of map ``m``, packet ``grp`` of ``src``."""
        import drjit as dr

        return dr.gather(self.mi.ArrayXf, src, m * self.g_u + grp, shape=(self.pk, width))


def _lanes(mi, total: int, n: int, orders: list[np.ndarray]) -> _Lanes:
    import drjit as dr

    t_count = total // n
    pk = _packet(t_count)
    g_count = t_count // pk  # packets per map
    k = len(orders)
    u32 = mi.UInt32
    order_all = u32(np.concatenate([np.asarray(o, dtype=np.uint32) for o in orders]))
    lane = dr.arange(u32, k * g_count)
    g_u = dr.opaque(u32, g_count)
    n_u = dr.opaque(u32, n)
    k_u = dr.opaque(u32, k)
    grp = lane // k_u
    which = lane - grp * k_u
    return _Lanes(
        mi, n, t_count, pk, g_count, order_all, grp, which, which * n_u, g_u, n_u, k * g_count
    )


def _capture_positions(lanes: _Lanes, order: np.ndarray, rows) -> list:
    """Opaque UInt32 position of each map of ``rows`` in the decoded ``order``."""
    import drjit as dr

    where = np.empty(lanes.n, dtype=np.int64)
    where[np.asarray(order, dtype=np.int64)] = np.arange(lanes.n)
    return [dr.opaque(lanes.mi.UInt32, int(where[m])) for m in np.asarray(rows, dtype=np.int64)]


def _walk(lanes: _Lanes, lo, hi, *, mine, table: bool, at_pos: list):
    """The forward walk: every lane over the ``N`` maps of its ordering (the loop over maps
    runs inside the kernel), counting runs. For the decoded ordering (lanes ``mine``):
    ``table``: every position's run prefix and break flags stored; ``at_pos``: the runs of
    the maps at these positions followed to their ends. Returns ``runs`` (UInt32 per lane)
    and ``(prefix, starts)`` (``table``) or the followed values (Float32 packets each)."""
    import drjit as dr

    mi, u32, width, grp = lanes.mi, lanes.mi.UInt32, lanes.width, lanes.grp
    n, pk, g_u = lanes.n, lanes.pk, lanes.g_u
    first = dr.gather(u32, lanes.order_all, lanes.base)
    cur_lo = lanes.load(lo, first, grp, width)
    cur_hi = lanes.load(hi, first, grp, width)
    prefix = starts = None
    if table:
        prefix = dr.empty(mi.Float, n * lanes.t_count)
        starts = dr.empty(mi.Float, n * lanes.t_count)
        dr.scatter(prefix, cur_lo, grp, active=mine)
        dr.scatter(starts, mi.ArrayXf([mi.Float(1.0)] * pk), grp, active=mine)
    caps, opens = [], []
    for at in at_pos:
        here = dr.zeros(mi.Bool, width) | (at == 0)
        caps.append(dr.select(here, cur_lo, 0.0))
        opens.append(mi.ArrayXb([here] * pk))
    runs = dr.zeros(mi.UInt32, width) + pk  # every texel starts a run

    def cond(pos, cur_lo, cur_hi, runs, caps, opens):
        return pos < lanes.n_u

    def body(pos, cur_lo, cur_hi, runs, caps, opens):
        m = dr.gather(u32, lanes.order_all, lanes.base + pos)
        m_lo = lanes.load(lo, m, grp, width)
        m_hi = lanes.load(hi, m, grp, width)
        new_lo = dr.maximum(cur_lo, m_lo)
        new_hi = dr.minimum(cur_hi, m_hi)
        brk = new_lo > new_hi
        cur_lo = dr.select(brk, m_lo, new_lo)
        cur_hi = dr.select(brk, m_hi, new_hi)
        for j in range(pk):
            runs = runs + dr.select(brk[j], 1, 0)
        if table:
            slot = pos * g_u + grp
            dr.scatter(prefix, cur_lo, slot, active=mine)
            dr.scatter(starts, dr.select(brk, 1.0, 0.0), slot, active=mine)
        # A followed map's value is its run's lo so far, until the run ends.
        for i, at in enumerate(at_pos):
            here = pos == at
            opens[i] = here | (opens[i] & ~brk)
            caps[i] = dr.select(opens[i], cur_lo, caps[i])
        return pos + 1, cur_lo, cur_hi, runs, caps, opens

    _, _, _, runs, caps, _ = dr.while_loop(
        (u32(1), cur_lo, cur_hi, runs, caps, opens),
        cond,
        body,
        labels=("pos", "lo", "hi", "runs", "caps", "opens"),
    )
    return runs, ((prefix, starts) if table else caps)


def _decode_backward(lanes: _Lanes, prefix, starts, order: np.ndarray):
    """The backward walk of the decoded ordering: every member of a run reads the run's
    final (largest) lo. Returns the decoded maps, map-major Float32 by map id."""
    import drjit as dr

    mi, u32, g_count, g_u = lanes.mi, lanes.mi.UInt32, lanes.g_count, lanes.g_u
    order_d = u32(np.asarray(order, dtype=np.uint32))
    grp2 = dr.arange(u32, g_count)
    decoded = dr.empty(mi.Float, lanes.n * lanes.t_count)
    last = u32(lanes.n - 1)
    value = lanes.load(prefix, last, grp2, g_count)
    dr.scatter(decoded, value, dr.gather(u32, order_d, last) * g_u + grp2)

    def cond_b(pos, value):
        return pos > 0

    def body_b(pos, value):
        p = pos - 1
        nxt_start = lanes.load(starts, pos, grp2, g_count) > 0.5
        value = dr.select(nxt_start, lanes.load(prefix, p, grp2, g_count), value)
        dr.scatter(decoded, value, dr.gather(u32, order_d, p) * g_u + grp2)
        return p, value

    dr.while_loop((last, value), cond_b, body_b, labels=("pos", "value"))
    dr.eval(decoded)
    return decoded


def launch_compression(
    lo, hi, n_maps: int, orders: list[np.ndarray], *, decode: int | None = 0, rows=None
):
    """Greedy runs of every ordering in ``orders``, and the decoded maps of one of them:
    the kernels are scheduled (Dr.Jit runs them asynchronously) and the function returned
    waits for them and returns ``(runs, decoded)``; NumPy work can run in between.

    A run is a maximal sequence of consecutive maps (in storage order) whose intervals
    ``[lo, hi]`` intersect (greedy: optimal for interval runs); each map of a run decodes to
    the run's largest ``lo``.

    Parameters
    ----------
    lo, hi : Float32 interval bounds, ``n_maps * T`` values, map-major (map ``m``, texel
        ``t`` at ``m * T + t``).
    n_maps : number of maps ``N``.
    orders : permutations of ``range(N)`` (storage orders).
    decode : index in ``orders`` of the ordering whose decoded maps are returned (``None``:
        none).
    rows : map ids whose decoded maps are returned (default: all, by map id).

    Returns
    -------
    A function returning ``runs`` (list of ints, the stored values of each ordering) and
    ``decoded`` (``(len(rows), T)`` float32 NumPy array, the value each map id of ``rows``
    reads; ``None`` without ``decode``).

    Every lane walks the ``N`` maps of one ordering in order for a packet of contiguous
    texels (:class:`_Lanes`). For up to :data:`MAX_CAPTURED` rows the walk follows those
    maps' runs to their ends; for more (or ``rows=None``) it stores every position's run
    prefix and break flags, and a second, backward walk spreads each run's value.
    """
    mi = backend.mitsuba()
    import drjit as dr

    u32 = mi.UInt32
    lanes = _lanes(mi, dr.width(lo), int(n_maps), orders)
    keep = decode is not None
    # Few maps looked up (a directional light: one): follow their runs during the walk
    # instead of keeping every map's run prefix for a backward pass.
    capture = keep and rows is not None and len(rows) <= MAX_CAPTURED
    table = keep and not capture
    mine = (lanes.which == dr.opaque(u32, int(decode))) if keep else None
    at_pos = _capture_positions(lanes, orders[decode], rows) if capture else []
    runs, kept = _walk(lanes, lo, hi, mine=mine, table=table, at_pos=at_pos)
    if table:
        dr.eval(runs, *kept)
    elif capture:
        captured = dr.empty(mi.Float, len(kept) * lanes.t_count)
        for i, cap in enumerate(kept):
            dr.scatter(captured, cap, dr.opaque(u32, i) * lanes.g_u + lanes.grp, active=mine)
        dr.eval(runs, captured)
    else:
        dr.eval(runs)

    def counts() -> list[int]:
        per_lane = runs.numpy().astype(np.int64).reshape(lanes.g_count, len(orders))
        return [int(c) for c in per_lane.sum(axis=0)]

    if not keep:
        return lambda: (counts(), None)
    if capture:
        return lambda: (counts(), captured.numpy().reshape(len(kept), lanes.t_count))
    decoded = _decode_backward(lanes, *kept, orders[decode])
    decoded_rows = launch_rows(decoded, rows, lanes.n)
    return lambda: (counts(), decoded_rows())


def launch_rows(flat, rows, n_rows: int):
    """Rows ``rows`` (default: all) of a map-major Dr.Jit array of ``n_rows`` rows: the copy
    is scheduled, the function returned waits and returns them as a ``(len(rows), T)``
    NumPy array (only those rows are copied)."""
    mi = backend.mitsuba()
    import drjit as dr

    t_count = dr.width(flat) // n_rows
    if rows is None:
        return lambda: flat.numpy().reshape(n_rows, t_count)
    rows = np.asarray(rows, dtype=np.int64)
    idx = (rows[:, None] * t_count + np.arange(t_count)[None, :]).ravel()
    out = dr.gather(type(flat), flat, mi.UInt32(idx.astype(np.uint32)))
    dr.eval(out)
    return lambda: out.numpy().reshape(len(rows), t_count)
