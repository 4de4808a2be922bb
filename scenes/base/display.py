"""The display transform: the one tone-mapping pipeline that turns linear radiance into a
display-encoded image (used by the scoring before any LDR metric, and by the techniques that
run in display space, FXAA and SMAA, after it).

Pipeline (the same for reference and candidate, with one exposure taken from the reference):

1. drop alpha: ``(H, W, 4)`` becomes ``(H, W, 3)``; ``(H, W)`` and ``(H, W, 3)`` pass;
2. clamp negative radiance to 0 (Monte Carlo estimates with signed filters can dip below 0);
3. scale by ``2**exposure`` (``exposure`` in stops, from :func:`exposure_from_reference`);
4. tone map: ``"aces"`` (Narkowicz's fit of the ACES filmic curve), ``"reinhard"``
   (luminance-based Reinhard) or ``"clip"`` (none);
5. clip to [0, 1];
6. sRGB-encode (IEC 61966-2-1 transfer function).

The result is display-encoded float32 in [0, 1]: code that wants linear values decodes it
back with :func:`srgb_decode`. :mod:`metrics.tonemap` re-exports these functions for the
metrics (raising ``MetricError`` there).
"""

from __future__ import annotations

import numpy as np

from .arrays import check_array

__all__ = [
    "LUMINANCE_WEIGHTS",
    "TONE_MAPPERS",
    "DisplayError",
    "exposure_from_reference",
    "luminance",
    "srgb_decode",
    "srgb_encode",
    "tonemap",
    "tonemap_inverse",
]


class DisplayError(ValueError):
    """Invalid input to the display transform: bad image, exposure, key or curve name."""


#: Rec. 709 / sRGB luminance weights of linear R, G, B (ITU-R BT.709).
LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)

#: Names accepted by :func:`tonemap`'s ``method``.
TONE_MAPPERS = ("aces", "reinhard", "clip")

# Exposures beyond +-256 stops only overflow float64; no real scene needs them.
_MAX_ABS_EXPOSURE = 256
# Exposed values are capped here before the curve; every curve maps it to >= 1 (clipped).
_MAX_EXPOSED = 1e30

# Reinhard et al.'s log-average offset, so that black pixels do not send log() to -inf.
_LOG_AVERAGE_DELTA = 1e-4


def _check_image(name: str, a, *, allow_negative: bool = True) -> np.ndarray:
    """``a`` as a float64 (H, W) or (H, W, C) array; :class:`DisplayError` naming ``name``
    when it is not numeric, 2-D or 3-D, non-empty, finite (and non-negative if asked)."""
    return check_array(name, a, error=DisplayError, allow_negative=allow_negative)


def _rgb(image: np.ndarray, name: str) -> np.ndarray:
    """Drop alpha; accept (H, W), (H, W, 3) and (H, W, 4)."""
    if image.ndim == 3:
        if image.shape[2] == 4:
            return image[..., :3]
        if image.shape[2] != 3:
            raise DisplayError(
                f"{name} must have 3 (RGB) or 4 (RGBA) channels, got shape {image.shape}"
            )
    return image


def luminance(image) -> np.ndarray:
    """Relative luminance Y of linear sRGB/Rec. 709 values.

    Parameters
    ----------
    image : array_like
        Linear values, ``(H, W)`` (already luminance: returned as is), ``(H, W, 3)`` or
        ``(H, W, 4)`` (alpha ignored).

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` float64, ``Y = 0.2126 R + 0.7152 G + 0.0722 B``.
    """
    img = _rgb(_check_image("image", image), "image")
    if img.ndim == 2:
        return img
    return img @ np.asarray(LUMINANCE_WEIGHTS)


