"""Dr.Jit twins of the coherent-shadow-map compression analysis: visibility intervals
computed inside the map-rendering kernel and the greedy run compression of every ordering.

Each function gives the same bytes as its NumPy reference in :mod:`raster_models.coherent.model`
(:func:`~raster_models.coherent.model.visibility_intervals`,
:func:`~raster_models.coherent.model.compress_runs`): the same float64 operations in the same order,
one rounding to float32, and the float32 step below a value taken on its bit pattern as
``np.nextafter`` does. They exist for speed only: at the defaults (1024 maps of 128^2) the
NumPy versions walk sixteen million texels several times over. ``tests/test_coherent_dr.py``
pins each twin to its reference on random input.

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
"""

from __future__ import annotations

import numpy as np

from scenes import backend

__all__ = [
    "below_f32",
    "compress_orders",
    "intervals",
    "launch_compression",
    "launch_rows",
    "take_rows",
]

#: Bit pattern of the float32 just below +0 (``np.nextafter(0, -inf)``: -1 subnormal step).
_NEG_TINY_BITS = 0x80000001

#: Most contiguous texels one lane of :func:`compress_orders` walks (one packet load each
#: of ``lo`` and ``hi`` per map instead of one gather per texel).
PACKET = 16

#: Most looked-up maps whose decoded values :func:`compress_orders` follows during its walk
#: (each adds a value and a flag per texel to the loop state); more take the backward pass
#: over every map's stored run prefix.
MAX_CAPTURED = 8


def below_f32(x):
    """Largest float32 strictly below each Float64 ``x`` (``inf`` stays ``inf``), as a
    Float32 array: the Dr.Jit twin of ``coherent._below``."""
    mi = backend.mitsuba()
    import drjit as dr

    f = mi.Float(x)
    bits = dr.reinterpret_array(mi.UInt32, f)
    down_bits = dr.select(f > 0, bits - 1, dr.select(f < 0, bits + 1, _NEG_TINY_BITS))
    down = dr.reinterpret_array(mi.Float, mi.UInt32(down_bits))
    f = dr.select(mi.Float64(f) >= x, down, f)
    return dr.select(dr.isinf(x), dr.inf, f)


def intervals(z1, z2, bias: float, guard: float, *, dz1=None, dz2=None):
    """Visibility intervals ``(lo, hi)`` (Float32) of texels with first/second surface depths
    ``z1``, ``z2`` and depth spreads ``dz1``, ``dz2`` (Float64; ``None``: texel centres
    only): the Dr.Jit twin of :func:`raster_models.coherent.model.visibility_intervals` (see
    there), ``guard`` its ``SPREAD_GUARD``."""
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
    """Texels per lane of :func:`compress_orders`: the largest power of two up to
    :data:`PACKET` dividing the texel count (their values are contiguous: one packet load)."""
    p = PACKET
    while t_count % p:
        p //= 2
    return p


def compress_orders(
    lo, hi, n_maps: int, orders: list[np.ndarray], *, decode: int | None = 0, rows=None
):
    """Greedy runs of every ordering in ``orders``, and the decoded maps of one of them: the
    Dr.Jit twin of :func:`raster_models.coherent.model.compress_runs`.

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
    runs : list of ints, the stored values of each ordering.
    decoded : ``(len(rows), T)`` float32 NumPy array (or ``None``), the value each map id
        of ``rows`` reads.

    Every lane walks the ``N`` maps of one ordering in order (the loop over maps runs
    inside the kernel) for a packet of contiguous texels. The decoded value of a map is its
    run's final (largest) ``lo``: for up to :data:`MAX_CAPTURED` rows the walk follows
    those maps' runs to their ends; for more (or ``rows=None``) it stores every position's
    run prefix and break flags, and a second, backward walk spreads each run's value.
    """
    return launch_compression(lo, hi, n_maps, orders, decode=decode, rows=rows)()


