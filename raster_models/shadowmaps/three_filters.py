"""three.js r187's shadow filters, transcribed: ``PCFShadowMap`` (``filter=three_pcf``) and
``VSMShadowMap`` (``filter=three_vsm``).

Pinned source: three.js r187 (tag ``r187`` of mrdoob/three.js; the npm package
``three@0.187.0``, ``src/constants.js:1`` ``REVISION = '187'``). Files and lines:

- ``src/renderers/shaders/ShaderChunk/shadowmap_pars_fragment.glsl.js`` (sha256 in
  :data:`SOURCES`): interleaved gradient noise ``fract(52.9829189 * fract(dot(p,
  vec2(0.06711056, 0.00583715))))`` (:130-134), ``vogelDiskSample``: golden angle
  ``2.399963229728653``, ``r = sqrt((i + 0.5) / n)``, ``theta = i * goldenAngle + phi``
  (:137-144); PCF ``getShadow``: ``shadowCoord.z += shadowBias`` (:162), lit outside
  ``[0, 1]^2`` or beyond ``z > 1`` (:166-167), ``radius = shadowRadius * texelSize`` (:174),
  ``phi = interleavedGradientNoise(gl_FragCoord.xy) * PI2`` (:177), 5 ``sampler2DShadow``
  taps ``vogelDiskSample(k, 5, phi) * radius`` averaged ``* 0.2`` (:179-185); VSM
  ``getShadow``: ``mean, std = texture2D(shadowMap, uv).rg`` (:216-219), lit where
  ``z <= mean`` (``step(z, mean)``, :227), ``variance = max(std^2, 0.0000001)`` (:239),
  ``p_max = variance / (variance + d^2)`` (:245), ``clamp((p_max - 0.3) / 0.65, 0, 1)``
  (:248), ``max(hard_shadow, p_max)`` (:250).
- ``src/renderers/shaders/ShaderLib/vsm.glsl.js`` (sha256 in :data:`SOURCES`):
  ``VSM_SAMPLES`` taps at ``uvStart + i * uvStride`` with
  ``uvStride = 2 / (samples - 1)``, ``uvStart = -1`` (:21-25) times ``radius`` texels from
  ``gl_FragCoord`` (:29, :35); the vertical pass reads depth and accumulates ``d``, ``d^2``
  (:35-37), the horizontal pass reads ``(mean, std)`` and accumulates ``mean`` and
  ``std^2 + mean^2`` (:29-31); both write ``(mean, sqrt(max(0, E[d^2] - mean^2)))`` (:43-48).
- ``src/renderers/webgl/WebGLShadowMap.js``: ``VSM_SAMPLES: 8`` (:55); the VSM map is
  ``RGFormat``/``HalfFloatType`` with ``LinearFilter`` (:227-232), its depth a
  ``FloatType`` (D32F) ``DepthTexture`` read with ``NearestFilter`` (:237-242); the vertical
  pass reads that depth texture, the horizontal pass the ``RGFormat``/``HalfFloatType``
  ``mapPass`` (:397-424, ``RenderTarget`` default ``LinearFilter``); the PCF map is a
  ``UnsignedIntType`` (``DEPTH_COMPONENT24``, ``WebGLTextures.js:281``) ``DepthTexture``
  with ``compareFunction = LessEqualCompare`` and ``LinearFilter`` (:262-265);
  ``shadowSide`` defaults to the opposite side (``FrontSide -> BackSide``, :51, :490) except
  for VSM, which renders ``material.side`` (:486).
- ``src/lights/LightShadow.js``: ``bias = 0`` (:53), ``normalBias = 0`` (:74),
  ``radius = 1`` (:87), ``blurSamples = 8`` (:95).

Conventions of the transcription: three's ``shadowCoord.z += shadowBias`` is this model's
``bias`` with the opposite sign (the model subtracts ``bias``); three's texture ``t`` axis
runs up the light camera's ``+y``, this model's ``v`` down it (:mod:`..light_frame`), so a
disk offset ``(x, y)`` is ``(du, dv) = (x, -y) * radius / R``; ``gl_FragCoord`` has its
origin at the lower-left pixel corner, so a pixel ``(x, y)`` of a top-down image (row 0 at
the top) of height ``H`` has ``gl_FragCoord.xy = (x + 0.5, H - y - 0.5)``.
"""

