"""An external engine's candidate image: its errors, its value checks, the PNG reader and the
EXR motion layer. Which EXR channels are read is decided in one place,
:mod:`oracle.scoring.inputs.layout` (:func:`~oracle.scoring.inputs.layout.load_candidate`).

- **EXR**: values are taken as linear; half, float and uint channels are returned as float32.
- **PNG**: 8-bit grey/grey+alpha/RGB/RGBA/palette and 16-bit grey (via Pillow), 16-bit
  RGB/RGBA (via pypng: Pillow would reduce them to 8 bits a channel). Colour is
  taken as sRGB-encoded (what engines write to PNG) and decoded to linear. A grey PNG read
  as ``visibility`` is *data*, not colour: its values are scaled to [0, 1] (``v / 255`` or
  ``v / 65535``) and **not** sRGB-decoded, so 50 % visibility is stored as 128 (8-bit).

Alpha is ignored everywhere.
"""

from __future__ import annotations

import os
import struct
import warnings
from pathlib import Path

import numpy as np
import png

from ....scenes.base.arrays import nonfinite_counts
from ...errors import InputError, InputWarning
from ...reference.exr import ExrError, read_exr

__all__ = [
    "DATA_RANGE_EPSILON",
    "RADIANCE_EPSILON",
    "CandidateError",
    "CandidateWarning",
    "MissingChannelError",
    "check_candidate_values",
    "load_motion",
    "png_is_grey",
    "read_png",
    "TRANSFERS",
    "decode_transfer",
]

#: How far grey data (visibility, coverage) may leave [0, 1] and still be clamped into it:
#: half-float conversion (1 ulp at 1.0 is 9.8e-4 / 2 ... 4.9e-4 below 1, 1e-7 in float32),
#: filtering and TAA resolves overshoot by float rounding, never by a visible 1e-3.
DATA_RANGE_EPSILON = 1e-4
#: Negative radiance down to -RADIANCE_EPSILON x the image's maximum is clamped to 0: the
#: ringing of a reconstruction filter or a resolve's float rounding, not a wrong image.
RADIANCE_EPSILON = 1e-4

#: How an 8/16-bit PNG's colour is decoded to linear radiance (``--transfer``).
TRANSFERS = ("srgb", "gamma2.2", "linear")
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# PNG colour types (PNG spec, table 11.1) that carry colour: truecolour and truecolour+alpha.
_PNG_COLOUR_TYPES = (2, 6)


class CandidateError(InputError):
    """A candidate image that cannot be used: unreadable, wrong size, missing channel, NaN."""


class MissingChannelError(CandidateError):
    """The candidate file lacks the channel or layer asked for (its own are listed): in a
    folder run, an error of that scene alone."""


class CandidateWarning(InputWarning):
    """A candidate's values just outside their range were clamped (count and extremes)."""


def check_candidate_values(path, image: np.ndarray, *, expected_shape, kind: str) -> np.ndarray:
    """A candidate image of ``kind`` has the reference's size, finite values, non-negative
    colour and grey data (visibility, coverage) in [0, 1]; else :class:`CandidateError`.

    Values outside their range by at most :data:`DATA_RANGE_EPSILON` (grey data) or
    ``RADIANCE_EPSILON`` x the image maximum (negative radiance) are clamped, with one
    :class:`CandidateWarning` giving their count and extreme values; returns the image
    (clamped, or as given)."""
    path = Path(path)
    _check_shape(path, image, expected_shape)
    return _check_values(path, image, kind)


def png_is_grey(path) -> bool:
    """A PNG whose colour type (IHDR) is grey or grey + alpha (any bit depth)."""
    _, colour_type = _png_header(Path(path))
    return colour_type in (0, 4)


def _check_shape(path: Path, image: np.ndarray, expected_shape) -> None:
    if expected_shape is None:
        return
    try:
        h, w = (int(v) for v in expected_shape)
    except (TypeError, ValueError) as exc:
        raise CandidateError(
            f"expected_shape must be (height, width), got {expected_shape!r}"
        ) from exc
    ch, cw = image.shape[:2]
    if (ch, cw) != (h, w):
        raise CandidateError(f"candidate is {cw}x{ch}, the reference is {w}x{h} ({path.name})")


def _exact(value) -> str:
    """A float32 value with the digits that tell it from its neighbours (``1.0000001``,
    ``-1e-07``): a rounded ``1`` would hide why it is out of range. The shortest text that
    reads back as the same float32 (9 significant digits always do)."""
    exact = np.float32(value)
    for digits in range(1, 10):
        text = f"{float(exact):.{digits}g}"
        if np.float32(float(text)) == exact:
            return text
    return repr(float(exact))


