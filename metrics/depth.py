"""Depth of an engine's image against the reference's: linear view depth, relative error.

Depth here is *linear view depth*: the distance along the camera's forward axis, in scene
units, as the oracle's G-buffer stores it (an engine linearizes its depth buffer first:
``near * far / (far - d (far - near))`` for a ``[0, 1]`` hyperbolic ``d``). The error of a
pixel is relative, ``|candidate - reference| / reference``, so a metre at 1 km and a
millimetre at 1 m weigh alike.

A hyperbolic depth buffer cannot do better than its rounding: a UNORM ``bits``-bit buffer
stores ``d`` to ``1 / (2^bits - 1)``, so the linearized depth's relative error is about
``z (far - near) / (near far) * q / 2`` (:func:`hyperbolic_rounding`, exactly), which grows with
distance and with ``far / near``: the near-plane precision case. Pixels whose error is
within that rounding are *precision-limited*, not wrong; :func:`depth_metrics` reports the
fraction beyond it when the buffer's ``near``, ``far`` and ``bits`` are given.

References
----------
.. [1] K. Akeley, J. Su, "Minimum triangle separation for correct z-buffer occlusion",
   Graphics Hardware 2006. DOI: 10.1145/1283900.1283903
"""

from __future__ import annotations

import numpy as np

from .validate import MetricError

__all__ = ["DEPTH_KEYS", "depth_metrics", "float32_linearization_limit", "hyperbolic_rounding"]

#: The keys :func:`depth_metrics` returns.
DEPTH_KEYS = (
    "depth_rel_error_mean",
    "depth_rel_error_p99",
    "depth_rel_error_max",
    "depth_pixels",
    "depth_beyond_precision_fraction",
)


def hyperbolic_rounding(z, *, near: float, far: float, bits: int) -> np.ndarray:
    """Largest relative error of linear depth ``z`` stored in a ``bits``-bit UNORM
    hyperbolic buffer (``d = far (z - near) / (z (far - near))``, rounded to half a quantum)
    and linearized again; to first order ``z (far - near) / (near far) q / 2``."""
    if not (0.0 < near < far):
        raise MetricError(f"depth buffer needs 0 < near < far, got near={near}, far={far}")
    if int(bits) not in (16, 24, 32):
        raise MetricError(f"depth buffer bits must be 16, 24 or 32, got {bits}")
    q = 1.0 / (2.0 ** int(bits) - 1.0)
    z = np.asarray(z, dtype=np.float64)
    d = far * (z - near) / (z * (far - near))
    # z(d) is convex: half a quantum towards the far plane moves it most (exactly, not to
    # first order: near the far plane the first-order bound is too small).
    denom = np.maximum(far - (d + 0.5 * q) * (far - near), 1e-300)
    return np.abs(near * far / denom - z) / z


def float32_linearization_limit(z, *, near: float, far: float, bits: int) -> np.ndarray:
    """Largest relative error of linear depth ``z`` read from a ``bits``-bit hyperbolic
    buffer and linearized in float32, as a shader does: the buffer's rounding
    (:func:`hyperbolic_rounding`) plus three half-ulps of float32 at the scale of a 24-bit
    quantum (``d`` held in float32, ``d (far - near)`` rounded, then subtracted from ``far``:
    each about half a 24-bit quantum of ``d``), plus ``2^-23`` for the division. A 32-bit
    buffer is no finer than float32 maths: the float32 terms dominate it."""
    own = hyperbolic_rounding(z, near=near, far=far, bits=bits)
    return own + 3.0 * hyperbolic_rounding(z, near=near, far=far, bits=24) + 2.0**-23


def depth_metrics(
    reference,
    candidate,
    *,
    valid,
    near: float | None = None,
    far: float | None = None,
    bits: int | None = None,
    full: bool = False,
) -> dict:
    """Relative error of a candidate's linear view depth on ``valid`` pixels.

    Parameters
    ----------
    reference, candidate : ``(H, W)`` linear view depth, scene units (> 0 on valid pixels).
    valid : ``(H, W)`` bool: the pixels scored (the reference sees a surface there).
    near, far, bits : the candidate's depth buffer (all three or none): adds the fraction
        of valid pixels whose error exceeds that buffer's rounding and the candidate's own
        float32 linearization (:func:`float32_linearization_limit`).
    full : also return ``"map"``, the ``(H, W)`` relative error (0 off ``valid``).

    Returns
    -------
    dict with :data:`DEPTH_KEYS`: mean, 99th percentile and maximum relative error, the
    number of pixels scored (``depth_pixels``; 0 gives ``None`` statistics, never a
    perfect score) and ``depth_beyond_precision_fraction`` (``None`` without a buffer).
    """
    ref = np.asarray(reference, dtype=np.float64)
    cand = np.asarray(candidate, dtype=np.float64)
    mask = np.asarray(valid, dtype=bool)
    if ref.shape != cand.shape or ref.shape != mask.shape or ref.ndim != 2:
        raise MetricError(
            "reference, candidate and valid must be (H, W) of one shape, got "
            f"{ref.shape}, {cand.shape} and {mask.shape}"
        )
    given = [v is not None for v in (near, far, bits)]
    if any(given) and not all(given):
        raise MetricError("near, far and bits describe one depth buffer: give all three or none")
    r, c = ref[mask], cand[mask]
    bad = ~np.isfinite(c) | (c <= 0)
    if np.any(bad):
        raise MetricError(
            f"candidate depth must be finite and > 0 where the reference sees a surface: "
            f"{int(bad.sum())} of {c.size} such pixels are not (min {float(np.min(c)):g})"
        )
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise MetricError("reference depth must be finite and > 0 on valid pixels")
    rel = np.abs(c - r) / r
    out: dict = dict.fromkeys(DEPTH_KEYS)
    out["depth_pixels"] = int(rel.size)
    if rel.size:
        out["depth_rel_error_mean"] = float(rel.mean())
        out["depth_rel_error_p99"] = float(np.percentile(rel, 99))
        out["depth_rel_error_max"] = float(rel.max())
        if all(given):
            limit = float32_linearization_limit(r, near=near, far=far, bits=bits)
            out["depth_beyond_precision_fraction"] = float(np.mean(rel > limit))
    if full:
        error = np.zeros(ref.shape)
        error[mask] = rel
        out["map"] = error.astype(np.float32)
    return out
