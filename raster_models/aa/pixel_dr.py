"""Per-pixel work on a multisample prepass, on the Dr.Jit side (no NumPy round trip).

Two layouts of a launch's samples: *sample lanes* (``N`` consecutive lanes a pixel, the
layout of the prepass's rays) and *pixel lanes* (one lane a pixel holding its ``N`` samples
as Python lists over the slots, :func:`slots`). The loops below run over the ``N`` sample
slots while a kernel is being traced (at most 16 rounds), never over pixels or data.

- :func:`first_of_key` (pixel lanes): for every sample, the first sample of its pixel with
  the same (shape, primitive): its fragment's representative (MSAA/AGAA grouping);
- :func:`fragments_of` (sample lanes): fragment ids, representatives and sample counts;
- :func:`store_normal`: a unit normal as stored in a G-buffer format and read back.
"""

from __future__ import annotations

__all__ = [
    "VALUES_PER_WORD",
    "first_of_key",
    "fragments_of",
    "slots",
    "store_normal",
    "to_sample_lanes",
]


def slots(mi, dr, tp, arr, n: int) -> list:
    """Pixel lanes of a sample-lane array ``arr`` (``n`` lanes a pixel): the list of its
    ``n`` slot values, each an array of type ``tp`` with one lane a pixel."""
    lane = dr.arange(mi.UInt32, dr.width(arr) // n)
    return [dr.gather(tp, arr, lane * n + j) for j in range(n)]


#: Per-slot values packed per UInt32 word by :func:`to_sample_lanes` (5 bits each: 0 to 31,
#: enough for a slot index or a sample count of up to 16 samples, and for ``N`` itself).
VALUES_PER_WORD = 6


def to_sample_lanes(mi, dr, per_slot: list):
    """The inverse of :func:`slots` for small counts: a list of ``N`` pixel-lane UInt32
    arrays of values in ``[0, 31]`` as one sample-lane UInt32 array (evaluated).

    One lane a pixel packs its values, :data:`VALUES_PER_WORD` to a word; one lane a sample
    then unpacks its own (two kernels, one or three word reads a sample).
    """
    n = len(per_slot)
    width = max(dr.width(x) for x in per_slot)
    words = [mi.UInt32(0) for _ in range(-(-n // VALUES_PER_WORD))]
    for j in range(n):  # sample slots (at most 16 rounds)
        i, shift = j // VALUES_PER_WORD, 5 * (j % VALUES_PER_WORD)
        words[i] = words[i] | (mi.UInt32(per_slot[j]) << shift)
    words = [w + dr.zeros(mi.UInt32, width) for w in words]
    dr.eval(*words)
    idx = dr.arange(mi.UInt32, width * n)
    local = idx // n
    s = idx - local * n
    word = dr.gather(mi.UInt32, words[0], local)
    for i in range(1, len(words)):
        word = dr.select(s >= i * VALUES_PER_WORD, dr.gather(mi.UInt32, words[i], local), word)
    out = (word >> (5 * (s % VALUES_PER_WORD))) & 31
    dr.eval(out)
    return out


def first_of_key(mi, dr, valid, shape, prim) -> list:
    """Per sample slot ``j``: UInt32 first slot of the pixel with the same (shape,
    primitive), ``N`` for sky; the arguments are lists over the slots (pixel lanes)."""
    n = len(valid)
    first = []
    for i in range(n):
        f = mi.UInt32(n)
        for j in range(i + 1):  # slot i itself matches when valid: no later slot can be first
            same = valid[j] & (prim[j] == prim[i]) & (shape[j] == shape[i])
            f = dr.select(same & (f == n), j, f)
        first.append(dr.select(valid[i], f, n))
    return first


def store_normal(mi, dr, nrm, fmt: str):
    """``nrm`` (Vector3f) written in ``fmt`` (rgba16f, rgb10a2, oct16) and read back."""
    if fmt == "rgba16f":
        return mi.Vector3f(*(mi.Float(mi.Float16(c)) for c in (nrm.x, nrm.y, nrm.z)))
    if fmt == "rgb10a2":
        q = [dr.floor(dr.clip(c * 0.5 + 0.5, 0.0, 1.0) * 1023.0 + 0.5) for c in nrm]
        return mi.Vector3f(*(c * (2.0 / 1023.0) - 1.0 for c in q))
    # octahedral, 2 x 16-bit SNORM
    l1 = dr.abs(nrm.x) + dr.abs(nrm.y) + dr.abs(nrm.z)
    l1 = dr.select(l1 > 0, l1, 1.0)
    x, y, z = nrm.x / l1, nrm.y / l1, nrm.z / l1
    sx, sy = dr.select(x >= 0, 1.0, -1.0), dr.select(y >= 0, 1.0, -1.0)
    u = dr.select(z < 0, (1.0 - dr.abs(y)) * sx, x)
    v = dr.select(z < 0, (1.0 - dr.abs(x)) * sy, y)
    u = dr.round(dr.clip(u, -1.0, 1.0) * 32767.0) / 32767.0
    v = dr.round(dr.clip(v, -1.0, 1.0) * 32767.0) / 32767.0
    zz = 1.0 - dr.abs(u) - dr.abs(v)
    t = dr.maximum(-zz, 0.0)
    u = u - dr.select(u >= 0, t, -t)
    v = v - dr.select(v >= 0, t, -t)
    return dr.normalize(mi.Vector3f(u, v, zz))


def fragments_of(mi, dr, valid, first, local, n: int, s, offset) -> dict:
    """Fragment bookkeeping of every sample (sample lanes) from its representative slot
    ``first`` (UInt32, sample lanes; ``local`` and ``s`` each lane's pixel in the launch
    and slot).

    Returns Dr.Jit arrays: ``rep`` (the sample is its fragment's representative), ``of``
    (Int32 fragment id, numbered over all pixels in lane order from ``offset``; -1 sky) and
    ``count`` (samples of the sample's fragment).
    """
    rep = valid & (first == s)
    fid = dr.prefix_sum(dr.select(rep, mi.UInt32(1), mi.UInt32(0))) + offset
    fid = dr.gather(mi.UInt32, fid, local * n + dr.select(valid, first, 0))
    count = dr.zeros(mi.UInt32, dr.width(valid))
    for j in range(n):
        at = local * n + j
        same = dr.gather(mi.Bool, valid, at) & (dr.gather(mi.UInt32, first, at) == first)
        count += dr.select(same, mi.UInt32(1), mi.UInt32(0))
    return {
        "rep": rep,
        "of": dr.select(valid, mi.Int32(fid), -1),
        "count": dr.select(valid, count, 0),
    }
