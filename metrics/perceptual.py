"""Perceptual and image-fidelity metrics of colour images: FLIP, SSIM, PSNR, CIEDE2000.

Every metric here except HDR-FLIP first puts reference and candidate through the one
pipeline of :mod:`metrics.tonemap` (drop alpha, one exposure from the reference, one tone
mapper, clip to [0, 1], sRGB-encode), so all LDR metrics of a report see the same pixels.
HDR-FLIP takes linear radiance and brackets exposures itself; :func:`hdr_exposure_range`
fixes that bracket from the reference so that every candidate is judged over the same one.

Inputs are linear radiance, float, ``(H, W)`` (grey, replicated to RGB where a metric needs
colour), ``(H, W, 3)`` or ``(H, W, 4)`` (alpha dropped), row 0 at the top.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import math
from collections import OrderedDict

import numpy as np

from .tonemap import (
    LUMINANCE_WEIGHTS,
    TONE_MAPPERS,
    exposure_from_reference,
    srgb_decode,
    tonemap,
)
from .validate import MetricError, check_image, check_images

__all__ = [
    "DEFAULT_PPD",
    "delta_e2000",
    "delta_e2000_lab",
    "flip",
    "hdr_exposure_range",
    "psnr_db",
    "ssim",
]

#: FLIP's default pixels per degree (about 67.02): a 0.7 m wide 3840-pixel display seen from
#: 0.7 m, computed as FLIP does, ``distance * (width_px / width_m) * pi / 180``.
DEFAULT_PPD = 0.7 * 3840 / 0.7 * math.pi / 180

# HDR-FLIP's exposure bracket (Andersson et al. 2021, section 3): the exposure at which the
# ACES curve (with its 0.6 pre-exposure folded in) reaches 0.85 ...
_FLIP_T = 0.85
# ... for FLIP's ACES coefficients k0..k5 of (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5).
_FLIP_ACES = (0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14)

_FLIP_MODES = ("LDR", "HDR")


def _as_rgb(img: np.ndarray, name: str) -> np.ndarray:
    """(H, W) -> (H, W, 3) by replication; (H, W, 4) -> (H, W, 3); (H, W, 3) as is."""
    if img.ndim == 2:
        return np.repeat(img[..., None], 3, axis=2)
    if img.shape[2] == 4:
        return img[..., :3]
    if img.shape[2] != 3:
        raise MetricError(f"{name} must have 3 (RGB) or 4 (RGBA) channels, got shape {img.shape}")
    return img


#: Bytes of reference sides (:func:`_reference_side`) this process keeps, oldest dropped
#: first: about 17 references of 640 x 360 (their tone-mapped image and CIE Lab).
REFERENCE_SIDE_BYTES = 192 << 20

_SIDES: OrderedDict = OrderedDict()


def _side_bytes(side: dict) -> int:
    return sum(v.nbytes for v in side.values() if isinstance(v, np.ndarray))


def _reference_side(ref: np.ndarray, exposure, tone_mapper: str) -> dict:
    """The reference's half of the tone-mapped metrics: ``{"exposure", "display"}`` (its
    exposure and tone-mapped image), and ``"lab"`` once :func:`delta_e2000` asked for it.

    Several candidates are judged against one reference (the cases of a sweep, the noise
    floor), so it is kept: keyed by the reference's bytes, shape and dtype with the exposure
    and tone mapper asked for, it is what recomputing would give, bit for bit. Its arrays
    are read-only."""
    digest = hashlib.blake2b(np.ascontiguousarray(ref).data, digest_size=20).digest()
    key = (digest, ref.shape, ref.dtype.str, exposure, tone_mapper)
    side = _SIDES.get(key)
    if side is not None:
        _SIDES.move_to_end(key)
        return side
    if exposure is None:
        exposure = exposure_from_reference(np.maximum(ref, 0.0))
    display = tonemap(ref, exposure=exposure, method=tone_mapper)
    display.setflags(write=False)
    side = {"exposure": exposure, "display": display}
    _SIDES[key] = side
    _trim_sides()
    return side


def _trim_sides() -> None:
    total = sum(_side_bytes(s) for s in _SIDES.values())
    while _SIDES and total > REFERENCE_SIDE_BYTES:
        total -= _side_bytes(_SIDES.popitem(last=False)[1])


def _tonemapped_sides(reference, candidate, exposure, tone_mapper):
    """Validate, then run both images through the shared pipeline with one exposure: the
    reference's side (:func:`_reference_side`) and the tone-mapped candidate."""
    ref, cand = check_images("reference", reference, "candidate", candidate)
    if tone_mapper not in TONE_MAPPERS:
        raise MetricError(
            f"tone_mapper must be one of {', '.join(TONE_MAPPERS)}, got {tone_mapper!r}"
        )
    side = _reference_side(ref, exposure, tone_mapper)
    return side, tonemap(cand, exposure=side["exposure"], method=tone_mapper)


