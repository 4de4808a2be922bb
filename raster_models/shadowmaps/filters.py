"""Shadow-map filters, vectorized over receivers: depth compare (point, PCF) and moments.

The compare filters read a map's float32 texels as a Dr.Jit array (:attr:`MapData.texels`,
:func:`upload_texels`) and run as one fused kernel per chunk of lookups
(:func:`compare_taps`); the moment filters (VSM/EVSM) are NumPy.

Texture conventions: a map is ``(R, R)`` (row ``j``, column ``i``); texel ``(i, j)`` covers
``u in [i, i+1)/R``, ``v in [j, j+1)/R``; its centre is ``((i + 0.5)/R, (j + 0.5)/R)``.
A compare returns 1 (lit) when ``reference <= stored`` (D3D ``COMPARISON_LESS_EQUAL``, the
Intel SDSM and Falcor samplers); the reference is clamped to [0, 1] first.

Address modes: ``clamp`` repeats the edge texels (D3D ``ADDRESS_CLAMP``: Intel sample, MJP);
``border`` returns stored depth 1, i.e. lit (Falcor's border colour 1).

- ``point``: nearest texel.
- ``hw_pcf``: D3D11 ``SampleCmp`` with a linear comparison filter: the 4 texels around the
  sample are compared, then the results are interpolated bilinearly; the weights have the
  hardware's ``subtexel_bits`` of sub-texel precision (D3D11 requires 8).
- ``pcf``: ``N x N`` hardware-PCF taps spaced one texel apart, centred on the sample (a box of
  bilinear taps: support ``N + 1`` texels; ``N^2`` lookups).
- ``poisson``: ``taps`` hardware-PCF taps on a fixed Poisson disc of diameter ``filter_size``
  texels (MJP's "random disc PCF"), optionally rotated per pixel by a seeded random angle.
- ``vsm``, ``evsm2``, ``evsm4``: moments of the stored depth (optionally exponentially warped,
  MJP's ``WarpDepth``), box-blurred, sampled bilinearly and turned into visibility by the
  one-tailed Chebyshev bound with a minimum variance and light-bleeding reduction.
- ``three_pcf``, ``three_vsm``: three.js r187's ``PCFShadowMap`` and ``VSMShadowMap``
  (:mod:`.three_filters`).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy import ndimage

from ..depth import clip01_dr

__all__ = [
    "FILTERS",
    "MOMENT_FILTERS",
    "bilinear_texture",
    "blur_moments",
    "chebyshev",
    "compare_bilinear",
    "compare_point",
    "compare_taps",
    "evsm_exponents",
    "lookups_per_pixel",
    "moment_lookup",
    "moment_texture",
    "moments_from_depth",
    "pcf_grid",
    "pcf_poisson",
    "poisson_disc",
    "upload_texels",
]

FILTERS = (
    "point",
    "hw_pcf",
    "pcf",
    "poisson",
    "vsm",
    "evsm2",
    "evsm4",
    "three_pcf",
    "three_vsm",
)
MOMENT_FILTERS = ("vsm", "evsm2", "evsm4")

#: Largest EVSM exponent that does not overflow the moment format (MJP, Intel).
EVSM_MAX_EXPONENT = {"float32": 42.0, "float16": 5.54}


#: Lookups per Dr.Jit launch (bounded memory: a few hundred MiB at most).
DRJIT_CHUNK = 1 << 22


def upload_texels(depth_map: np.ndarray):
    """The Dr.Jit ``Float`` texels (flat, row-major) of a float32 ``(R, R)`` depth map, as
    the compare filters read them (:attr:`MapData.texels` of a rendered map)."""
    from ...scenes import backend

    mi = backend.mitsuba()
    return mi.Float(np.ascontiguousarray(depth_map, dtype=np.float32).ravel())


def _resolution(texels) -> int:
    import drjit as dr

    n = dr.width(texels)
    r = math.isqrt(n)
    if r * r != n:
        raise ValueError(f"texels must hold a square map, got {n} texels")
    return r


def compare_taps(texels, u, v, ref, size: int, *, address: str, subtexel_bits: int):
    """Depth compares of receivers at texture coordinates ``(u, v)`` against reference
    depths ``ref``: nearest texel (``size=0``) or ``size x size`` hardware-PCF taps one texel
    apart (``size=1``: one 2x2 hardware-PCF tap), float64 coordinates and weights against
    the float32 ``texels`` of an ``(R, R)`` map (:func:`upload_texels`).

    All taps of a lookup share the same sub-texel position, so the kernel is evaluated
    exactly on its ``(size + 1)^2`` texel footprint with separable tent weights (each texel
    compared once). All gathers, compares and weights of a chunk of :data:`DRJIT_CHUNK`
    lookups are one fused Dr.Jit kernel. Returns float64 visibility in [0, 1], shaped as
    ``u``.
    """
    from ...scenes import backend

    mi = backend.mitsuba()
    import drjit as dr

    r = _resolution(texels)
    f64, i32 = mi.Float64, mi.Int32
    # Resolution as a kernel parameter (not a literal): one compiled kernel per filter shape.
    r_i, r_f = dr.opaque(i32, r), dr.opaque(f64, float(r))
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ref = np.broadcast_to(np.asarray(ref, dtype=np.float64), u.shape)
    shape = u.shape
    single = 0 < u.size <= DRJIT_CHUNK
    out = None if single else np.empty(u.size, dtype=np.float64)
    u, v, ref = u.ravel(), v.ravel(), ref.ravel()
    # Index range that decides every fetch (clamp and border alike); keeps int32 safe.
    lo_idx = -float(size) - 2.0

    def fetch(ix, iy, rr):
        inside = (ix >= 0) & (ix < r_i) & (iy >= 0) & (iy < r_i)
        idx = dr.clip(iy, 0, r_i - 1) * r_i + dr.clip(ix, 0, r_i - 1)
        val = f64(dr.gather(mi.Float, texels, idx))
        if address == "border":
            val = dr.select(inside, val, 1.0)
        return dr.select(rr <= val, f64(1.0), f64(0.0))

    def sub(frac):
        if subtexel_bits <= 0:
            return frac
        scale = float(1 << subtexel_bits)
        return dr.round(frac * scale) / scale

    def weight(f, m):
        # Footprint texel m in 0..size gets (1 - f) from tap m and f from tap m - 1.
        w = f64(0.0)
        if m < size:
            w = w + (1.0 - f)
        if m > 0:
            w = w + f
        return w

    for start in range(0, u.size, DRJIT_CHUNK):
        sl = slice(start, min(u.size, start + DRJIT_CHUNK))
        # np.clip of the reference, bit for bit, in the kernel.
        uu, vv, rr = f64(u[sl]), f64(v[sl]), clip01_dr(mi, f64(ref[sl]))
        if size == 0:
            ix = i32(dr.clip(dr.floor(uu * r_f), lo_idx, r_f + 1.0))
            iy = i32(dr.clip(dr.floor(vv * r_f), lo_idx, r_f + 1.0))
            acc = fetch(ix, iy, rr)
        else:
            half = (size - 1) / 2.0
            # First tap centre, in texel units with texel centres at integers.
            x = uu * r_f - 0.5 - half
            y = vv * r_f - 0.5 - half
            x0, y0 = dr.floor(x), dr.floor(y)
            fx, fy = sub(x - x0), sub(y - y0)
            ix0 = i32(dr.clip(x0, lo_idx, r_f + 1.0))
            iy0 = i32(dr.clip(y0, lo_idx, r_f + 1.0))
            wx = [weight(fx, m) for m in range(size + 1)]
            acc = f64(0.0)
            for my in range(size + 1):
                row = f64(0.0)
                for mx in range(size + 1):
                    row = row + wx[mx] * fetch(ix0 + mx, iy0 + my, rr)
                acc = acc + weight(fy, my) * row
            acc = acc / float(size * size)
        dr.eval(acc)
        if single:
            return acc.numpy().reshape(shape)  # the kernel's own output (a view)
        out[sl] = acc.numpy()
    return out.reshape(shape)


def compare_point(texels, u, v, ref, *, address: str = "clamp") -> np.ndarray:
    """Nearest-texel depth compare: 1.0 where lit, 0.0 where shadowed."""
    return compare_taps(texels, u, v, ref, 0, address=address, subtexel_bits=0)


def compare_bilinear(texels, u, v, ref, *, address: str = "clamp", subtexel_bits: int = 8):
    """Hardware 2x2 PCF (compare four texels, then bilinear weights)."""
    return compare_taps(texels, u, v, ref, 1, address=address, subtexel_bits=subtexel_bits)


def _tap_ref(ref, du, dv, plane):
    if plane is None:
        return ref
    return ref + du * plane[0] + dv * plane[1]


def pcf_grid(
    texels, u, v, ref, size: int, *, address="clamp", subtexel_bits=8, plane=None
) -> np.ndarray:
    """``size x size`` hardware-PCF taps one texel apart (``plane``: receiver-plane slopes
    ``(dz/du, dz/dv)`` applied per tap, one 2x2 compare per tap; without it, one footprint
    kernel, :func:`compare_taps`)."""
    if plane is None:
        return compare_taps(texels, u, v, ref, size, address=address, subtexel_bits=subtexel_bits)
    r = _resolution(texels)
    offsets = (np.arange(size) - (size - 1) / 2.0) / r
    acc = np.zeros(np.shape(u), dtype=np.float64)
    for oy in offsets:
        for ox in offsets:
            acc += compare_bilinear(
                texels,
                u + ox,
                v + oy,
                _tap_ref(ref, ox, oy, plane),
                address=address,
                subtexel_bits=subtexel_bits,
            )
    return acc / float(size * size)


@lru_cache(maxsize=16)
def poisson_disc(taps: int, seed: int = 0) -> np.ndarray:
    """``taps`` points in the unit disc with a large minimum distance (seeded dart throwing).

    Deterministic for a given ``(taps, seed)``; ``(taps, 2)`` float64, radius <= 1.
    """
    rng = np.random.default_rng(seed + 7919 * taps)
    cand = rng.uniform(-1.0, 1.0, size=(20000, 2))
    cand = cand[np.einsum("ij,ij->i", cand, cand) <= 1.0]
    radius = 2.0 / np.sqrt(taps)
    while True:
        pts = [cand[0]]
        for c in cand[1:]:
            if np.min(np.sum((np.asarray(pts) - c) ** 2, axis=1)) >= radius * radius:
                pts.append(c)
                if len(pts) == taps:
                    return np.asarray(pts)
        radius *= 0.9


def pcf_poisson(
    texels,
    u,
    v,
    ref,
    *,
    taps: int,
    diameter: float,
    rotation: np.ndarray | None = None,
    address="clamp",
    subtexel_bits=8,
    plane=None,
    seed: int = 0,
) -> np.ndarray:
    """Poisson-disc PCF: ``taps`` hardware-PCF taps in a disc of ``diameter`` texels."""
    r = _resolution(texels)
    disc = poisson_disc(int(taps), int(seed)) * (0.5 * diameter / r)
    acc = np.zeros(np.shape(u), dtype=np.float64)
    if rotation is not None:
        c, s = np.cos(rotation), np.sin(rotation)
    for ox, oy in disc:
        if rotation is not None:
            dx, dy = c * ox - s * oy, s * ox + c * oy
        else:
            dx, dy = ox, oy
        acc += compare_bilinear(
            texels,
            u + dx,
            v + dy,
            _tap_ref(ref, dx, dy, plane),
            address=address,
            subtexel_bits=subtexel_bits,
        )
    return acc / float(len(disc))


# ---------------------------------------------------------------------- moment filters
def evsm_exponents(positive: float, negative: float, fmt: str, scale: float = 1.0):
    """Exponents actually used: ``min(c * scale, max)`` with the format's overflow limit."""
    cap = EVSM_MAX_EXPONENT[fmt]
    return min(positive * scale, cap), min(negative * scale, cap)


