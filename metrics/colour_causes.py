"""Colour that explains itself: which kind of gap an engine's colour error is.

A shading-model or units gap scales radiance (a global gain: colour x pi, 1/pi, an exposure
off by some stops; or a gain per material: a Fresnel-weighted diffuse darkens dielectrics
by a few per cent); a transfer-function gap bends it (8-bit colour written with a 2.2 power
and decoded as sRGB); a geometry or visibility error moves edges (a sub-pixel shift) or
leaves an error no gain removes. :func:`colour_causes` tries each on the candidate and
names those that explain the error; :func:`material_rows` is the per-shape table (from the
reference's ``id``): pixels, mean ratio candidate/reference, least-squares gain, FLIP,
worst first.

Errors are the mean absolute difference relative to the reference's mean (as
:mod:`metrics.diagnose`): a cause "explains" the error when undoing it leaves at most
:data:`EXPLAINED` of it or brings it within :data:`NEAR_FLOOR` noise floors.
"""

from __future__ import annotations

import math

import numpy as np

from .shift import apply_shift, best_gain, subpixel_shift
from .tonemap import luminance, srgb_decode, srgb_encode

__all__ = [
    "EXPLAINED",
    "NEAR_FLOOR",
    "colour_causes",
    "gain_name",
    "material_gain_corrected",
    "material_rows",
]

#: Undoing a cause explains the error when at most this fraction of it is left (an
#: engine's image keeps its own error once the cause is undone) ...
EXPLAINED = 0.6
#: ... or it falls within this many noise floors; of several, those leaving at most this
#: many times the best one's error are named (best first).
NEAR_BEST = 1.25
#: ... or it falls within this many noise floors.
NEAR_FLOOR = 3.0
#: A gain within this relative distance of pi or 1/pi is named as such.
_PI_TOLERANCE = 0.03
#: Gains closer to 1 than this are no gain.
_NO_GAIN = 0.01
#: An error is worth explaining above this many noise floors (:mod:`metrics.diagnose`'s).
LARGE_OVER_FLOOR = 5.0
#: The smallest relative floor assumed (float32 rounding of an exact candidate).
_MIN_FLOOR = 1e-3
#: Shifts below this many pixels are not reported.
_MIN_SHIFT_PX = 0.2


def _rel_error(ref, cand, mask) -> float:
    d = np.abs(np.asarray(cand, np.float64) - np.asarray(ref, np.float64))
    d = d.mean(axis=-1) if d.ndim == 3 else d
    r = np.asarray(ref, np.float64)
    r = r.mean(axis=-1) if r.ndim == 3 else r
    scale = max(float(r[mask].mean()) if mask.any() else 0.0, 1e-6)
    return float(d[mask].mean() / scale) if mask.any() else 0.0


def gain_name(g: float) -> str:
    """``x3.142 (colour x pi: ...)``, ``x0.318 (colour / pi: ...)`` or ``x0.942 (-0.09 stops)``."""
    stops = math.log2(g) if g > 0 else float("-inf")
    if abs(g - math.pi) <= _PI_TOLERANCE * math.pi:
        return f"x{g:.4g}: colour x pi (a BRDF without its 1/pi, or irradiance shown as radiance)"
    if abs(g - 1 / math.pi) <= _PI_TOLERANCE / math.pi:
        return f"x{g:.4g}: colour / pi (divided by pi twice, or radiance shown as irradiance)"
    return f"x{g:.4g} ({stops:+.2f} exposure stops, {100 * (g - 1):+.1f} %)"


def material_gain_corrected(ref, cand, ids) -> np.ndarray:
    """The candidate with each material's least-squares gain undone (sky left as is)."""
    out = np.array(cand, dtype=np.float64, copy=True)
    for k in np.unique(ids):
        if k < 0:
            continue
        sel = ids == k
        g = best_gain(ref[sel], out[sel])
        if g is not None and g > 0:
            out[sel] = out[sel] / g
    return out


def material_rows(ref, cand, ids, *, flip_map=None, names=None) -> list[dict]:
    """One row per shape id seen (``ids`` ``(H, W)``, -1 sky): ``id``, ``name``, ``pixels``,
    ``mean_ratio`` (candidate over reference luminance), ``gain`` (least squares),
    ``flip_mean`` (over its pixels, when ``flip_map`` is given), ``mean_abs_error``
    (relative); sorted worst first (FLIP, else the error)."""
    rows = []
    lr, lc = luminance(np.asarray(ref)), luminance(np.asarray(cand))
    for k in np.unique(ids):
        if k < 0:
            continue
        sel = ids == k
        sr = float(lr[sel].sum())
        rows.append(
            {
                "id": int(k),
                "name": (names[k] if names is not None and k < len(names) else None),
                "pixels": int(sel.sum()),
                "mean_ratio": float(lc[sel].sum() / sr) if sr > 0 else None,
                "gain": best_gain(ref[sel], cand[sel]),
                "flip_mean": float(flip_map[sel].mean()) if flip_map is not None else None,
                "mean_abs_error": _rel_error(ref, cand, sel),
            }
        )
    key = "flip_mean" if flip_map is not None else "mean_abs_error"
    return sorted(rows, key=lambda r: -(r[key] or 0.0))