def exposure_from_reference(reference, *, key: float = 0.18) -> float:
    """Exposure (in stops) that maps the reference's log-average luminance to ``key``.

    Reinhard's "key value" auto-exposure: with the log-average luminance
    ``L_avg = exp(mean(log(delta + Y)))`` over the non-black pixels (``Y > 0``;
    ``delta = 1e-4``): black sky and shadow pixels would drag the average down and over-expose
    every lit pixel. The exposure is ``log2(key / L_avg)``, so that ``2**exposure * L_avg == key``.
    The same exposure must then be used for the reference and every candidate.

    Parameters
    ----------
    reference : array_like
        Linear radiance, ``(H, W)`` or ``(H, W, 3|4)``, non-negative.
    key : float, keyword-only
        Target middle grey in linear units, in (0, 1); 0.18 is Reinhard's "normal key".

    Returns
    -------
    float
        Exposure in stops (the scale factor is ``2**exposure``). An all-black reference
        gives 0.0.

    References
    ----------
    .. [1] E. Reinhard, M. Stark, P. Shirley, J. Ferwerda, "Photographic tone reproduction
       for digital images", ACM Trans. Graph. 21(3), 2002. DOI: 10.1145/566654.566575
    """
    if not 0.0 < key < 1.0:
        raise DisplayError(f"key must be in (0, 1), got {key!r}")
    ref = _rgb(_check_image("reference", reference, allow_negative=False), "reference")
    y = ref if ref.ndim == 2 else ref @ np.asarray(LUMINANCE_WEIGHTS)
    lit = y > 0
    if not lit.any():
        return 0.0
    # black pixels (sky, hard shadow: this renderer has no ambient term) are not part of the
    # exposure: on `star` (mostly sky) they pushed the exposure up 6.8 stops and saturated
    # every lit pixel, so colour metrics hardly saw errors there
    log_average = float(np.exp(np.mean(np.log(_LOG_AVERAGE_DELTA + y[lit]))))
    return float(np.log2(key / log_average))


def srgb_encode(linear) -> np.ndarray:
    """sRGB transfer function (IEC 61966-2-1): linear values to display-encoded values.

    ``12.92 x`` for ``x <= 0.0031308``, else ``1.055 x**(1/2.4) - 0.055``. Defined for
    [0, 1]; values above 1 follow the power law, negative values the linear segment.

    Parameters
    ----------
    linear : array_like
        Linear values, any shape.

    Returns
    -------
    numpy.ndarray
        Encoded values, float32 for float32 or integer input, otherwise the input's float
        precision.

    References
    ----------
    .. [1] IEC 61966-2-1:1999, "Multimedia systems and equipment - Colour measurement and
       management - Part 2-1: Default RGB colour space - sRGB".
       M. Stokes et al., "A standard default color space for the Internet - sRGB", 1996.
    """
    x = np.asarray(linear)
    x = x.astype(np.result_type(x.dtype, np.float32), copy=False)
    power = 1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055
    return np.where(x <= 0.0031308, 12.92 * x, power).astype(x.dtype, copy=False)


def srgb_decode(encoded) -> np.ndarray:
    """Inverse sRGB transfer function: display-encoded values to linear values.

    ``x / 12.92`` for ``x <= 0.04045``, else ``((x + 0.055) / 1.055)**2.4``.

    Parameters
    ----------
    encoded : array_like
        sRGB-encoded values, nominally in [0, 1], any shape.

    Returns
    -------
    numpy.ndarray
        Linear values, float32 for float32 or integer input.

    References
    ----------
    .. [1] IEC 61966-2-1:1999 (see :func:`srgb_encode`).
    """
    x = np.asarray(encoded)
    x = x.astype(np.result_type(x.dtype, np.float32), copy=False)
    power = np.power((np.maximum(x, 0.04045) + 0.055) / 1.055, 2.4)
    return np.where(x <= 0.04045, x / 12.92, power).astype(x.dtype, copy=False)


def _aces(x: np.ndarray) -> np.ndarray:
    # Narkowicz's rational fit of the ACES RRT+ODT: x (a x + b) / (x (c x + d) + e).
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    return (x * (a * x + b)) / (x * (c * x + d) + e)


def _reinhard(x: np.ndarray) -> np.ndarray:
    # Reinhard's global operator on luminance, colour scaled alike: x / (1 + Y).
    y = x if x.ndim == 2 else x @ np.asarray(LUMINANCE_WEIGHTS)
    y = y if x.ndim == 2 else y[..., None]
    return x / (1.0 + y)


_CURVES = {"aces": _aces, "reinhard": _reinhard, "clip": lambda x: x}


