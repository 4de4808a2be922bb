"""Depth-buffer formats, their quantization, and depth bias as hardware and shaders apply it.

Normalized depth ``d`` is in ``[0, 1]`` (D3D: 0 at the near plane). Stored values
(:func:`quantize_dr`, on Dr.Jit values: the one implementation of the rule):

- ``D16``, ``D24``: UNORM, ``round(d * (2^n - 1)) / (2^n - 1)`` after clamping to [0, 1];
- ``D32F``: ``float32(d)``.

Hardware depth bias (D3D11 rasterizer, applied to every fragment written to the map):
``bias = DepthBias * r + SlopeScaledDepthBias * MaxDepthSlope``, clamped to
``DepthBiasClamp`` when that is non-zero; ``r = 1 / (2^n - 1)`` for an n-bit UNORM format
(D3D11 functional spec: the minimum representable value > 0 of the format) and
``2^(exponent(z) - 23)`` for D32F (exponent of the primitive's maximum depth; here of the
texel's own depth, a per-texel stand-in for the primitive's maximum). ``MaxDepthSlope`` is
``max(|dz/dx|, |dz/dy|)`` of the primitive in normalized depth per texel. The bias is added
to the fragment's depth before the viewport depth clamp to ``[0, 1]`` (D3D11 order: bias,
then clamp), see :func:`raster_models.shadowmaps.depth_dr.stored_depth_dr`.

Shader-side biases (constant, receiver-plane, normal offset) live in
:mod:`raster_models.shadowmaps.shade`.

Rasterized depth (:func:`window_vertices`, :func:`plane_setup`, :func:`plane_eval`): what a
rasterizer's depth test compares is not the exact depth of the surface under a sample but
the triangle's screen-space depth plane, set up from its float32 window-space vertices and
evaluated at the sample position in float32 (Mesa llvmpipe's setup: ``a0 = z0 - (dzdx x0 +
dzdy y0)``, then ``a0 + dzdx x + dzdy y``). Coplanar triangles with different vertices get
planes that differ in their last bits, so they tie on some samples, not all.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FORMATS",
    "MAX_DEPTH_SLOPE",
    "bytes_per_texel",
    "clip01_dr",
    "hardware_bias",
    "plane_eval",
    "plane_setup",
    "quantize_dr",
    "window_vertices",
]

#: Format name -> (kind, bits).
FORMATS = {"D16": ("unorm", 16), "D24": ("unorm", 24), "D32F": ("float", 32)}

#: Largest MaxDepthSlope used when a surface is almost parallel to the light (the slope is
#: then infinite in theory; a rasterizer never produces fragments of a zero-area triangle).
MAX_DEPTH_SLOPE = 1e3


def clip01_dr(mi, x):
    """``np.clip(x, 0.0, 1.0)`` bit for bit on a Dr.Jit ``Float64``: NaN and ``-0.0`` pass
    through unchanged.

    "Below zero" is read from the bits (sign set, not ``-0.0``, not NaN): the LLVM backend
    treats subnormal inputs as zero in comparisons, NumPy does not."""
    import drjit as dr

    bits = dr.reinterpret_array(mi.Int64, x)
    below = (bits < 0) & (bits != dr.opaque(mi.Int64, -(1 << 63))) & ~dr.isnan(x)
    x = dr.select(below, 0.0, x)
    return dr.select((x <= 1.0) | dr.isnan(x), x, 1.0)


def quantize_dr(mi, d, fmt: str):
    """Stored depth of normalized depths ``d`` in format ``fmt`` (Dr.Jit ``Float64`` in and
    out): the one implementation of the format rule, used by the shadow maps' texels
    (:func:`raster_models.shadowmaps.depth_dr.stored_depth_dr`) and ACAA's depth tests.

    UNORM: ``round(clip(d, 0, 1) * (2^n - 1)) / (2^n - 1)`` (round half to even; every step
    one IEEE float64 operation, nothing an FMA could contract). D32F: ``float32(d)`` (no
    clamp), returned as float64, with a float32 subnormal (magnitude in ``(0, 2^-126)``)
    stored as ``+-0``: D3D's floating-point rules flush denormals on output. The flush is
    done on the bits, so every backend stores the same: the LLVM backend's conversion
    flushes by itself, CUDA's (``cvt.rn.f32.f64``) keeps the subnormal, as NumPy does
    (three D32F cases differed on an H200 before).
    """
    import drjit as dr

    kind, bits = FORMATS[fmt]
    if kind == "unorm":
        scale = dr.opaque(mi.Float64, float((1 << bits) - 1))
        return dr.round(clip01_dr(mi, d) * scale) / scale
    single = mi.Float32(d)
    raw = dr.reinterpret_array(mi.UInt32, single)
    magnitude = raw & 0x7FFFFFFF
    flushed = dr.select((magnitude != 0) & (magnitude < 0x00800000), raw & 0x80000000, raw)
    return mi.Float64(dr.reinterpret_array(type(single), flushed))


def hardware_bias(
    d: np.ndarray,
    max_slope: np.ndarray | None,
    fmt: str,
    *,
    depth_bias: int,
    slope_scaled: float,
    clamp: float,
) -> np.ndarray:
    """D3D11 rasterizer depth bias for fragments at normalized depth ``d``."""
    kind, bits = FORMATS[fmt]
    d = np.asarray(d, dtype=np.float64)
    if kind == "unorm":
        r = np.full_like(d, 1.0 / float((1 << bits) - 1))
    else:
        a = np.abs(d)
        safe = np.where(a > 0.0, a, 1.0)
        r = np.where(a > 0.0, np.exp2(np.floor(np.log2(safe)) - 23.0), 2.0**-149)
    bias = depth_bias * r
    if slope_scaled != 0.0 and max_slope is not None:
        bias = bias + slope_scaled * np.minimum(max_slope, MAX_DEPTH_SLOPE)
    if clamp > 0.0:
        bias = np.minimum(bias, clamp)
    elif clamp < 0.0:
        bias = np.maximum(bias, clamp)
    return bias


def bytes_per_texel(fmt: str) -> int:
    """Bytes of one depth texel (D24 is stored as D24S8, 4 bytes)."""
    return {"D16": 2, "D24": 4, "D32F": 4}[fmt]


def window_vertices(camera, verts: np.ndarray):
    """Window-space ``(x, y, z)`` float32 arrays and clip ``w`` of world vertices ``(..., 3)``
    as a float32 vertex pipeline computes them: the D3D-style view-projection matrix
    (depth in ``[0, 1]``, :meth:`scenes.camera.Camera.projection`) rounded to float32, the
    product, the perspective divide and the viewport (film pixels, y down)."""
    m = (camera.projection("direct3d") @ camera.world_to_view("direct3d")).astype(np.float32)
    v = np.asarray(verts, np.float32)
    clip = [
        v[..., 0] * m[r, 0] + v[..., 1] * m[r, 1] + v[..., 2] * m[r, 2] + m[r, 3] for r in range(4)
    ]
    w = clip[3]
    safe = np.where(w != 0, w, np.float32(1.0))
    half_w, half_h = np.float32(camera.width / 2), np.float32(camera.height / 2)
    x = (clip[0] / safe + np.float32(1.0)) * half_w
    y = (np.float32(1.0) - clip[1] / safe) * half_h
    return x, y, clip[2] / safe, w


def plane_setup(x, y, z):
    """Depth planes of triangles from their window vertices (``(T, 3)`` float32 each):
    ``(a0, dzdx, dzdy, ok)``, float32, ``ok`` False where the triangle has no area on
    screen. Every step one float32 operation, as a rasterizer's triangle setup."""
    f = np.float32
    x, y, z = (np.asarray(a, f) for a in (x, y, z))
    dx10, dy10, dz10 = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0], z[:, 1] - z[:, 0]
    dx20, dy20, dz20 = x[:, 2] - x[:, 0], y[:, 2] - y[:, 0], z[:, 2] - z[:, 0]
    det = dx10 * dy20 - dx20 * dy10
    ok = det != 0
    inv = np.where(ok, det, f(1.0))
    dzdx = (dz10 * dy20 - dz20 * dy10) / inv
    dzdy = (dx10 * dz20 - dx20 * dz10) / inv
    a0 = z[:, 0] - (dzdx * x[:, 0] + dzdy * y[:, 0])
    return a0, dzdx, dzdy, ok


def plane_eval(a0, dzdx, dzdy, sx, sy) -> np.ndarray:
    """Depth planes evaluated at sample positions ``(sx, sy)`` (film pixels), float32:
    ``(a0 + dzdx sx) + dzdy sy``."""
    f = np.float32
    return (f(a0) + f(dzdx) * f(sx)) + f(dzdy) * f(sy)