def _gamma22_as_srgb(cand) -> np.ndarray:
    """Undo 8-bit colour written with a 2.2 power and decoded with the sRGB curve."""
    return np.power(srgb_encode(np.clip(cand, 0.0, 1.0)), 2.2)


def _srgb_as_gamma22(cand) -> np.ndarray:
    """Undo sRGB-encoded colour decoded with a 2.2 power."""
    return srgb_decode(np.power(np.clip(cand, 0.0, 1.0), 1 / 2.2))


def _transfer_messages(linear_file: bool) -> tuple[str, str]:
    """What to say when a 2.2 power or the sRGB curve explains the error: the ``--transfer``
    to score an 8-bit file with, or, for a linear file (an EXR, which takes no
    ``--transfer``), that the engine wrote display-encoded values into it."""
    if linear_file:
        return (
            "colour encoded with a 2.2 power written into a linear file: write linear radiance "
            "(an EXR takes no --transfer)",
            "sRGB-encoded colour written into a linear file: write linear radiance (an EXR "
            "takes no --transfer)",
        )
    return (
        "8-bit colour encoded with a 2.2 power, decoded as sRGB (score with --transfer gamma2.2)",
        "sRGB-encoded colour decoded with a 2.2 power (score with --transfer srgb)",
    )


def colour_causes(
    ref, cand, ids, *, noise_floor: float = 0.0, names=None, linear_file: bool = False
) -> dict:
    """Which gap explains the colour error of ``cand`` against ``ref`` (both ``(H, W, 3)``
    linear; ``ids`` the reference's ``id``; ``noise_floor`` the relative error an exact
    candidate scores; ``linear_file``: the candidate came from a linear file such as an EXR,
    so a transfer-curve cause names the file's content, not a ``--transfer``).

    Returns ``{"error", "tried": {cause: error left}, "gain", "material_gains", "shift":
    {"dx", "dy", "magnitude"}, "causes": [{"cause", "error", "message"}]}``, the causes
    that explain it, best first.
    """
    ref = np.asarray(ref, np.float64)
    cand = np.asarray(cand, np.float64)
    valid = np.asarray(ids) >= 0
    err = _rel_error(ref, cand, valid)
    g = best_gain(ref[valid], cand[valid])
    shift = subpixel_shift(ref, cand, mask=valid)
    tried, msg = {}, {}
    if g is not None and g > 0 and abs(g - 1) > _NO_GAIN:
        tried["global gain"] = _rel_error(ref, cand / g, valid)
        msg["global gain"] = f"a global gain of {gain_name(g)}"
    per = material_gain_corrected(ref, cand, ids)
    gains = {int(k): best_gain(ref[ids == k], cand[ids == k]) for k in np.unique(ids) if k >= 0}
    spread = [v for v in gains.values() if v is not None]
    if spread and max(abs(v - 1) for v in spread) > _NO_GAIN:
        tried["per-material gain"] = _rel_error(ref, per, valid)
        worst = sorted(gains.items(), key=lambda kv: -abs((kv[1] or 1.0) - 1.0))[:3]
        named = ", ".join(
            f"{names[k] if names is not None and k < len(names) else f'id {k}'} "
            f"x{v:.4g} ({100 * (v - 1):+.1f} %)"
            for k, v in worst
            if v is not None
        )
        msg["per-material gain"] = f"a gain per material (shading model or units): {named}"
    gamma_text, srgb_text = _transfer_messages(linear_file)
    for name, fn, text in (
        ("gamma 2.2 read as sRGB", _gamma22_as_srgb, gamma_text),
        ("sRGB read as gamma 2.2", _srgb_as_gamma22, srgb_text),
    ):
        tried[name] = _rel_error(ref, fn(cand), valid)
        msg[name] = text
    if shift["magnitude"] >= _MIN_SHIFT_PX:
        back = apply_shift(cand, -shift["dx"], -shift["dy"])
        tried["sub-pixel edge shift"] = _rel_error(ref, back, valid)
        msg["sub-pixel edge shift"] = (
            f"edges shifted by ({shift['dx']:+.2f}, {shift['dy']:+.2f}) px "
            f"({shift['magnitude']:.2f} px): geometry, projection or sampling offset"
        )
    # an error within a few noise floors needs no explaining (an exact candidate's noise)
    large = err > LARGE_OVER_FLOOR * max(noise_floor, _MIN_FLOOR)
    causes = [
        {"cause": k, "error": v, "message": msg[k]}
        for k, v in sorted(tried.items(), key=lambda kv: kv[1])
        if large and (v <= EXPLAINED * err or (noise_floor > 0 and v <= NEAR_FLOOR * noise_floor))
    ]
    if causes:
        causes = [c for c in causes if c["error"] <= NEAR_BEST * causes[0]["error"]]
    if any(c["cause"] == "global gain" for c in causes):  # one gain explains it: say so once
        causes = [c for c in causes if c["cause"] != "per-material gain"]
    return {
        "error": err,
        "tried": tried,
        "gain": g,
        "material_gains": gains,
        "shift": {k: shift[k] for k in ("dx", "dy", "magnitude")},
        "causes": causes,
    }
