"""The shipped alpha-test rules of real-time engines, as functions of a fragment's alpha.

A fragment (one triangle in one pixel; the shader runs once at the pixel centre under MSAA)
has an alpha ``a`` (from its mip-mapped texture, :mod:`scenes.shading.alpha_mips`), the sum
of its absolute screen derivatives ``fwidth(a)`` and, for hashed alpha, its object-space
position and that position's screen derivatives. Each rule returns the fragment's
**alpha-to-coverage value** in [0, 1] and whether the fragment is **discarded**; the model
(:mod:`.model`) turns them into the samples the fragment keeps.

Rules (each a transcription of a pinned source; the code is written here, not copied):

- ``test``: the plain alpha test, kept where ``a >= cutoff`` (glTF 2.0 3.9.6; three.js
  ``alphatest_fragment.glsl.js`` line 7 of the copy below, ``if ( diffuseColor.a < alphaTest
  ) discard;``).
- ``threejs-a2c``: three.js with ``alphaToCoverage``: ``a' = smoothstep(t, t + fwidth(a), a)``,
  discarded where ``a' == 0`` (three.js ``src/renderers/shaders/ShaderChunk/
  alphatest_fragment.glsl.js`` lines 3-5, as stored at FeatureaEngine/three.js commit
  0a134a49656836ebf414daa62935f735a5664a0c, a fork of mrdoob/three.js whose stored copy,
  commit 23b1db990bd284c78218c369f82687c1aa1e1c27, predates alpha-to-coverage). Its
  half-coverage contour lies where ``a = t + fwidth(a) / 2``: half a pixel's alpha ramp
  inside the cutoff contour, which shrinks silhouettes.
- ``filament-a2c``: Filament's ``applyAlphaMask`` (google/filament commit
  24a7bc2799eee5e5694b5df2adea457727ae25d8, ``shaders/src/surface_main.fs`` lines 25-33):
  ``a' = (a - t) / max(fwidth(a), 1e-3) + 0.5``, centred on the cutoff, then discarded where
  ``a' <= t`` (the remapped alpha compared with the threshold again); default ``t`` 0.4
  (``float mMaskThreshold = 0.4f;``, a member initializer of ``MaterialBuilder`` in
  ``libs/filamat/include/filamat/MaterialBuilder.h`` at commit
  001a4c46db3750d60d002872d667001f3ce90a82; its line is not pinned here).
- ``hashed``: Wyman and McGuire's hashed alpha test as three.js ships it (mrdoob/three.js
  commit 80c40c4ff59059d6773b0a3d99090e597b07a2f2, ``src/renderers/shaders/ShaderChunk/
  alphahash_pars_fragment.glsl.js``: ``ALPHA_HASH_SCALE = 0.05`` line 8, ``hash2D`` line 12,
  ``hash3D`` line 18, ``getAlphaHashThreshold`` lines 22-65; and commit
  814aa0ba6886baea899e98c818c1d9e13d3be06f, ``alphahash_fragment.glsl.js`` line 4, discard
  where ``a < threshold``); the position is the object-space vertex position (three.js
  ``begin_vertex``: ``vPosition = vec3( position )``). GLSL's ``sin`` and ``fract`` run here in
  float64: the hash's values differ from a GPU's, its distribution does not.

Alpha-to-coverage's sample mask is implementation-dependent (OpenGL 4.6 core,
"Multisample Fragment Operations", ``SAMPLE_ALPHA_TO_COVERAGE``); :func:`a2c_samples` keeps
the first ``floor(a' N + 1/2)`` samples of the pixel's pattern (an assumption: no vendor's
dither pattern).

References
----------
C. Wyman and M. McGuire, "Hashed Alpha Testing", I3D 2017, doi:10.1145/3023368.3023370.
The Khronos Group, glTF 2.0 specification, 3.9.6 "Alpha Coverage".
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ALPHA_HASH_SCALE",
    "FILAMENT_MASK_THRESHOLD",
    "RULES",
    "a2c_samples",
    "apply_rule",
    "filament_a2c",
    "hash3d",
    "hashed_threshold",
    "plain_test",
    "smoothstep",
    "threejs_a2c",
]

#: three.js alphahash_pars_fragment.glsl.js:8 (80c40c4): "Derived from trials only".
ALPHA_HASH_SCALE = 0.05
#: Filament MaterialBuilder.h (001a4c4): ``mMaskThreshold = 0.4f``.
FILAMENT_MASK_THRESHOLD = 0.4
#: Filament surface_main.fs:29 (24a7bc2): ``max(fwidth(baseColor.a), 1e-3)``.
FILAMENT_MIN_FWIDTH = 1e-3
#: The rules :func:`apply_rule` knows, with their one-line descriptions.
RULES = {
    "test": "plain alpha test, kept where a >= cutoff (glTF, three.js alphaTest)",
    "threejs-a2c": "three.js alphaToCoverage: smoothstep(t, t + fwidth(a), a)",
    "filament-a2c": "Filament masked: (a - t) / max(fwidth(a), 1e-3) + 0.5, discard <= t",
    "hashed": "hashed alpha test (Wyman-McGuire 2017, three.js alphaHash, scale 0.05)",
}


def smoothstep(e0, e1, x):
    """GLSL ``smoothstep``: ``t^2 (3 - 2t)``, ``t = clamp((x - e0) / (e1 - e0), 0, 1)``; where
    ``e0 == e1`` (GLSL leaves it undefined) a step at ``e0``, 1 for ``x >= e0``."""
    e0, e1, x = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in (e0, e1, x)))
    span = e1 - e0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip((x - e0) / np.where(span != 0, span, 1.0), 0.0, 1.0)
    return np.where(span != 0, t * t * (3.0 - 2.0 * t), (x >= e0).astype(np.float64))


def plain_test(a, cutoff):
    """``(value, discarded)``: 1 where ``a >= cutoff``, discarded elsewhere."""
    keep = np.asarray(a) >= cutoff
    return keep.astype(np.float64), ~keep


def threejs_a2c(a, fwidth_a, cutoff):
    """three.js alpha-to-coverage: ``(smoothstep(t, t + fwidth, a), value == 0)``."""
    v = smoothstep(cutoff, np.asarray(cutoff) + np.asarray(fwidth_a), a)
    return v, v == 0.0


def filament_a2c(a, fwidth_a, threshold=FILAMENT_MASK_THRESHOLD):
    """Filament's masked rule: ``a' = (a - t) / max(fwidth, 1e-3) + 1/2``, discarded where
    ``a' <= t``; the coverage value is ``a'`` clamped to [0, 1] (the fixed-function
    alpha-to-coverage clamps the output alpha)."""
    v = (np.asarray(a, np.float64) - threshold) / np.maximum(fwidth_a, FILAMENT_MIN_FWIDTH) + 0.5
    return np.clip(v, 0.0, 1.0), v <= threshold


def _fract(x):
    return x - np.floor(x)


def hash2d(x, y):
    """three.js ``hash2D`` (line 12): ``fract(1e4 sin(17 x + 0.1 y) (0.1 + |sin(13 y + x)|))``."""
    return _fract(1.0e4 * np.sin(17.0 * x + 0.1 * y) * (0.1 + np.abs(np.sin(13.0 * y + x))))


def hash3d(p):
    """three.js ``hash3D`` (line 18): ``hash2D(hash2D(p.xy), p.z)``; ``p`` (..., 3)."""
    p = np.asarray(p, np.float64)
    return hash2d(hash2d(p[..., 0], p[..., 1]), p[..., 2])


def hashed_threshold(p, dpdx, dpdy, *, scale: float = ALPHA_HASH_SCALE):
    """three.js ``getAlphaHashThreshold`` (lines 22-65): the hashed alpha threshold of
    object-space points ``p`` (..., 3) with screen derivatives ``dpdx``, ``dpdy``: the hash of
    ``p`` on the two power-of-two grids around ``1 / (scale max(|dp/dx|, |dp/dy|))``, blended
    by the fractional scale and mapped through the CDF of that blend to a uniform value,
    clamped to ``[1e-6, 1]``."""
    p = np.asarray(p, np.float64)
    max_deriv = np.maximum(np.linalg.norm(dpdx, axis=-1), np.linalg.norm(dpdy, axis=-1))
    with np.errstate(divide="ignore"):
        pix_scale = 1.0 / (scale * max_deriv)
    lg = np.log2(pix_scale)
    lo, hi = np.exp2(np.floor(lg)), np.exp2(np.ceil(lg))
    ax = hash3d(np.floor(lo[..., None] * p))
    ay = hash3d(np.floor(hi[..., None] * p))
    lerp = _fract(lg)
    x = (1.0 - lerp) * ax + lerp * ay
    a = np.minimum(lerp, 1.0 - lerp)
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 2.0 * a * (1.0 - a)
        c1 = x * x / denom
        c2 = (x - 0.5 * a) / (1.0 - a)
        c3 = 1.0 - (1.0 - x) * (1.0 - x) / denom
    threshold = np.where(x < 1.0 - a, np.where(x < a, c1, c2), c3)
    return np.clip(threshold, 1.0e-6, 1.0)


def a2c_samples(value, n: int) -> np.ndarray:
    """Samples an alpha-to-coverage value keeps: ``floor(value n + 1/2)`` (int) of ``n``."""
    return np.floor(np.clip(np.asarray(value, np.float64), 0.0, 1.0) * n + 0.5).astype(np.int64)


def apply_rule(
    rule: str,
    a,
    *,
    cutoff: float,
    fwidth_a=None,
    position=None,
    dpdx=None,
    dpdy=None,
    hash_scale: float = ALPHA_HASH_SCALE,
):
    """``(value, discarded)`` of ``rule`` (a key of :data:`RULES`) for fragment alphas ``a``
    (``fwidth_a`` for the alpha-to-coverage rules; ``position``, ``dpdx``, ``dpdy`` for
    ``hashed``). For ``test`` and ``hashed`` the value is 1 (all covered samples kept) or 0."""
    if rule == "test":
        return plain_test(a, cutoff)
    if rule == "threejs-a2c":
        return threejs_a2c(a, fwidth_a, cutoff)
    if rule == "filament-a2c":
        return filament_a2c(a, fwidth_a, cutoff)
    if rule == "hashed":
        keep = np.asarray(a) >= hashed_threshold(position, dpdx, dpdy, scale=hash_scale)
        return keep.astype(np.float64), ~keep
    raise ValueError(f"unknown alpha rule {rule!r}; choose one of {', '.join(RULES)}")
