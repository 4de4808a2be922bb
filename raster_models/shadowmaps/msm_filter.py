"""Moment shadow maps (Peters and Klein 2015): four moments of depth, filtered like VSM, and
the Hamburger 4MSM reconstruction (the sharpest lower bound of the shadow intensity that the
four moments allow, from a three-point distribution).

- Moments ``b = (d, d^2, d^3, d^4)`` of the stored normalized depth ``d`` in [0, 1], box
  blurred (``blur_size`` texels), stored either as float32 or in 16-bit UNORM after the
  paper's optimized quantization: ``q = M b + (0.035955884801, 0, 0, 0)`` (section 4, with
  the inverse applied after the bilinear fetch). The matrices are those of the paper as
  transcribed in Unity HDRP 10.10.1 ``Runtime/Lighting/Shadow/ShadowMoments.hlsl`` lines
  55-67 and 70-79 (``ShadowMoments_Encode16MSM`` / ``Decode16MSM``).
- Moment bias: ``b' = (1 - alpha) b + alpha (0.5, 0.5, 0.5, 0.5)`` before the solve (the
  rounding errors of the quantization otherwise make the Hankel matrix indefinite).
- Hamburger 4MSM (paper, algorithm 3; HDRP ``ShadowMoments_SolveMSM`` lines 82-113 and
  ``SolveDelta3MSM`` lines 115-125): a Cholesky solve of the Hankel system for the
  quadratic whose roots ``z2 <= z3`` complete the support ``{z_r, z2, z3}``; the shadow
  intensity is the weight of the support points nearer than the receiver.
- Light-bleeding reduction (HDRP ``lightLeakBias``): ``linstep(bias, 1, visibility)``.

References
----------
.. [1] C. Peters, R. Klein, "Moment Shadow Mapping", I3D 2015. DOI: 10.1145/2699276.2699277
.. [2] Unity Technologies, HDRP 10.10.1 ``Runtime/Lighting/Shadow/ShadowMoments.hlsl`` (lines
   cited above); published package mirror needle-mirror/com.unity.render-pipelines.high-
   definition, commit 6328cc84.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from . import filters as _filters

__all__ = [
    "DEPTHS",
    "DECODE_16",
    "ENCODE_16",
    "ENCODE_OFFSET",
    "MSM_FORMATS",
    "decode16",
    "encode16",
    "hamburger_4msm",
    "msm_lookup",
    "msm_texture",
    "raw_moments",
]

#: Moment storage: ``unorm16`` (the paper's 64 bits a texel with the optimized quantization)
#: or ``float32`` (128 bits, no quantization).
MSM_FORMATS = ("unorm16", "float32")

#: The paper's quantization matrix, applied as ``q = b @ ENCODE_16`` (HDRP's
#: ``mul(moments, mat)``, HDRP 10.10.1 ShadowMoments.hlsl lines 59-62).
ENCODE_16 = np.array(
    [
        [-2.07224649, 13.7948857237, 0.105877704, 9.7924062118],
        [32.23703778, -59.4683975703, -1.9077466311, -33.7652110555],
        [-68.571074599, 82.0359750338, 9.3496555107, 47.9456096605],
        [39.3703274134, -35.364903257, -6.6543490743, -23.9728048165],
    ],
    dtype=np.float64,
)

#: Its inverse as published (HDRP lines 73-76), applied as ``b = (q - offset) @ DECODE_16``.
DECODE_16 = np.array(
    [
        [0.2227744146, 0.1549679261, 0.1451988946, 0.163127443],
        [0.0771972861, 0.1394629426, 0.2120202157, 0.2591432266],
        [0.7926986636, 0.7963415838, 0.7258694464, 0.6539092497],
        [0.0319417555, -0.1722823173, -0.2758014811, -0.3376131734],
    ],
    dtype=np.float64,
)

#: Offset added to the first quantized moment (HDRP line 65).
ENCODE_OFFSET = 0.035955884801

#: Depth the moments are taken of: the map's stored depth, or linear light-view distance
#: normalized between the near and far planes (the same for orthographic maps).
DEPTHS = ("stored", "linear")

#: Levels of a 16-bit UNORM channel.
UNORM16 = 65535.0


def raw_moments(depth) -> np.ndarray:
    """``(..., 4)`` float64 moments ``(d, d^2, d^3, d^4)`` of depths ``d``."""
    d = np.asarray(depth, dtype=np.float64)
    d2 = d * d
    return np.stack([d, d2, d2 * d, d2 * d2], axis=-1)


def encode16(moments: np.ndarray) -> np.ndarray:
    """The optimized quantization's linear map (before rounding to 16 bits)."""
    q = np.asarray(moments, dtype=np.float64) @ ENCODE_16
    q[..., 0] += ENCODE_OFFSET
    return q


def decode16(q: np.ndarray) -> np.ndarray:
    """Moments back from quantized values (the published inverse)."""
    q = np.array(q, dtype=np.float64)
    q[..., 0] -= ENCODE_OFFSET
    return q @ DECODE_16