def _check_values(path: Path, image: np.ndarray, channel: str) -> np.ndarray:
    counts = nonfinite_counts(image)
    if counts is not None:
        raise CandidateError(
            f"candidate {path.name} channel {channel!r} has {counts[0]} NaN and {counts[1]} "
            f"inf values (of {image.size})"
        )
    if channel in ("visibility", "coverage"):
        low, high = 0.0, 1.0
        eps_low = eps_high = DATA_RANGE_EPSILON
        what, tolerance = f"{channel} must be in [0, 1]", f"{DATA_RANGE_EPSILON:g}"
    elif channel == "color":
        low, high = 0.0, np.inf
        eps_low, eps_high = RADIANCE_EPSILON * max(float(image.max()), 0.0), 0.0
        what = "radiance must be >= 0"
        tolerance = f"{RADIANCE_EPSILON:g} x the image maximum = {eps_low:.3g}"
    else:
        return image
    out = (image < low) | (image > high)
    n_out = int(out.sum())
    if not n_out:
        return image
    lo, hi = float(image.min()), float(image.max())
    extremes = ", ".join(
        f"{label} {_exact(v)}"
        for label, v, bad in (("min", lo, lo < low), ("max", hi, hi > high))
        if bad
    )
    if lo < low - eps_low or hi > high + eps_high:
        raise CandidateError(
            f"candidate {path.name}: {what}, got {n_out} "
            f"{'values outside' if high == 1.0 else 'negative values'} ({extremes}); "
            f"beyond the {tolerance} that is clamped"
        )
    warnings.warn(
        CandidateWarning(
            f"candidate {path.name}: clamped {n_out} {channel} values outside "
            f"{'[0, 1]' if high == 1.0 else '>= 0'} by at most {tolerance} ({extremes})"
        ),
        stacklevel=2,
    )
    return np.clip(image, low, high).astype(np.float32)


# --------------------------------------------------------------------------- EXR motion


