"""The reference's sub-pixel sample positions: a stratified jittered grid keyed by a TEA hash
of (pixel, sample, seed), and the scrambled Sobol (0, 2)-sequence of the adaptive passes.
Both depend only on those three integers, never on how the samples are chunked into launches.
"""

from __future__ import annotations

from ...scenes import backend

__all__ = ["JITTER_ROUNDS", "jitter_from_key", "jitter_key", "sample_jitter", "sobol_sample"]


def _mix32(x: int) -> int:
    """A 32-bit integer hash (lowbias32) of a host integer: spreads the seed's bits."""
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    return x ^ (x >> 16)


def jitter_key(pix, seed: int):
    """Per-pixel key of :func:`sample_jitter`: the pixel index times the golden-ratio
    constant (a bijection of 32-bit integers) XOR a hash of the seed; the 6-round TEA of
    :func:`jitter_from_key` mixes it (a TEA hash of seed and pixel here as well cost 3 % of
    the colour reference's CPU time and changed none of the independence statistics)."""
    mi = backend.mitsuba()
    return (mi.UInt32(pix) * 0x9E3779B9) ^ _mix32(int(seed))


#: TEA rounds of the per-sample hash: 4 leave consecutive samples of a pixel correlated
#: (joint 32x32 chi-square of samples s and s + 1: z = 303), 6 do not (|z| < 2 for every
#: pixel and sample offset the statistics tests try).
JITTER_ROUNDS = 6


def jitter_from_key(key, sample):
    """Jitter of sample ``sample`` of the pixel whose :func:`jitter_key` is ``key``: the two
    32-bit halves of a 6-round TEA hash of key and sample, 24 bits each. 32-bit integer
    operations only (the PCG32 stream seeded from a 64-bit TEA hash that it replaces cost
    four 64-bit multiplies a sample, 8 % of the colour reference's CPU time)."""
    mi = backend.mitsuba()

    a, b = mi.sample_tea_32(key, mi.UInt32(sample), JITTER_ROUNDS)
    scale = 1.0 / (1 << 24)
    return mi.Float(a >> 8) * scale, mi.Float(b >> 8) * scale


def sample_jitter(pix, sample, seed: int):
    """Jitter ``(u, v)`` in ``[0, 1)^2`` of sample ``sample`` of pixel ``pix`` (Dr.Jit UInt32).

    Each (pixel, sample, seed) gets its own hash (:func:`jitter_key`, then
    :func:`jitter_from_key`): seeding PCG32 streams with consecutive stream numbers (an
    earlier scheme) correlated the jitter of neighbouring samples (a joint 32x32 chi-square
    of samples s and s + 2 deviated by thousands of sigma), hashing removes it. The result
    depends only on the three integers, never on chunking.
    """
    return jitter_from_key(jitter_key(pix, seed), sample)


def _reverse_bits(x):
    """Bit reversal of Dr.Jit UInt32 ``x`` (five swap steps)."""
    x = ((x >> 1) & 0x55555555) | ((x & 0x55555555) << 1)
    x = ((x >> 2) & 0x33333333) | ((x & 0x33333333) << 2)
    x = ((x >> 4) & 0x0F0F0F0F) | ((x & 0x0F0F0F0F) << 4)
    x = ((x >> 8) & 0x00FF00FF) | ((x & 0x00FF00FF) << 8)
    return (x >> 16) | (x << 16)


def sobol_sample(pix, sample, seed: int, bits: int = 32):
    """Point ``sample`` of pixel ``pix``'s 2-D Sobol sequence, digitally shifted (Dr.Jit).

    The first two Sobol dimensions (van der Corput and the Pascal-matrix dimension) form a
    (0, 2)-sequence: every aligned block of ``2^k`` points, and every prefix of ``2^k``
    points, has one point in each elementary interval of area ``2^-k``. Adaptive passes
    double a pixel's samples, so each pass is a stratified net and so is their union, as
    good as one grid of the final count (separate jittered grids per pass are not: 16 + 16
    + 32 + ... + 512 samples estimate an edge pixel worse than one 1024 grid). A per-pixel
    random XOR shift (TEA hash of pixel and seed; the shift keeps the net property) makes
    every point uniform over the pixel, so any count is unbiased, and depends only on the
    three integers, never on chunking. ``bits``: how many low bits of ``sample`` can be set
    (the higher ones contribute nothing).
    """
    mi = backend.mitsuba()
    import drjit as dr

    shift_u, shift_v = mi.sample_tea_32(mi.UInt32(int(seed) & 0xFFFFFFFF), mi.UInt32(pix), 8)
    sample = mi.UInt32(sample)
    u_bits = _reverse_bits(sample)
    v_bits = dr.zeros(mi.UInt32, dr.width(sample))
    col = 1 << 31
    for bit in range(min(int(bits), 32)):  # Sobol dimension 2: column c_{k+1} = c_k ^ (c_k >> 1)
        v_bits ^= dr.select(((sample >> bit) & 1) == 1, mi.UInt32(col), mi.UInt32(0))
        col ^= col >> 1
    scale = 1.0 / (1 << 24)
    u = mi.Float((u_bits ^ shift_u) >> 8) * scale
    v = mi.Float((v_bits ^ shift_v) >> 8) * scale
    return u, v
