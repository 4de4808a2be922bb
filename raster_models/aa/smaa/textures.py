"""SMAA's two precomputed textures, built by this project from the published construction.

``area_texture()``: the ``AreaTexDX10`` texture, 160 columns x 560 rows, two channels (R, G:
the areas above and below the revectorised line, as ``uint8`` = ``int(255 * area)``). Seven
80-row bands hold the orthogonal patterns for the seven sub-sample offsets
(:data:`SUBSAMPLE_OFFSETS_ORTHO`) in columns 0-79; the first five bands hold the diagonal
patterns for :data:`SUBSAMPLE_OFFSETS_DIAG` in columns 80-159. Inside a band each of the
16 crossing-edge patterns owns a 16 x 16 (orthogonal, distances compressed quadratically:
texel ``(l, r)`` holds distances ``(l**2, r**2)``) or 20 x 20 (diagonal) block; texels that
no pattern owns are 0.

``search_texture()``: the ``SearchTex`` texture, 64 columns x 16 rows, one channel: how far
(0, 1 or 2 pixels, stored as 0, 127, 254) the last step of an orthogonal search must go
back, indexed by the bilinearly fetched edge values (left half: searches to the left;
right half: to the right; cropped and flipped vertically).

Both follow ``Scripts/AreaTex.py`` and ``Scripts/SearchTex.py`` of the reference
implementation operation for operation in float64 (the same IEEE operations in the same
order, so the bytes are the published ones), vectorised over all texels: the diagonal areas
are brute-force 30 x 30 sample counts. SHA-256 of the bytes in row-major order:
:data:`AREA_SHA256`, :data:`SEARCH_SHA256` (the digests of the published ``AreaTex.h`` and
``SearchTex.h``). The area texture takes a few seconds and is cached in memory.

References
----------
J. Jimenez, J. I. Echevarria, T. Sousa, D. Gutierrez, SMAA: Enhanced Subpixel Morphological
Antialiasing, Computer Graphics Forum 31(2) (Eurographics 2012),
doi:10.1111/j.1467-8659.2012.03014.x.
J. Jimenez et al., SMAA reference implementation (``iryoku/smaa``: ``Scripts/AreaTex.py``,
``Scripts/SearchTex.py``, ``SMAA.hlsl``), 2013.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = [
    "AREA_SHA256",
    "SEARCH_SHA256",
    "SUBSAMPLE_OFFSETS_DIAG",
    "SUBSAMPLE_OFFSETS_ORTHO",
    "area_ortho",
    "area_texture",
    "search_texture",
]

#: SHA-256 of the published ``AreaTex.h`` bytes (R8G8, 160 x 560, row 0 first).
AREA_SHA256 = "35065cef2a02cabcad711d6bf430239ae64e27d71c4e4fa06f29cce2c992f0d2"
#: SHA-256 of the published ``SearchTex.h`` bytes (R8, 64 x 16, row 0 first).
SEARCH_SHA256 = "3694eae5e9d44b8ebb4415a13f8c7b94dc08a2fc86658434d771c4610fe5744d"

#: Sub-sample offsets of the orthogonal bands (``AreaTex.py``), band index = offset index.
SUBSAMPLE_OFFSETS_ORTHO = (0.0, -0.25, 0.25, -0.125, 0.125, -0.375, 0.375)
#: Sub-sample offsets of the diagonal bands (``AreaTex.py``).
SUBSAMPLE_OFFSETS_DIAG = (
    (0.0, 0.0),
    (0.25, -0.25),
    (-0.25, 0.25),
    (0.125, -0.125),
    (-0.125, 0.125),
)

SIZE_ORTHO = 16  # texels per orthogonal pattern block side (5 x 16 = 80)
SIZE_DIAG = 20  # texels per diagonal pattern block side (4 x 20 = 80)
SAMPLES_DIAG = 30  # brute-force samples per side of a diagonal pixel
SMOOTH_MAX_DISTANCE = 32  # U-patterns shorter than this are smoothed

# where each crossing-edge pattern's block lies, in blocks (column, row) (AreaTex.py)
EDGES_ORTHO = (
    (0, 0), (3, 0), (0, 3), (3, 3), (1, 0), (4, 0), (1, 3), (4, 3),
    (0, 1), (3, 1), (0, 4), (3, 4), (1, 1), (4, 1), (1, 4), (4, 4),
)  # fmt: skip
EDGES_DIAG = (
    (0, 0), (1, 0), (0, 2), (1, 2), (2, 0), (3, 0), (2, 2), (3, 2),
    (0, 1), (1, 1), (0, 3), (1, 3), (2, 1), (3, 1), (2, 3), (3, 3),
)  # fmt: skip


# ----------------------------------------------------------------------------- orthogonal
def _area_line(p1, p2, x):
    """Areas (below, above) the line ``p1 -> p2`` inside pixel column ``[x, x + 1)``:
    ``AreaTex.py``'s ``area`` on arrays (``p1``, ``p2``: pairs of scalars or arrays)."""
    x = np.asarray(x, np.float64)
    d0, d1 = p2[0] - p1[0], p2[1] - p1[1]
    x1 = x.astype(np.float64)
    x2 = x + 1.0
    y1 = p1[1] + d1 * (x1 - p1[0]) / d0
    y2 = p1[1] + d1 * (x2 - p1[0]) / d0
    inside = ((x1 >= p1[0]) & (x1 < p2[0])) | ((x2 > p1[0]) & (x2 <= p2[0]))
    trapezoid = (
        (np.copysign(1.0, y1) == np.copysign(1.0, y2)) | (np.abs(y1) < 1e-4) | (np.abs(y2) < 1e-4)
    )
    a = (y1 + y2) / 2.0
    trap = (np.where(a < 0.0, np.abs(a), 0.0), np.where(a < 0.0, 0.0, np.abs(a)))
    # two triangles: the line crosses y = 0 at xc inside the pixel
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = -p1[1] * d0 / d1 + p1[0]
    frac = np.modf(xc)[0]
    a1 = np.where(xc > p1[0], y1 * frac / 2.0, 0.0)
    a2 = np.where(xc < p2[0], y2 * (1.0 - frac) / 2.0, 0.0)
    neg = np.where(np.abs(a1) > np.abs(a2), a1, -a2) < 0.0
    tri = (
        np.where(neg, np.abs(a1), np.abs(a2)),
        np.where(neg, np.abs(a2), np.abs(a1)),
    )
    out = [np.where(trapezoid, t, r) for t, r in zip(trap, tri, strict=True)]
    return tuple(np.where(inside, o, 0.0) for o in out)