def tonemap(image, *, exposure: float, method: str = "aces") -> np.ndarray:
    """Apply the shared pipeline: drop alpha, expose, tone map, clip, sRGB-encode.

    Parameters
    ----------
    image : array_like
        Linear radiance, ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` (alpha dropped);
        negative values are clamped to 0.
    exposure : float, keyword-only
        Exposure in stops: the image is multiplied by ``2**exposure`` before the curve.
        Use :func:`exposure_from_reference` on the reference, and the same value for every
        image compared with it.
    method : {"aces", "reinhard", "clip"}, keyword-only
        ``"aces"``: Narkowicz's fit ``x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14)`` per
        channel (no built-in exposure bias). ``"reinhard"``: ``x / (1 + Y)`` with ``Y`` the
        Rec. 709 luminance of the exposed pixel (Reinhard et al. 2002, eq. 3).
        ``"clip"``: no curve, values above 1 clip.

    Returns
    -------
    numpy.ndarray
        sRGB-encoded float32 in [0, 1], shape ``(H, W)`` or ``(H, W, 3)``.

    Raises
    ------
    DisplayError
        On an unknown ``method``, a non-finite ``exposure``, or invalid ``image``.

    References
    ----------
    .. [1] K. Narkowicz, "ACES Filmic Tone Mapping Curve", blog post, 2016.
       https://knarkowicz.wordpress.com/2016/01/06/aces-filmic-tone-mapping-curve/
    .. [2] E. Reinhard, M. Stark, P. Shirley, J. Ferwerda, "Photographic tone reproduction
       for digital images", ACM Trans. Graph. 21(3), 2002. DOI: 10.1145/566654.566575
    .. [3] IEC 61966-2-1:1999 (sRGB transfer function).
    """
    if method not in _CURVES:
        raise DisplayError(f"method must be one of {', '.join(TONE_MAPPERS)}, got {method!r}")
    if not (np.isfinite(exposure) and abs(exposure) <= _MAX_ABS_EXPOSURE):
        raise DisplayError(
            f"exposure must be a finite number of stops in [-{_MAX_ABS_EXPOSURE}, "
            f"{_MAX_ABS_EXPOSURE}], got {exposure!r}"
        )
    img = _rgb(_check_image("image", image), "image")
    # Clamp before the curve: ACES's x**2 overflows to inf/inf = NaN for x > ~1e154.
    with np.errstate(over="ignore"):
        x = np.clip(img * (2.0 ** float(exposure)), 0.0, _MAX_EXPOSED)
    mapped = np.clip(_CURVES[method](x), 0.0, 1.0)
    return srgb_encode(mapped.astype(np.float32))


def _aces_inverse(y: np.ndarray) -> np.ndarray:
    # the positive root of (2.43 y - 2.51) x^2 + (0.59 y - 0.03) x + 0.14 y = 0, written as
    # 2c / (-b + sqrt(b^2 - 4ac)) so that it stays exact near y = 0 (no cancellation)
    a, b, c = 2.43 * y - 2.51, 0.59 * y - 0.03, 0.14 * y
    return 2.0 * c / (-b + np.sqrt(b * b - 4.0 * a * c))


def _reinhard_inverse(y: np.ndarray) -> np.ndarray:
    # x / (1 + Y) has luminance Y / (1 + Y): Y = Y' / (1 - Y'), x = y (1 + Y)
    lum = y if y.ndim == 2 else y @ np.asarray(LUMINANCE_WEIGHTS)
    lum = np.minimum(lum, 1.0 - 1e-7)
    scale = 1.0 + lum / (1.0 - lum)
    return y * (scale if y.ndim == 2 else scale[..., None])


_INVERSES = {"aces": _aces_inverse, "reinhard": _reinhard_inverse, "clip": lambda y: y}


def tonemap_inverse(display, *, exposure: float, method: str = "aces") -> np.ndarray:
    """Linear radiance that :func:`tonemap` maps to ``display`` (the pipeline run backwards).

    Used where a technique works in display space (FXAA after tone mapping) and its result
    must enter the scoring pipeline, which tone-maps every candidate itself:
    ``tonemap(tonemap_inverse(d, exposure=e), exposure=e)`` returns ``d`` up to float32
    rounding. A display value of 1 (where the curve was clipped) maps back to the smallest
    radiance the curve takes to 1 (ACES: ``x = 7.24`` exposed), so clipped inputs come back
    at the clip level, not at their original radiance.

    Parameters
    ----------
    display : array_like
        sRGB-encoded values in [0, 1] (values outside are clipped), ``(H, W)`` or
        ``(H, W, 3)``, or any ``(..., 3)`` array for ``aces`` and ``clip``.
    exposure, method : as in :func:`tonemap`.

    Returns
    -------
    numpy.ndarray
        Linear radiance, float64, same shape.
    """
    if method not in _INVERSES:
        raise DisplayError(f"method must be one of {', '.join(TONE_MAPPERS)}, got {method!r}")
    if not (np.isfinite(exposure) and abs(exposure) <= _MAX_ABS_EXPOSURE):
        raise DisplayError(f"exposure must be a finite number of stops, got {exposure!r}")
    y = np.clip(srgb_decode(np.asarray(display, np.float64)), 0.0, 1.0)
    return _INVERSES[method](y) / 2.0 ** float(exposure)