def _warp(d: np.ndarray, exponents) -> tuple[np.ndarray, np.ndarray]:
    d = 2.0 * d - 1.0
    return np.exp(exponents[0] * d), -np.exp(-exponents[1] * d)


def _moment_planes(depth_map: np.ndarray, kind: str, exponents) -> list[np.ndarray]:
    """The float64 ``(R, R)`` planes of :func:`moments_from_depth`, in channel order."""
    d = np.asarray(depth_map, dtype=np.float64)
    if kind == "vsm":
        return [d, d * d]
    pos, neg = _warp(d, exponents)
    if kind == "evsm2":
        return [pos, pos * pos]
    return [pos, pos * pos, neg, neg * neg]


def moments_from_depth(depth_map: np.ndarray, kind: str, exponents=(0.0, 0.0)) -> np.ndarray:
    """``(R, R, C)`` float64 moments: VSM ``(d, d^2)``, EVSM2 ``(p, p^2)``, EVSM4 adds
    ``(n, n^2)`` of the negative warp."""
    return np.stack(_moment_planes(depth_map, kind, exponents), axis=-1)


def blur_moments(moments: np.ndarray, size: int, fmt: str) -> np.ndarray:
    """Separable box blur of ``size`` texels (clamp to edge), stored in ``fmt``."""
    store = np.float16 if fmt == "float16" else np.float32
    m = moments.astype(store).astype(np.float64)
    if size > 1:
        m = ndimage.uniform_filter1d(m, size, axis=0, mode="nearest")
        m = m.astype(store).astype(np.float64)
        m = ndimage.uniform_filter1d(m, size, axis=1, mode="nearest")
    return m.astype(store)