def _smooth(d, a1, a2):
    """``AreaTex.py``'s ``smootharea``: short U-patterns get sqrt-softened areas."""
    p = np.clip(d / float(SMOOTH_MAX_DISTANCE), 0.0, 1.0)
    out = []
    for a in (a1, a2):
        b = tuple(np.sqrt(v * 2.0) * 0.5 for v in a)
        out.append(tuple(bv + p * (av - bv) for av, bv in zip(a, b, strict=True)))
    return out


def _add(a, b):
    return (a[0] + b[0], a[1] + b[1])


def area_ortho(pattern: int, left, right, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Areas (R, G) of orthogonal crossing-edge ``pattern`` (0-15) at distances ``left``,
    ``right`` (pixels, arrays of equal shape) for sub-sample ``offset`` (pixels).

    ``AreaTex.py``'s ``areaortho``: the pattern's end points are joined by a revectorised line
    through the middle of the edge (Z and L shapes, U shapes smoothed), and each pixel gets
    the area between that line and the edge, split into the part above and below.
    """
    left = np.asarray(left, np.float64)
    right = np.asarray(right, np.float64)
    zero = (np.zeros_like(left), np.zeros_like(left))
    d = left + right + 1
    o1 = 0.5 + offset
    o2 = 0.5 + offset - 1.0
    half = (d / 2.0, 0.0)

    def when(cond, a):
        return tuple(np.where(cond, v, 0.0) for v in a)

    def z_blend(start, end):
        # Z patterns: with an offset, the full Z blended with two offset L halves
        full = _area_line(start, end, left)
        if abs(offset) > 0.0:
            halves = _add(_area_line(start, half, left), _area_line(half, end, left))
            return tuple((f + h) / 2.0 for f, h in zip(full, halves, strict=True))
        return full

    def u_shape(o):
        a1, a2 = _smooth(d, _area_line((0.0, o), half, left), _area_line(half, (d, o), left))
        return (a1[0] + a2[0], a1[1] + a2[1])

    if pattern in (0, 5, 10, 15):
        return zero
    if pattern == 1:
        return when(left <= right, _area_line((0.0, o2), half, left))
    if pattern == 2:
        return when(left >= right, _area_line(half, (d, o2), left))
    if pattern == 3:
        return u_shape(o2)
    if pattern == 4:
        return when(left <= right, _area_line((0.0, o1), half, left))
    if pattern == 6:
        return z_blend((0.0, o1), (d, o2))
    if pattern in (7, 14):
        return _area_line((0.0, o1), (d, o2), left)
    if pattern == 8:
        return when(left >= right, _area_line(half, (d, o1), left))
    if pattern == 9:
        return z_blend((0.0, o2), (d, o1))
    if pattern in (11, 13):
        return _area_line((0.0, o2), (d, o1), left)
    if pattern == 12:
        return u_shape(o1)
    raise ValueError(f"pattern must be in 0..15, got {pattern!r}")


# ----------------------------------------------------------------------------- diagonal
# the line end points of each diagonal pattern, before the (d, d) shift of the second point:
# one pair, or two pairs whose areas are averaged (AreaTex.py's "black magic" blends)
_DIAG_LINES = {
    0: (((1, 1), (1, 1)), ((1, 0), (1, 0))),
    1: (((1, 0), (0, 0)), ((1, 0), (1, 0))),
    2: (((0, 0), (1, 0)), ((1, 0), (1, 0))),
    3: (((1, 0), (1, 0)),),
    4: (((1, 1), (0, 0)), ((1, 1), (1, 0))),
    5: (((1, 1), (0, 0)), ((1, 0), (1, 0))),
    6: (((1, 1), (1, 0)),),
    7: (((1, 1), (1, 0)), ((1, 0), (1, 0))),
    8: (((0, 0), (1, 1)), ((1, 0), (1, 1))),
    9: (((1, 0), (1, 1)),),
    10: (((0, 0), (1, 1)), ((1, 0), (1, 0))),
    11: (((1, 0), (1, 1)), ((1, 0), (1, 0))),
    12: (((1, 1), (1, 1)),),
    13: (((1, 1), (1, 1)), ((1, 0), (1, 1))),
    14: (((1, 1), (1, 1)), ((1, 1), (1, 0))),
    15: (((1, 1), (1, 1)), ((1, 0), (1, 0))),
}


def _area_diag_pixel(p1, p2, px, py):
    """Fraction of the 30 x 30 samples of the pixel at (``px``, ``py``) (arrays) on the
    positive side of the line ``p1 -> p2`` (arrays (x, y)); ``AreaTex.py``'s ``area1``."""
    o = np.arange(SAMPLES_DIAG, dtype=np.float64) / float(SAMPLES_DIAG - 1)
    x = px[..., None, None] + o[:, None]  # sample x varies with the first loop index
    y = py[..., None, None] + o[None, :]
    xm = ((p1[0] + p2[0]) / 2.0)[..., None, None]
    ym = ((p1[1] + p2[1]) / 2.0)[..., None, None]
    a = (p2[1] - p1[1])[..., None, None]
    b = (p1[0] - p2[0])[..., None, None]
    c = a * (x - xm) + b * (y - ym)
    same = ((p1[0] == p2[0]) & (p1[1] == p2[1]))[..., None, None]
    count = np.count_nonzero((c > 0) | same, axis=(-2, -1)).astype(np.float64)
    return count / (SAMPLES_DIAG * SAMPLES_DIAG)


def _area_diag(pattern: int, left, right, offset) -> tuple[np.ndarray, np.ndarray]:
    """``AreaTex.py``'s ``areadiag`` for arrays ``left``, ``right`` (pixels)."""
    left = np.asarray(left, np.float64)
    d = left + np.asarray(right, np.float64) + 1
    e1, e2 = EDGES_DIAG[pattern]
    results = []
    for s, t in _DIAG_LINES[pattern]:
        p1 = (np.full_like(d, float(s[0])), np.full_like(d, float(s[1])))
        p2 = (float(t[0]) + d, float(t[1]) + d)
        if e1 > 0:
            p1 = (p1[0] + offset[0], p1[1] + offset[1])
        if e2 > 0:
            p2 = (p2[0] + offset[0], p2[1] + offset[1])
        a1 = _area_diag_pixel(p1, p2, 1.0 + left, 0.0 + left)
        a2 = _area_diag_pixel(p1, p2, 1.0 + left, 1.0 + left)
        results.append((1.0 - a1, a2))
    if len(results) == 1:
        return results[0]
    (u0, u1), (v0, v1) = results
    return ((u0 + v0) / 2.0, (u1 + v1) / 2.0)


# ----------------------------------------------------------------------------- assembly
def _to_byte(a: np.ndarray) -> np.ndarray:
    # int(255.0 * a): truncation, as the published script converts
    return np.trunc(255.0 * a).astype(np.uint8)


@functools.lru_cache(maxsize=1)
def _area_texture() -> np.ndarray:
    tex = np.zeros((560, 160, 2), np.uint8)
    lr = np.arange(SIZE_ORTHO)
    right, left = np.meshgrid(lr, lr, indexing="ij")  # [row = right, column = left]
    for band, offset in enumerate(SUBSAMPLE_OFFSETS_ORTHO):
        for pattern in range(16):
            # the texture compresses distances quadratically: texel (l, r) holds (l^2, r^2)
            a = area_ortho(pattern, left**2, right**2, offset)
            col, row = EDGES_ORTHO[pattern]
            r0 = 5 * SIZE_ORTHO * band + SIZE_ORTHO * row
            c0 = SIZE_ORTHO * col
            tex[r0 : r0 + SIZE_ORTHO, c0 : c0 + SIZE_ORTHO] = np.stack(
                [_to_byte(a[0]), _to_byte(a[1])], axis=-1
            )
    lr = np.arange(SIZE_DIAG)
    right, left = np.meshgrid(lr, lr, indexing="ij")
    for band, offset in enumerate(SUBSAMPLE_OFFSETS_DIAG):
        for pattern in range(16):
            a = _area_diag(pattern, left, right, offset)
            col, row = EDGES_DIAG[pattern]
            r0 = 4 * SIZE_DIAG * band + SIZE_DIAG * row
            c0 = 5 * SIZE_ORTHO + SIZE_DIAG * col
            tex[r0 : r0 + SIZE_DIAG, c0 : c0 + SIZE_DIAG] = np.stack(
                [_to_byte(a[0]), _to_byte(a[1])], axis=-1
            )
    tex.setflags(write=False)
    return tex


def area_texture() -> np.ndarray:
    """The SMAA area texture: ``(560, 160, 2)`` uint8, row 0 first (read-only, cached).

    Equal byte for byte to the published ``AreaTexDX10`` (SHA-256 :data:`AREA_SHA256`).
    """
    return _area_texture()


def _bilinear_key(e) -> float:
    # SearchTex.py's bilinear(): the value a fetch at (-0.25, -0.125) returns for edges e
    a = e[0] + (e[1] - e[0]) * (1.0 - 0.25)
    b = e[2] + (e[3] - e[2]) * (1.0 - 0.25)
    return a + (b - a) * (1.0 - 0.125)


@functools.lru_cache(maxsize=1)
def _search_texture() -> np.ndarray:
    combos = np.array([[(i >> k) & 1 for k in (3, 2, 1, 0)] for i in range(16)])
    # the reverse lookup: texcoord 0.03125 * k -> edges, for the 33 texcoords that are keys
    keys = {_bilinear_key(c.tolist()): c for c in combos}
    lookup = np.full((33, 4), -1)
    for k in range(33):
        if 0.03125 * k in keys:
            lookup[k] = keys[0.03125 * k]
    known = lookup[:, 0] >= 0
    # [row y (top edges), column x (left edges)]
    top = lookup[:, None, :]
    left = lookup[None, :, :]
    ok = known[:, None] & known[None, :]
    t3, t2 = top[..., 3] == 1, top[..., 2] == 1
    l0, l1, l2, l3 = (left[..., i] == 1 for i in range(4))
    d_left = t3.astype(int) + (t3 & t2 & ~l1 & ~l3)
    first = t3 & ~l1 & ~l3
    d_right = first.astype(int) + (first & t2 & ~l0 & ~l2)
    image = np.zeros((33, 66), np.uint8)
    image[:, :33] = np.where(ok, 127 * d_left, 0)
    image[:, 33:] = np.where(ok, 127 * d_right, 0)
    tex = np.ascontiguousarray(image[17:33, 0:64][::-1])  # crop to 64 x 16, flip vertically
    tex.setflags(write=False)
    return tex


def search_texture() -> np.ndarray:
    """The SMAA search texture: ``(16, 64)`` uint8, row 0 first (read-only, cached).

    Equal byte for byte to the published ``SearchTex`` (SHA-256 :data:`SEARCH_SHA256`).
    """
    return _search_texture()