def msm_texture(depth_map: np.ndarray, blur_size: int, fmt: str) -> np.ndarray:
    """The stored ``(R, R, 4)`` moment texture: moments, box blur (clamp to edge), then
    float32 or the 16-bit UNORM quantization (values ``k / 65535`` held as float32, which
    represents each exactly)."""
    m = raw_moments(depth_map)
    if blur_size > 1:
        m = ndimage.uniform_filter1d(m, blur_size, axis=0, mode="nearest")
        m = ndimage.uniform_filter1d(m, blur_size, axis=1, mode="nearest")
    if fmt == "float32":
        return m.astype(np.float32)
    q = np.clip(encode16(m), 0.0, 1.0)
    return (np.round(q * UNORM16) / UNORM16).astype(np.float32)


def moment_depth(proj, depth, kind: str) -> np.ndarray:
    """The depth moments are taken of: ``depth`` itself (``stored``), or for a perspective
    map with ``linear``, ``(tau - near) / (far - near)`` of its light-view distance ``tau``
    (hyperbolic depth crowds most of a scene into the top 1 % of [0, 1], below the 16-bit
    quantization's resolution)."""
    d = np.asarray(depth, dtype=np.float64)
    if kind == "stored" or proj is None or proj.kind != "persp":
        return d
    _, near, far = (float(x) for x in proj.extent)
    a, b = far / (far - near), far * near / (far - near)
    with np.errstate(divide="ignore"):
        tau = b / np.maximum(a - d, 1e-300)
    return np.clip((tau - near) / (far - near), 0.0, 1.0)


def hamburger_4msm(b: np.ndarray, z, moment_bias: float) -> np.ndarray:
    """Shadow intensity in [0, 1] (1 = fully shadowed) at receiver depths ``z`` from
    filtered moments ``b`` ``(N, 4)``: the Hamburger 4MSM lower bound after the moment bias.

    Degenerate systems (a singular Hankel matrix: unbiased moments of one depth) resolve to
    the step at that depth: shadowed where ``z > b1``.
    """
    b = np.asarray(b, dtype=np.float64)
    b = (1.0 - moment_bias) * b + moment_bias * 0.5
    z0 = np.asarray(z, dtype=np.float64)
    b1, b2, b3, b4 = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        l32d22 = b3 - b1 * b2
        d22 = b2 - b1 * b1
        sq_var = b4 - b2 * b2
        d33d22 = sq_var * d22 - l32d22 * l32d22
        inv_d22 = 1.0 / d22
        l32 = l32d22 * inv_d22
        c1 = z0 - b1
        c2 = z0 * z0 - (b2 + l32 * c1)
        c1 = c1 * inv_d22
        c2 = c2 * (d22 / d33d22)
        c1 = c1 - l32 * c2
        c0 = 1.0 - (c1 * b1 + c2 * b2)
        p = c1 / c2
        q = c0 / c2
        r = np.sqrt(np.maximum(p * p * 0.25 - q, 0.0))
        z1 = -0.5 * p - r
        z2 = -0.5 * p + r
        # Three-point solution: which support points lie in front of the receiver.
        s0 = np.where(z2 < z0, z1, np.where(z1 < z0, z0, 0.0))
        s1 = np.where(z2 < z0, z0, np.where(z1 < z0, z1, 0.0))
        s2 = np.where(z2 < z0, 1.0, 0.0)
        s3 = np.where((z2 < z0) | (z1 < z0), 1.0, 0.0)
        quotient = (s0 * z2 - b1 * (s0 + z2) + b2) / ((z2 - s1) * (z0 - z1))
        shadow = np.clip(s2 + np.where(s3 > 0.0, s3 * quotient, 0.0), 0.0, 1.0)
    ok = np.isfinite(shadow) & np.isfinite(d33d22) & (d22 > 0) & (d33d22 > 0)
    step = np.where(z0 > b1, 1.0, 0.0)
    return np.where(ok, np.nan_to_num(shadow), step)


def msm_lookup(
    moments: np.ndarray,
    u,
    v,
    depth,
    *,
    fmt: str,
    moment_bias: float,
    bleed_reduction: float,
    subtexel_bits: int = 8,
) -> np.ndarray:
    """Visibility (1 = lit) from a moment texture at receiver depths ``depth`` (normalized,
    clamped to [0, 1]): one bilinear fetch, decode, Hamburger 4MSM, bleeding reduction."""
    s = _filters.bilinear_texture(moments, u, v, subtexel_bits)
    if fmt == "unorm16":
        s = decode16(s)
    d = np.clip(np.asarray(depth, dtype=np.float64), 0.0, 1.0)
    vis = 1.0 - hamburger_4msm(s, d, moment_bias)
    if bleed_reduction > 0.0:
        vis = np.clip((vis - bleed_reduction) / (1.0 - bleed_reduction), 0.0, 1.0)
    return vis