from __future__ import annotations

import math

import numpy as np

from .filters import _resolution, bilinear_texture, compare_bilinear

__all__ = [
    "GOLDEN_ANGLE",
    "IGN",
    "PCF_SAMPLES",
    "SOURCES",
    "VSM_BLEED",
    "VSM_MIN_VARIANCE",
    "frag_coord",
    "interleaved_gradient_noise",
    "lookup_pcf",
    "lookup_vsm",
    "vogel_disk",
    "vsm_blur_offsets",
    "vsm_texture",
]

#: The pinned files (three.js r187) and the SHA-256 of each as read.
SOURCES = {
    "src/renderers/shaders/ShaderChunk/shadowmap_pars_fragment.glsl.js": (
        "acc292ea208f347308f89f55e7e553e9b69a96b0a2e9cb8d1423a4340e5b8b34"
    ),
    "src/renderers/shaders/ShaderLib/vsm.glsl.js": (
        "0bd3b13a03e43709aa3583bc07f57581798dc92ce5aeee30712c503e3997cdb5"
    ),
}

#: ``interleavedGradientNoise``: (x weight, y weight, outer scale), shadowmap_pars_fragment:132.
IGN = (0.06711056, 0.00583715, 52.9829189)
#: ``vogelDiskSample``'s golden angle (radians), shadowmap_pars_fragment:139.
GOLDEN_ANGLE = 2.399963229728653
#: Taps of ``PCFShadowMap``: ``vogelDiskSample(k, 5, phi)``, shadowmap_pars_fragment:180-185.
PCF_SAMPLES = 5
#: VSM light-bleeding remap ``clamp((p - 0.3) / 0.65, 0, 1)``, shadowmap_pars_fragment:248.
VSM_BLEED = (0.3, 0.65)
#: VSM minimum variance ``max(variance, 0.0000001)``, shadowmap_pars_fragment:239.
VSM_MIN_VARIANCE = 1e-7


def interleaved_gradient_noise(px, py) -> np.ndarray:
    """three's ``interleavedGradientNoise(position)`` in [0, 1), float64."""
    x = np.asarray(px, dtype=np.float64)
    y = np.asarray(py, dtype=np.float64)
    inner = x * IGN[0] + y * IGN[1]
    inner = inner - np.floor(inner)
    val = IGN[2] * inner
    return val - np.floor(val)


