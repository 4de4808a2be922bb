"""Likely causes of a large error: the usual ways an engine's image goes wrong on its way out.

An image flipped (a framebuffer read bottom-up, or a texture coordinate's v), transposed,
inverted (a shadow factor where visibility was expected), stored with the wrong transfer
function (sRGB values in an EXR, linear values in a PNG), or shifted by one pixel (a
half-pixel offset rounded, a viewport off by one) scores badly with no hint of why. When the
error is large, :func:`diagnose` applies each of those transforms to the candidate; a
transform that brings the error near the noise floor (or removes most of it) is the likely
cause.

The error is the mean absolute difference over the scored pixels (relative to the
reference's mean for colour); its noise floor is what an exact candidate would score,
``sqrt(2 / pi)`` times the mean standard error of the reference (the mean of ``|N(0, s)|``).
"""

from __future__ import annotations

import numpy as np

from .tonemap import srgb_decode, srgb_encode

__all__ = [
    "LARGE_OVER_FLOOR",
    "NEAR_FLOOR",
    "REMOVED_FRACTION",
    "diagnose",
    "mean_abs_floor",
]

#: An error is large (worth diagnosing) above this many noise floors.
LARGE_OVER_FLOOR = 5.0
#: A transformed candidate within this many noise floors is "near the floor".
NEAR_FLOOR = 3.0
#: ... or a transform that leaves at most this fraction of the error explains it (an engine
#: image is not exact, so its own error may sit above the floor once the transform is undone).
REMOVED_FRACTION = 0.2
#: E|N(0, s)| / s: the mean absolute error of an exact candidate per unit standard error.
_HALF_NORMAL_MEAN = float(np.sqrt(2.0 / np.pi))


def mean_abs_floor(reference_stderr, *, mask=None) -> float:
    """The mean absolute error an exact candidate scores against a reference of standard
    error ``reference_stderr`` (``(H, W)`` or ``(H, W, C)``) over ``mask`` (``(H, W)``)."""
    se = np.asarray(reference_stderr, dtype=np.float64)
    if mask is not None:
        se = se[np.asarray(mask, dtype=bool)]
    return float(_HALF_NORMAL_MEAN * se.mean()) if se.size else 0.0


def _shift(image: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """``image`` moved by ``(dy, dx)`` pixels, the uncovered border repeated."""
    out = np.roll(image, (dy, dx), axis=(0, 1))
    if dy > 0:
        out[:dy] = out[dy : dy + 1]
    elif dy < 0:
        out[dy:] = out[dy - 1 : dy]
    if dx > 0:
        out[:, :dx] = out[:, dx : dx + 1]
    elif dx < 0:
        out[:, dx:] = out[:, dx - 1 : dx]
    return out


def _transforms(candidate: np.ndarray, kind: str) -> dict:
    """Name -> transformed candidate (the inverse of each way an image goes wrong)."""
    c = candidate
    out = {
        "flipped vertically (rows bottom-up)": c[::-1],
        "flipped horizontally": c[:, ::-1],
    }
    if c.shape[0] == c.shape[1]:
        out["transposed (rows and columns swapped)"] = np.swapaxes(c, 0, 1)
    if kind in ("visibility", "coverage"):
        out["inverted (1 means shadowed: --visibility 1-is-shadowed)"] = 1.0 - c
    if kind == "color":
        out["sRGB-encoded values in a linear file (decode them)"] = srgb_decode(
            np.clip(c, 0.0, 1.0)
        )
        out["linear values in an sRGB file (a PNG holding linear data)"] = srgb_encode(
            np.clip(c, 0.0, 1.0)
        )
    for dy, dx, where in ((1, 0, "down"), (-1, 0, "up"), (0, 1, "right"), (0, -1, "left")):
        # the candidate is one pixel off in the opposite direction of the fix
        out[f"shifted by one pixel ({where} undoes it)"] = _shift(c, dy, dx)
    return out


def _error(reference, candidate, mask, scale: float) -> float:
    d = np.abs(np.asarray(candidate, np.float64) - np.asarray(reference, np.float64))
    if d.ndim == 3:
        d = d.mean(axis=-1)
    d = d[mask] if mask is not None else d
    return float(d.mean() / scale) if d.size else 0.0


def diagnose(
    reference,
    candidate,
    *,
    reference_stderr,
    kind: str,
    mask=None,
    noise_floor: float | None = None,
) -> dict:
    """Try the inverse of each usual mistake on ``candidate``; say which explains the error.

    Parameters
    ----------
    reference, candidate : ``(H, W)`` data in [0, 1] (``kind`` ``"visibility"`` or
        ``"coverage"``) or ``(H, W, 3)`` linear radiance (``"color"``).
    reference_stderr : the reference's standard error, same shape.
    mask : ``(H, W)`` bool, the scored pixels (a shadow mask's receivers); None: all.
    noise_floor : the mean absolute error an exact candidate scores, when known (the
        score's own noise floor of its mean absolute error); None: from
        ``reference_stderr`` (:func:`mean_abs_floor`), an upper bound where the standard
        error is floored (binomial floors of agreeing samples).

    Returns
    -------
    dict
        ``{"error", "noise_floor", "large": bool, "tried": {name: error}, "likely": None or
        {"transform", "error", "error_as_given", "noise_floor", "message"}}``. Errors are mean
        absolute differences over ``mask`` (colour: relative to the reference's mean).
        ``tried`` is empty when the error is not large (nothing to explain).
    """
    ref = np.asarray(reference, dtype=np.float32)
    cand = np.asarray(candidate, dtype=np.float32)
    if ref.shape != cand.shape:
        raise ValueError(f"reference and candidate shapes differ: {ref.shape} and {cand.shape}")
    mask = None if mask is None else np.asarray(mask, dtype=bool)
    scale = max(float(ref.mean()), 1e-6) if kind == "color" else 1.0
    if noise_floor is None:
        floor = mean_abs_floor(reference_stderr, mask=mask) / scale
    else:
        floor = float(noise_floor) / (scale if kind == "color" else 1.0)
    err = _error(ref, cand, mask, scale)
    out = {"error": err, "noise_floor": floor, "large": False, "tried": {}, "likely": None}
    # float32 rounding keeps an exact candidate's error above 0: a floor of 0 is no floor
    if err <= LARGE_OVER_FLOOR * max(floor, 1e-6):
        return out
    out["large"] = True
    tried = {}
    for name, image in _transforms(cand, kind).items():
        if image.shape != ref.shape:
            continue
        tried[name] = _error(ref, image, mask, scale)
    out["tried"] = tried
    if not tried:
        return out
    name = min(tried, key=tried.get)
    best = tried[name]
    if best <= NEAR_FLOOR * floor or best <= REMOVED_FRACTION * err:
        out["likely"] = {
            "transform": name,
            "error": best,
            "error_as_given": err,
            "noise_floor": floor,
            "message": (
                f"likely cause: the candidate is {name}: undone, its mean |error| drops from "
                f"{err:.4g} to {best:.4g} (noise floor {floor:.4g})"
            ),
        }
    return out