def _tonemapped_pair(reference, candidate, exposure, tone_mapper):
    """Validate, then run both images through the shared pipeline with one exposure."""
    side, cand = _tonemapped_sides(reference, candidate, exposure, tone_mapper)
    return side["display"], cand


def hdr_exposure_range(reference) -> tuple[float, float]:
    """HDR-FLIP's start and stop exposures, computed from the reference alone.

    As FLIP does it: with ``x_t`` the exposed value at which FLIP's ACES curve reaches
    ``t = 0.85``, ``start = log2(x_t / Y_max)`` (the brightest pixel just reaches 0.85)
    and ``stop = log2(x_t / Y_median)`` (the median pixel does), with ``Y`` the Rec. 709
    luminance and ``Y_median`` the upper median (element ``n // 2`` of the sorted values,
    as FLIP's C++ code picks it). Compute it once per reference and pass it as
    ``exposure_range`` to :func:`flip` for every candidate.

    Parameters
    ----------
    reference : array_like
        Linear radiance, ``(H, W)`` or ``(H, W, 3|4)``, non-negative.

    Returns
    -------
    tuple of float
        ``(start, stop)`` in stops, ``start <= stop``. An all-black reference gives
        ``(0.0, 0.0)``. When more than half of the pixels are black, the median of the
        non-black pixels is used (FLIP itself would get an infinite stop exposure).

    References
    ----------
    .. [1] P. Andersson, J. Nilsson, P. Shirley, T. Akenine-Moller, "Visualizing Errors in
       Rendered High Dynamic Range Images", Eurographics 2021 short papers.
       DOI: 10.2312/egs.20211015
    """
    ref = _as_rgb(check_image("reference", reference, allow_negative=False), "reference")
    y = ref @ np.asarray(LUMINANCE_WEIGHTS)
    y_max = float(y.max())
    if y_max <= 0.0:
        return 0.0, 0.0
    k0, k1, k2, k3, k4, k5 = _FLIP_ACES
    c0 = (k1 - k4 * _FLIP_T) / (k0 - k3 * _FLIP_T)
    c1 = (k2 - k5 * _FLIP_T) / (k0 - k3 * _FLIP_T)
    x_t = -0.5 * c0 + math.sqrt((0.5 * c0) ** 2 - c1)
    flat = y.ravel()
    if np.count_nonzero(flat > 0) * 2 <= flat.size:
        flat = flat[flat > 0]
    y_median = float(np.partition(flat, flat.size // 2)[flat.size // 2])
    start = math.log2(x_t / y_max)
    stop = math.log2(x_t / y_median)
    return start, stop


def flip(
    reference,
    candidate,
    *,
    mode: str = "LDR",
    ppd: float = DEFAULT_PPD,
    exposure: float | None = None,
    tone_mapper: str = "aces",
    exposure_range: tuple[float, float] | None = None,
    full: bool = False,
):
    """NVIDIA FLIP difference between reference and candidate, via ``flip_evaluator``.

    ``mode="LDR"``: both images go through the shared pipeline (:func:`metrics.tonemap.
    tonemap` with one ``exposure`` from the reference) and the sRGB-encoded results are
    given to LDR-FLIP with ``inputsRGB=True``, i.e. FLIP sees exactly what a display
    shows. For data that is already display-linear in [0, 1] (visibility, coverage) use
    ``tone_mapper="clip", exposure=0``.

    ``mode="HDR"``: linear radiance goes to HDR-FLIP directly (FLIP applies its own ACES
    curve over a bracket of exposures and keeps the per-pixel maximum); ``exposure`` and
    ``tone_mapper`` are not used. The bracket is ``exposure_range``, by default
    :func:`hdr_exposure_range` of the reference; pass the same value for every candidate.

    Parameters
    ----------
    reference, candidate : array_like
        Linear radiance, ``(H, W)`` (replicated to RGB), ``(H, W, 3)`` or ``(H, W, 4)``
        (alpha dropped: FLIP would score RGBA wrongly), same shape; non-negative for HDR.
    mode : {"LDR", "HDR"}, keyword-only
    ppd : float, keyword-only
        Pixels per degree of visual angle, > 0. Default :data:`DEFAULT_PPD` (about 67.02,
        FLIP's own default).
    exposure : float or None, keyword-only
        LDR only: exposure in stops, default :func:`~metrics.tonemap.exposure_from_reference`
        of the reference.
    tone_mapper : {"aces", "reinhard", "clip"}, keyword-only
        LDR only: tone mapper of the shared pipeline.
    exposure_range : (float, float) or None, keyword-only
        HDR only: ``(start, stop)`` exposures in stops, ``start <= stop``.
    full : bool, keyword-only
        Also return the per-pixel error map.

    Returns
    -------
    mean : float
        Mean FLIP error, in [0, 1] (0 = identical).
    error_map : numpy.ndarray
        Only when ``full=True``: ``(H, W)`` float32 per-pixel FLIP error in [0, 1] (raw
        values, no colour map). Maps differ across platforms in the last digits.

    Raises
    ------
    MetricError
        On invalid images or options, or when ``flip_evaluator`` rejects its arguments
        (it calls ``sys.exit``; that is turned into this exception).

    References
    ----------
    .. [1] P. Andersson, J. Nilsson, T. Akenine-Moller, M. Oskarsson, K. Astrom,
       M. D. Fairchild, "FLIP: A Difference Evaluator for Alternating Images", Proc. ACM
       Comput. Graph. Interact. Tech. 3(2), 2020. DOI: 10.1145/3406183
    .. [2] P. Andersson, J. Nilsson, P. Shirley, T. Akenine-Moller, "Visualizing Errors in
       Rendered High Dynamic Range Images", Eurographics 2021 short papers.
       DOI: 10.2312/egs.20211015
    """
    if mode not in _FLIP_MODES:
        raise MetricError(f"mode must be one of {', '.join(_FLIP_MODES)}, got {mode!r}")
    if not (np.isfinite(ppd) and ppd > 0):
        raise MetricError(f"ppd must be a positive number of pixels per degree, got {ppd!r}")
    if mode == "LDR" and exposure_range is not None:
        raise MetricError("exposure_range is used with mode='HDR' only; got mode='LDR'")
    if mode == "HDR" and exposure is not None:
        raise MetricError(
            "exposure is used with mode='LDR' only (HDR-FLIP brackets exposures itself, "
            "see exposure_range); got mode='HDR'"
        )
    parameters: dict = {"ppd": float(ppd)}
    if mode == "LDR":
        ref, cand = _tonemapped_pair(reference, candidate, exposure, tone_mapper)
        input_srgb = True
    else:
        ref, cand = check_images(
            "reference", reference, "candidate", candidate, allow_negative=False
        )
        if exposure_range is None:
            exposure_range = hdr_exposure_range(ref)
        start, stop = _check_exposure_range(exposure_range)
        parameters.update(startExposure=start, stopExposure=stop)
        input_srgb = False
    ref = np.ascontiguousarray(_as_rgb(ref, "reference"), dtype=np.float32)
    if not ref.flags.writeable:  # a kept reference side: flip_evaluator takes writable arrays
        ref = ref.copy()
    cand = np.ascontiguousarray(_as_rgb(cand, "candidate"), dtype=np.float32)
    error_map, mean = _evaluate_flip(ref, cand, mode, input_srgb, parameters)
    if full:
        return mean, error_map
    return mean


def _check_exposure_range(exposure_range) -> tuple[float, float]:
    try:
        start, stop = (float(v) for v in exposure_range)
    except (TypeError, ValueError) as exc:
        raise MetricError(
            f"exposure_range must be a pair (start, stop) of stops, got {exposure_range!r}"
        ) from exc
    if not (math.isfinite(start) and math.isfinite(stop) and start <= stop):
        raise MetricError(
            f"exposure_range must be finite with start <= stop, got ({start!r}, {stop!r})"
        )
    return start, stop


def _evaluate_flip(ref, cand, mode, input_srgb, parameters):
    import flip_evaluator

    captured = io.StringIO()
    try:
        with contextlib.redirect_stdout(captured):
            error_map, mean, _ = flip_evaluator.evaluate(
                ref,
                cand,
                mode,
                inputsRGB=input_srgb,
                applyMagma=False,
                computeMeanError=True,
                parameters=parameters,
            )
    except SystemExit as exc:
        message = " ".join(captured.getvalue().split())
        if not message and exc.code in (130, 143):
            raise  # a stop (SIGINT/SIGTERM unwinding through the call), not flip's refusal
        message = message or f"exit status {exc.code}"
        raise MetricError(f"flip_evaluator rejected its arguments: {message}") from None
    except (RuntimeError, TypeError) as exc:
        raise MetricError(f"flip_evaluator failed: {exc}") from exc
    return np.asarray(error_map, dtype=np.float32)[..., 0], float(mean)


def ssim(
    reference,
    candidate,
    *,
    exposure: float | None = None,
    tone_mapper: str = "aces",
    full: bool = False,
):
    """Structural similarity (SSIM) after the shared tone-mapping pipeline.

    Computed by ``skimage.metrics.structural_similarity`` on the sRGB-encoded images with
    ``data_range=1``, ``gaussian_weights=True``, ``sigma=1.5``,
    ``use_sample_covariance=False`` (Wang et al.'s settings), per channel for colour.

    Parameters
    ----------
    reference, candidate : array_like
        Linear radiance, ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``, same shape, at least
        11 x 11 pixels (the Gaussian window).
    exposure : float or None, keyword-only
        Exposure in stops, default from the reference (:func:`~metrics.tonemap.
        exposure_from_reference`).
    tone_mapper : {"aces", "reinhard", "clip"}, keyword-only
    full : bool, keyword-only
        Also return scikit-image's SSIM map.

    Returns
    -------
    mssim : float
        Mean SSIM, in [-1, 1] (1 = identical).
    ssim_map : numpy.ndarray
        Only when ``full=True``: float32 map of the tone-mapped images' shape.

    References
    ----------
    .. [1] Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image quality
       assessment: from error visibility to structural similarity", IEEE Trans. Image
       Process. 13(4), 2004. DOI: 10.1109/TIP.2003.819861
    """
    from skimage.metrics import structural_similarity

    ref, cand = _tonemapped_pair(reference, candidate, exposure, tone_mapper)
    try:
        result = structural_similarity(
            ref,
            cand,
            data_range=1.0,
            channel_axis=-1 if ref.ndim == 3 else None,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            full=full,
        )
    except ValueError as exc:
        raise MetricError(f"SSIM needs images of at least 11 x 11 pixels: {exc}") from exc
    if full:
        mssim, ssim_map = result
        return float(mssim), np.asarray(ssim_map, dtype=np.float32)
    return float(result)


def psnr_db(
    reference,
    candidate,
    *,
    exposure: float | None = None,
    tone_mapper: str = "aces",
) -> float:
    """Peak signal-to-noise ratio, in dB, after the shared tone-mapping pipeline.

    ``10 log10(1 / MSE)`` of the sRGB-encoded images (``data_range=1``), as
    ``skimage.metrics.peak_signal_noise_ratio`` computes it.

    Parameters
    ----------
    reference, candidate : array_like
        Linear radiance, ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``, same shape.
    exposure : float or None, keyword-only
        Exposure in stops, default from the reference.
    tone_mapper : {"aces", "reinhard", "clip"}, keyword-only

    Returns
    -------
    float
        PSNR in dB; ``math.inf`` when the tone-mapped images are identical.

    References
    ----------
    .. [1] Q. Huynh-Thu, M. Ghanbari, "Scope of validity of PSNR in image/video quality
       assessment", Electronics Letters 44(13), 2008. DOI: 10.1049/el:20080522
    """
    from skimage.metrics import peak_signal_noise_ratio

    ref, cand = _tonemapped_pair(reference, candidate, exposure, tone_mapper)
    if np.array_equal(ref, cand):
        return math.inf  # skimage would divide by a zero MSE
    return float(peak_signal_noise_ratio(ref, cand, data_range=1.0))


def delta_e2000_lab(lab_a, lab_b) -> np.ndarray:
    """CIEDE2000 colour difference of CIE L*a*b* values, via colour-science.

    Parameters
    ----------
    lab_a, lab_b : array_like
        CIE L*a*b* values, shape ``(..., 3)``, same shape; L* in [0, 100] (reference scale).

    Returns
    -------
    numpy.ndarray
        float64 Delta E 00 of shape ``(...)`` (a 0-d array for single colours), >= 0;
        symmetric in its arguments; about 1 is a just-noticeable difference.

    References
    ----------
    .. [1] G. Sharma, W. Wu, E. N. Dalal, "The CIEDE2000 color-difference formula:
       Implementation notes, supplementary test data, and mathematical observations",
       Color Res. Appl. 30(1), 2005. DOI: 10.1002/col.20070
    """
    import colour

    shape_a, shape_b = np.shape(lab_a), np.shape(lab_b)
    if shape_a != shape_b:
        raise MetricError(
            f"lab_a and lab_b must have the same shape, got {tuple(shape_a)} and {tuple(shape_b)}"
        )
    if len(shape_a) == 0 or shape_a[-1] != 3:
        raise MetricError(f"lab_a and lab_b must have shape (..., 3), got {tuple(shape_a)}")
    ndim = (len(shape_a),)
    a, b = check_images("lab_a", lab_a, "lab_b", lab_b, ndim=ndim)
    return np.asarray(colour.delta_E(a, b, method="CIE 2000"), dtype=np.float64)


def delta_e2000(
    reference,
    candidate,
    *,
    exposure: float | None = None,
    tone_mapper: str = "aces",
    full: bool = False,
):
    """Mean CIEDE2000 difference after the shared tone-mapping pipeline.

    The sRGB-encoded pipeline output is decoded back to linear sRGB in [0, 1] (display
    white has Y = 1), converted to CIE XYZ and to CIE L*a*b* with the sRGB (D65) white
    point, and compared with :func:`delta_e2000_lab`.

    Parameters
    ----------
    reference, candidate : array_like
        Linear radiance, ``(H, W)`` (grey), ``(H, W, 3)`` or ``(H, W, 4)``, same shape.
    exposure : float or None, keyword-only
        Exposure in stops, default from the reference.
    tone_mapper : {"aces", "reinhard", "clip"}, keyword-only
    full : bool, keyword-only
        Also return the per-pixel map.

    Returns
    -------
    mean : float
        Mean Delta E 00 over pixels, >= 0.
    delta_e_map : numpy.ndarray
        Only when ``full=True``: ``(H, W)`` float32 per-pixel Delta E 00.

    References
    ----------
    .. [1] G. Sharma, W. Wu, E. N. Dalal, "The CIEDE2000 color-difference formula:
       Implementation notes, supplementary test data, and mathematical observations",
       Color Res. Appl. 30(1), 2005. DOI: 10.1002/col.20070
    .. [2] M. R. Luo, G. Cui, B. Rigg, "The development of the CIE 2000 colour-difference
       formula: CIEDE2000", Color Res. Appl. 26(5), 2001. DOI: 10.1002/col.1049
    """
    side, cand = _tonemapped_sides(reference, candidate, exposure, tone_mapper)
    lab_ref = side.get("lab")
    if lab_ref is None:
        lab_ref = _linear_srgb_to_lab(srgb_decode(_as_rgb(side["display"], "reference")))
        lab_ref.setflags(write=False)
        side["lab"] = lab_ref
        _trim_sides()
    lab_cand = _linear_srgb_to_lab(srgb_decode(_as_rgb(cand, "candidate")))
    de = delta_e2000_lab(lab_ref, lab_cand)
    if full:
        return float(de.mean()), de.astype(np.float32)
    return float(de.mean())


def _linear_srgb_to_lab(linear: np.ndarray) -> np.ndarray:
    import colour

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    xyz = colour.RGB_to_XYZ(linear.astype(np.float64), srgb, apply_cctf_decoding=False)
    return colour.XYZ_to_Lab(xyz, illuminant=srgb.whitepoint)