#: Texels a band of :func:`moment_texture` works on at a time (float64 temporaries of about
#: 0.25 GiB for EVSM4): only the stored texture is whole, at any map size.
MOMENT_BAND_TEXELS = 1 << 23


def moment_texture(depth_map: np.ndarray, kind: str, exponents, size: int, fmt: str):
    """The stored moment texture, ``blur_moments(moments_from_depth(...))`` computed in
    bands (row bands for the warp and the horizontal pass, column bands for the vertical
    one), so memory is the ``(R, R, C)`` result plus one band: byte-identical to the
    whole-map computation, since each pass filters along one axis only."""
    store = np.float16 if fmt == "float16" else np.float32
    rows_n, cols_n = depth_map.shape
    channels = 2 if kind in ("vsm", "evsm2") else 4
    out = np.empty((rows_n, cols_n, channels), dtype=store)
    rows = max(1, MOMENT_BAND_TEXELS // max(cols_n, 1))
    cols = max(1, MOMENT_BAND_TEXELS // max(rows_n, 1))
    for y0 in range(0, rows_n, rows):
        # stacked straight into the stored type: no (rows, R, C) float64 stack to allocate
        # (the same float64 values, rounded to the store type once, as assigning them does)
        planes = _moment_planes(depth_map[y0 : y0 + rows], kind, exponents)
        np.stack(planes, axis=-1, out=out[y0 : y0 + rows])
    if size > 1:
        for axis, step, n in ((0, cols, cols_n), (1, rows, rows_n)):
            for a in range(0, n, step):
                band = (slice(None), slice(a, a + step)) if axis == 0 else slice(a, a + step)
                m = out[band].astype(np.float64)
                out[band] = ndimage.uniform_filter1d(m, size, axis=axis, mode="nearest")
    return out


def _subtexel(frac: np.ndarray, bits: int) -> np.ndarray:
    if bits <= 0:
        return frac
    scale = float(1 << bits)
    return np.round(frac * scale) / scale


def _bilinear(tex: np.ndarray, u, v, subtexel_bits: int) -> np.ndarray:
    """Bilinear sample of an ``(R, R, C)`` texture with clamp addressing -> ``(N, C)``."""
    r = tex.shape[0]
    x = np.asarray(u) * r - 0.5
    y = np.asarray(v) * r - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = _subtexel(x - x0, subtexel_bits)[:, None]
    fy = _subtexel(y - y0, subtexel_bits)[:, None]
    ix0 = np.clip(x0.astype(np.int64), 0, r - 1)
    iy0 = np.clip(y0.astype(np.int64), 0, r - 1)
    ix1 = np.clip(x0.astype(np.int64) + 1, 0, r - 1)
    iy1 = np.clip(y0.astype(np.int64) + 1, 0, r - 1)
    t = tex
    top = t[iy0, ix0].astype(np.float64) * (1 - fx) + t[iy0, ix1].astype(np.float64) * fx
    bot = t[iy1, ix0].astype(np.float64) * (1 - fx) + t[iy1, ix1].astype(np.float64) * fx
    return top * (1 - fy) + bot * fy


def bilinear_texture(tex: np.ndarray, u, v, subtexel_bits: int) -> np.ndarray:
    """Bilinear sample of an ``(R, R, C)`` texture with clamp addressing -> ``(N, C)``
    float64 (the moment filters' fetch, D3D's ``subtexel_bits`` weights)."""
    return _bilinear(tex, u, v, subtexel_bits)


def chebyshev(m1, m2, mean, min_variance, bleed_reduction) -> np.ndarray:
    """One-tailed Chebyshev upper bound with light-bleeding reduction (MJP's form)."""
    variance = np.maximum(m2 - m1 * m1, min_variance)
    d = mean - m1
    p = variance / (variance + d * d)
    if bleed_reduction > 0.0:
        p = np.clip((p - bleed_reduction) / (1.0 - bleed_reduction), 0.0, 1.0)
    return np.where(mean <= m1, 1.0, p)


def moment_lookup(
    moments: np.ndarray,
    u,
    v,
    depth,
    kind: str,
    *,
    exponents=(0.0, 0.0),
    min_variance: float,
    bleed_reduction: float,
    subtexel_bits: int = 8,
) -> np.ndarray:
    """Visibility from a moment map at receiver depths ``depth`` (normalized, clamped)."""
    s = _bilinear(moments, u, v, subtexel_bits)
    d = np.clip(np.asarray(depth, dtype=np.float64), 0.0, 1.0)
    if kind == "vsm":
        return chebyshev(s[:, 0], s[:, 1], d, min_variance, bleed_reduction)
    pos, neg = _warp(d, exponents)
    mv_pos = (min_variance * exponents[0] * pos) ** 2
    vis = chebyshev(s[:, 0], s[:, 1], pos, mv_pos, bleed_reduction)
    if kind == "evsm4":
        mv_neg = (min_variance * exponents[1] * neg) ** 2
        vis = np.minimum(vis, chebyshev(s[:, 2], s[:, 3], neg, mv_neg, bleed_reduction))
    return vis


def lookups_per_pixel(kind: str, *, pcf_size: int = 3, taps: int = 16) -> int:
    """Texture sample instructions one shadow lookup issues."""
    if kind == "pcf":
        return int(pcf_size) ** 2
    if kind == "poisson":
        return int(taps)
    if kind == "three_pcf":
        return 5
    return 1