def launch_compression(
    lo, hi, n_maps: int, orders: list[np.ndarray], *, decode: int | None = 0, rows=None
):
    """Schedule the kernels of :func:`compress_orders` (Dr.Jit runs them asynchronously) and
    return the function that waits for them and returns its result: NumPy work can run in
    between."""
    mi = backend.mitsuba()
    import drjit as dr

    n = int(n_maps)
    total = dr.width(lo)
    t_count = total // n
    pk = _packet(t_count)
    g_count = t_count // pk  # packets per map
    k = len(orders)
    u32 = mi.UInt32
    vec_f = mi.ArrayXf
    vec_b = mi.ArrayXb
    order_all = u32(np.concatenate([np.asarray(o, dtype=np.uint32) for o in orders]))
    lane = dr.arange(u32, k * g_count)
    g_u = dr.opaque(u32, g_count)
    n_u = dr.opaque(u32, n)
    # Neighbouring lanes walk the same texels in the k orderings: each packet's texels
    # stay in the cache for all orderings instead of being read from memory k times.
    k_u = dr.opaque(u32, k)
    grp = lane // k_u
    which = lane - grp * k_u
    base = which * n_u

    def load(src, m, grp, width):
        return dr.gather(vec_f, src, m * g_u + grp, shape=(pk, width))

    width = k * g_count
    first = dr.gather(u32, order_all, base)
    cur_lo = load(lo, first, grp, width)
    cur_hi = load(hi, first, grp, width)
    keep = decode is not None
    # Few maps looked up (a directional light: one): follow their runs during the walk
    # instead of keeping every map's run prefix for a backward pass.
    capture = keep and rows is not None and len(rows) <= MAX_CAPTURED
    table = keep and not capture
    if keep:
        mine = which == dr.opaque(u32, int(decode))
    if table:
        prefix = dr.empty(mi.Float, n * t_count)
        starts = dr.empty(mi.Float, n * t_count)
        dr.scatter(prefix, cur_lo, grp, active=mine)
        dr.scatter(starts, vec_f([mi.Float(1.0)] * pk), grp, active=mine)
    caps, opens, at_pos = [], [], []
    if capture:
        # Position of each looked-up map in the decoded ordering.
        where = np.empty(n, dtype=np.int64)
        where[np.asarray(orders[decode], dtype=np.int64)] = np.arange(n)
        for m in np.asarray(rows, dtype=np.int64):
            at = dr.opaque(u32, int(where[m]))
            at_pos.append(at)
            here = dr.zeros(mi.Bool, width) | (at == 0)
            caps.append(dr.select(here, cur_lo, 0.0))
            opens.append(vec_b([here] * pk))
    runs = dr.zeros(mi.UInt32, width) + pk  # every texel starts a run
    pos = u32(1)

    def cond(pos, cur_lo, cur_hi, runs, caps, opens):
        return pos < n_u

    def body(pos, cur_lo, cur_hi, runs, caps, opens):
        m = dr.gather(u32, order_all, base + pos)
        m_lo = load(lo, m, grp, width)
        m_hi = load(hi, m, grp, width)
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

    pos, cur_lo, cur_hi, runs, caps, opens = dr.while_loop(
        (pos, cur_lo, cur_hi, runs, caps, opens),
        cond,
        body,
        labels=("pos", "lo", "hi", "runs", "caps", "opens"),
    )
    if table:
        dr.eval(runs, prefix, starts)
    elif capture:
        captured = dr.empty(mi.Float, len(caps) * t_count)
        for i, cap in enumerate(caps):
            dr.scatter(captured, cap, dr.opaque(u32, i) * g_u + grp, active=mine)
        dr.eval(runs, captured)
    else:
        dr.eval(runs)

    def counts() -> list[int]:
        per_lane = runs.numpy().astype(np.int64).reshape(g_count, k)
        return [int(c) for c in per_lane.sum(axis=0)]

    if not keep:
        return lambda: (counts(), None)
    if capture:
        return lambda: (counts(), captured.numpy().reshape(len(caps), t_count))
    # Backward: every member of a run reads the run's final (largest) lo.
    order_d = u32(np.asarray(orders[decode], dtype=np.uint32))
    grp2 = dr.arange(u32, g_count)
    decoded = dr.empty(mi.Float, n * t_count)
    last = u32(n - 1)
    value = load(prefix, last, grp2, g_count)
    dr.scatter(decoded, value, dr.gather(u32, order_d, last) * g_u + grp2)

    def cond_b(pos, value):
        return pos > 0

    def body_b(pos, value):
        p = pos - 1
        nxt_start = load(starts, pos, grp2, g_count) > 0.5
        value = dr.select(nxt_start, load(prefix, p, grp2, g_count), value)
        dr.scatter(decoded, value, dr.gather(u32, order_d, p) * g_u + grp2)
        return p, value

    dr.while_loop((last, value), cond_b, body_b, labels=("pos", "value"))
    dr.eval(decoded)
    decoded_rows = launch_rows(decoded, rows, n)
    return lambda: (counts(), decoded_rows())


def take_rows(flat, rows, n_rows: int) -> np.ndarray:
    """Rows ``rows`` (default: all) of a map-major Dr.Jit array of ``n_rows`` rows, as a
    ``(len(rows), T)`` NumPy array (only those rows are copied)."""
    return launch_rows(flat, rows, n_rows)()


def launch_rows(flat, rows, n_rows: int):
    """:func:`take_rows`, scheduled: returns the function that waits and returns it."""
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
