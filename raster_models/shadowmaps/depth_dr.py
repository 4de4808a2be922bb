"""The texels a rasterizer stores in a shadow map, on Dr.Jit: the hardware depth bias added
first, then the viewport clamp to [0, 1] (D3D11 order: a pancaked caster in front of the
near plane ends at 0 whatever its bias), then the depth format's quantization
(:func:`raster_models.depth.quantize_dr`, the one implementation of the rule), stored as
float32.

For a constant bias (:func:`fused_bias`) this runs in the kernel that casts the texels'
rays; a per-texel bias (slope-scaled, or D32F's exponent-scaled ``DepthBias``) is computed
by :func:`raster_models.depth.hardware_bias` and passed as an array.

Every step is one IEEE float64 operation (an add, a clamp, a multiply, round-half-even and a
divide: nothing an FMA could contract), and the clamp
(:func:`raster_models.depth.clip01_dr`) is written with selects that reproduce ``np.clip``
exactly (``-0.0`` kept, NaN propagated), so the stored bytes equal the NumPy reference in
``tests/test_shadow_speed_paths.py`` on random and edge inputs for every format.
"""

from __future__ import annotations

import numpy as np

from .. import depth as _depth

__all__ = ["fused_bias", "stored_depth_dr"]


def fused_bias(fmt: str, *, depth_bias: int, slope_scaled: float, clamp: float) -> float | None:
    """The constant hardware bias every texel of a map gets, or ``None`` when the bias
    varies per texel (a slope-scaled bias, or a D32F ``DepthBias`` that scales with each
    texel's exponent): those maps pass a per-texel bias to :func:`stored_depth_dr`.

    ``0.0`` means no bias at all (nothing is added)."""
    if slope_scaled != 0.0:
        return None
    if depth_bias == 0:
        return 0.0
    kind, _ = _depth.FORMATS[fmt]
    if kind != "unorm":
        return None
    # The per-texel rule on one texel: the UNORM bias does not depend on depth.
    bias = _depth.hardware_bias(
        np.zeros(1), None, fmt, depth_bias=depth_bias, slope_scaled=0.0, clamp=clamp
    )
    return float(bias[0])


def stored_depth_dr(mi, z, fmt: str, bias):
    """Stored float32 texels and the hit mask of unclamped normalized depths ``z``
    (Dr.Jit ``Float64``; ``inf`` on a miss).

    ``bias``: the constant of :func:`fused_bias` (a float; ``0.0``: none added) or a
    per-texel Dr.Jit ``Float64`` array (always added). Misses store 1.0.
    """
    import drjit as dr

    hit = dr.isfinite(z)
    d = dr.select(hit, z, 1.0)
    if isinstance(bias, float):
        if bias != 0.0:
            d = d + dr.opaque(mi.Float64, bias)
    else:
        d = d + bias
    d = _depth.quantize_dr(mi, _depth.clip01_dr(mi, d), fmt)
    return mi.Float32(dr.select(hit, d, 1.0)), hit