def frag_coord(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """``gl_FragCoord.xy`` of every pixel of a top-down ``(height, width)`` image, flat
    row-major: ``(x + 0.5, height - y - 0.5)`` (lower-left origin)."""
    idx = np.arange(int(width) * int(height))
    return idx % width + 0.5, height - (idx // width) - 0.5


def vogel_disk(k, n: int, phi) -> tuple[np.ndarray, np.ndarray]:
    """``vogelDiskSample(k, n, phi)``: ``(cos theta, sin theta) * sqrt((k + 0.5) / n)``."""
    r = math.sqrt((float(k) + 0.5) / float(n))
    theta = float(k) * GOLDEN_ANGLE + np.asarray(phi, dtype=np.float64)
    return np.cos(theta) * r, np.sin(theta) * r


def _frustum_lit(u, v, ref) -> np.ndarray:
    """three's ``frustumTest`` failed: the pixel is lit without a lookup."""
    return ~((u >= 0.0) & (u <= 1.0) & (v >= 0.0) & (v <= 1.0) & (ref <= 1.0))


def lookup_pcf(
    texels, u, v, ref, *, radius: float, phi, address: str = "clamp", subtexel_bits: int = 8
) -> np.ndarray:
    """``PCFShadowMap``: 5 hardware-PCF (2x2 ``LessEqual``) taps on a Vogel disk of
    ``radius`` texels rotated by ``phi`` per receiver; ``ref`` is the receiver's compare
    depth (three's ``z + shadowBias``). Float64 visibility, 1 = lit."""
    r = _resolution(texels)
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ref = np.broadcast_to(np.asarray(ref, dtype=np.float64), u.shape)
    scale = float(radius) / r
    acc = np.zeros(u.shape, dtype=np.float64)
    for k in range(PCF_SAMPLES):
        dx, dy = vogel_disk(k, PCF_SAMPLES, phi)
        acc += compare_bilinear(
            texels,
            u + dx * scale,
            v - dy * scale,
            ref,
            address=address,
            subtexel_bits=subtexel_bits,
        )
    vis = acc * 0.2
    return np.where(_frustum_lit(u, v, ref), 1.0, vis)


def vsm_blur_offsets(samples: int) -> np.ndarray:
    """Tap offsets of the blur in units of ``radius``: ``uvStart + i * uvStride``."""
    s = int(samples)
    if s <= 1:
        return np.zeros(1)
    return -1.0 + np.arange(s) * (2.0 / (s - 1))


def _nearest_rows(n: int, centre_offset: float) -> np.ndarray:
    """Nearest texel of each texel centre moved by ``centre_offset`` texels (clamp)."""
    pos = np.arange(n) + 0.5 + centre_offset
    return np.clip(np.floor(pos).astype(np.int64), 0, n - 1)


def _linear_cols(tex: np.ndarray, centre_offset: float, subtexel_bits: int) -> np.ndarray:
    """Bilinear (``LinearFilter``, clamp to edge) reads of ``tex`` ``(R, R, C)`` along x
    at every texel centre moved by ``centre_offset`` texels (y at the texel centre)."""
    n = tex.shape[1]
    x = np.arange(n) + centre_offset  # texel-centre-relative coordinate: (pos - 0.5)
    x0 = np.floor(x)
    f = x - x0
    if subtexel_bits > 0:
        scale = float(1 << subtexel_bits)
        f = np.round(f * scale) / scale
    i0 = np.clip(x0.astype(np.int64), 0, n - 1)
    i1 = np.clip(x0.astype(np.int64) + 1, 0, n - 1)
    t = tex.astype(np.float64)
    return t[:, i0] * (1.0 - f)[None, :, None] + t[:, i1] * f[None, :, None]


def vsm_texture(
    depth_map: np.ndarray, *, radius: float, samples: int, subtexel_bits: int = 8
) -> np.ndarray:
    """The VSM map three renders: ``(R, R, 2)`` float16 ``(mean, std_dev)`` after the
    vertical pass (``samples`` nearest reads of the D32F depth, ``radius`` texels) and
    the horizontal pass (``samples`` bilinear reads of the RG16F pass texture)."""
    d = np.asarray(depth_map, dtype=np.float32).astype(np.float64)
    rows_n = d.shape[0]
    offsets = vsm_blur_offsets(samples) * float(radius)
    mean = np.zeros_like(d)
    sq = np.zeros_like(d)
    for off in offsets:
        # Rows of the map are texture rows (the pass is symmetric: up or down alike).
        rows = _nearest_rows(rows_n, off)
        tap = d[rows, :]
        mean += tap
        sq += tap * tap
    n = float(len(offsets))
    mean, sq = mean / n, sq / n
    std = np.sqrt(np.maximum(0.0, sq - mean * mean))
    first = np.stack([mean, std], axis=-1).astype(np.float16)
    mean = np.zeros_like(d)
    sq = np.zeros_like(d)
    for off in offsets:
        tap = _linear_cols(first, off, subtexel_bits)
        mean += tap[..., 0]
        sq += tap[..., 1] * tap[..., 1] + tap[..., 0] * tap[..., 0]
    mean, sq = mean / n, sq / n
    std = np.sqrt(np.maximum(0.0, sq - mean * mean))
    return np.stack([mean, std], axis=-1).astype(np.float16)


def lookup_vsm(tex: np.ndarray, u, v, ref, *, subtexel_bits: int = 8) -> np.ndarray:
    """``VSMShadowMap``'s ``getShadow`` on a :func:`vsm_texture` (bilinear read), for
    receivers with compare depth ``ref`` (three's ``z + shadowBias``)."""
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    s = bilinear_texture(tex, u.ravel(), v.ravel(), subtexel_bits).reshape(*u.shape, 2)
    mean, std = s[..., 0], s[..., 1]
    hard = mean >= ref
    variance = np.maximum(std * std, VSM_MIN_VARIANCE)
    d = ref - mean
    p = variance / (variance + d * d)
    p = np.clip((p - VSM_BLEED[0]) / VSM_BLEED[1], 0.0, 1.0)
    vis = np.where(hard, 1.0, p)
    return np.where(_frustum_lit(u, v, ref), 1.0, vis)