def load_motion(
    path: str | os.PathLike,
    *,
    layer: str,
    convention: str,
    expected_shape: tuple[int, int],
    disocclusion: str | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """An engine's motion vectors from EXR layer ``layer`` (channels ``layer.X/Y``,
    ``layer.R/G`` or ``layer.U/V``), converted from ``convention``
    (:data:`metrics.motion.CONVENTIONS`) to the oracle's pixels, ``(H, W, 2)`` float64; and
    with ``disocclusion``, that channel as the engine's disocclusion mask (``> 0.5``).

    Raises
    ------
    CandidateError
        Not an EXR, no such layer or channel (listing the channels), wrong size, NaN or inf.
    """
    from .... import metrics as M

    path = Path(path)
    if path.suffix.lower() != ".exr":
        raise CandidateError(f"motion vectors are read from an EXR layer, got {path.name}")
    try:
        raw = read_exr(path)
    except ExrError as exc:
        raise CandidateError(f"candidate {path.name} is not a readable EXR ({exc})") from exc
    pair = next(
        (
            (raw[f"{layer}.{a}"], raw[f"{layer}.{b}"])
            for a, b in ("XY", "RG", "UV")
            if f"{layer}.{a}" in raw and f"{layer}.{b}" in raw
        ),
        None,
    )
    if pair is None:
        raise CandidateError(
            f"candidate {path.name} has no motion layer {layer!r} ({layer}.X/Y, .R/G or .U/V); "
            f"available: {', '.join(sorted(raw))}"
        )
    for channel in pair:  # each channel its own size (a sub-sampled .Y: issue 48)
        if np.ndim(channel) != 2:
            raise CandidateError(f"candidate {path.name}: motion layer {layer!r} is not 2-D")
        _check_shape(path, np.asarray(channel), expected_shape or np.shape(pair[0]))
    mv = np.stack([np.asarray(c, dtype=np.float64) for c in pair], -1)
    if not np.all(np.isfinite(mv)):
        raise CandidateError(f"candidate {path.name}: motion layer {layer!r} holds NaN or inf")
    h, w = expected_shape
    mv = M.to_oracle_motion(mv, convention=convention, width=w, height=h)
    mask = None
    if disocclusion is not None:
        if disocclusion not in raw:
            raise CandidateError(
                f"candidate {path.name} has no channel {disocclusion!r}; "
                f"available: {', '.join(sorted(raw))}"
            )
        _check_shape(path, np.asarray(raw[disocclusion]), mv.shape[:2])
        mask = np.asarray(raw[disocclusion]) > 0.5
    return mv, mask


# --------------------------------------------------------------------------- PNG


def _png_header(path: Path) -> tuple[int, int]:
    """(bit depth, colour type) from the IHDR chunk, which the PNG spec puts first."""
    with open(path, "rb") as f:
        head = f.read(26)
    if len(head) < 26 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise CandidateError(f"candidate {path.name} is truncated or not a PNG file")
    bit_depth, colour_type = struct.unpack(">BB", head[24:26])
    return bit_depth, colour_type


def decode_transfer(values: np.ndarray, transfer: str) -> np.ndarray:
    """Encoded display values in [0, 1] -> linear, by ``transfer`` (:data:`TRANSFERS`)."""
    from ....metrics.tonemap import srgb_decode

    if transfer == "srgb":
        return srgb_decode(values)
    if transfer == "gamma2.2":
        return np.power(np.clip(values, 0.0, 1.0), np.float32(2.2))
    if transfer == "linear":
        return values
    raise CandidateError(f"transfer must be one of {', '.join(TRANSFERS)}, got {transfer!r}")


def read_png(path: Path, channel: str, transfer: str = "srgb") -> np.ndarray:
    """A PNG's pixels as ``channel`` (``color``: decoded by ``transfer`` to linear, grey
    replicated; ``visibility``: grey values as data in [0, 1]), unchecked; the one PNG
    reader (:func:`oracle.scoring.inputs.layout.read_candidate` checks the values)."""
    from PIL import Image

    if channel not in ("color", "visibility"):
        raise CandidateError(
            f"candidate {path.name} is a PNG, which has no named channels: channel must be "
            f"'color' or 'visibility', got {channel!r}"
        )
    bit_depth, colour_type = _png_header(path)
    try:
        if bit_depth == 16 and colour_type in _PNG_COLOUR_TYPES:
            # Pillow reduces 16-bit colour to 8 bits a channel; pypng keeps all 16
            pixels, scale = _png16_colour(path)
        else:
            with Image.open(path) as im:
                im.load()
                pixels, scale = _png_pixels(im)
    except CandidateError:
        raise
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError, png.Error) as exc:
        raise CandidateError(
            f"candidate {path.name} is truncated or not a readable PNG ({exc})"
        ) from exc
    values = pixels.astype(np.float32) / np.float32(scale)
    if channel == "visibility":
        return _png_visibility(path, values)
    if values.ndim == 2:
        values = np.repeat(values[..., None], 3, axis=-1)
    return np.ascontiguousarray(decode_transfer(values, transfer), dtype=np.float32)


def _png16_colour(path: Path) -> tuple[np.ndarray, float]:
    """A 16-bit RGB(A) PNG as ``(H, W, 3)`` uint16 (rows decoded by pypng, one per scanline)."""
    with open(path, "rb") as f:
        width, height, rows, info = png.Reader(file=f).asDirect()
        planes = info["planes"]
        data = np.vstack([np.asarray(row, dtype=np.uint16) for row in rows])
    return data.reshape(height, width, planes)[..., :3], 65535.0


def _png_pixels(im) -> tuple[np.ndarray, float]:
    """Pixel array without alpha and the value of full scale (white)."""
    mode = im.mode
    if mode == "P":
        im = im.convert("RGBA")
        mode = im.mode
    if mode == "1":
        return np.asarray(im, dtype=np.uint8), 1.0
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        return np.asarray(im).astype(np.int64), 65535.0
    if mode in ("L", "LA"):
        arr = np.asarray(im)
        return (arr[..., 0] if arr.ndim == 3 else arr), 255.0
    if mode in ("RGB", "RGBA"):
        return np.asarray(im)[..., :3], 255.0
    raise CandidateError(f"unsupported PNG pixel mode {mode!r}")


def _png_visibility(path: Path, values: np.ndarray) -> np.ndarray:
    if values.ndim == 3:
        if not (
            np.array_equal(values[..., 0], values[..., 1])
            and np.array_equal(values[..., 0], values[..., 2])
        ):
            raise CandidateError(
                f"candidate {path.name} is a colour PNG with unequal R, G, B; visibility "
                "needs a grey PNG"
            )
        values = values[..., 0]
    return np.ascontiguousarray(values, dtype=np.float32)
