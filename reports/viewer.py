"""Float image data for the report's pixel viewer: reduce, pack as float16, check on read.

The viewer (``templates/viewer.html``, ``viewer.js``) shows the linear images of a case the
way the scoring saw them: nearest-neighbour zoom down to single pixels, an exposure slider
applied to the linear values before the documented tone mapper and sRGB encode
(:func:`metrics.tonemap.tonemap`), and a readout of reference, candidate, reference stderr and
error under the cursor. It needs the float values in the page (no network), so each frame's
arrays are packed here:

- reduced by the smallest integer ``factor`` whose image fits the pixel budget (box mean for
  the images, root-sum-square over the block for the stderr of that mean, the value of largest
  magnitude for the error map, so a one-pixel error stays visible); the page says so;
- stored as float16 (values clipped to +-65504; relative precision 2**-11, so a readout's
  fourth significant digit is float16's), channels interleaved, row 0 at the top, the bytes
  shuffled: every value's low byte first, then every high byte (smooth images compress about
  twice as well);
- zlib-compressed (level 6, deterministic) and base64-encoded; the page inflates them with the
  browser's ``DecompressionStream("deflate")``.

Viewer record (the case record's ``"viewer"``, ``None`` when the case has no float data)::

    {"schema": "raster-oracle.viewer/1", "factor", "width", "height" (of the packed arrays),
     "full_width", "full_height", "channels" (1 or 3), "encoding" (ENCODING),
     "exposure" (default stops), "tone_mapper" ("aces" | "reinhard" | "clip"),
     "srgb" (encode for display: colour yes, visibility data no), "max_pixels",
     "error": {"name", "style", "range"}, "palette": base64 of the error style's uint8 RGB LUT,
     "frames": [{"label", "metrics": name -> number or None, "reference", "candidate",
                 "stderr" (or None), "error"}]}
"""

from __future__ import annotations

import base64
import math
import zlib
from collections.abc import Mapping, Sequence

import numpy as np

from . import images as _images

__all__ = [
    "ENCODING",
    "MAX_VIEWER_PIXELS",
    "VIEWER_SCHEMA",
    "MAX_VIEWER_PAGE_BYTES",
    "check_viewer",
    "decode_array",
    "encode_array",
    "fit_viewers",
    "shrink_viewer",
    "viewer_bytes",
    "viewer_cases",
    "viewer_factor",
    "viewer_record",
]

VIEWER_SCHEMA = "raster-oracle.viewer/1"
ENCODING = "float16+byteshuffle+zlib+base64"

#: Pixel budget of one frame's packed images (640 x 360): a colour frame (reference,
#: candidate, stderr: 3 channels each, and the error map) is then at most 4.6 MB of float16
#: before compression.
MAX_VIEWER_PIXELS = 640 * 360

#: All frames together hold at most this many budgets: a long camera path is reduced further.
MAX_FRAME_BUDGETS = 4

_FLOAT16_MAX = 65504.0
_TONE_MAPPERS = ("aces", "reinhard", "clip")


def viewer_factor(height: int, width: int, *, max_pixels: int, n_frames: int = 1) -> int:
    """Smallest integer factor whose reduced frames fit the pixel budget.

    One frame holds at most ``max_pixels``; ``n_frames`` frames together at most
    ``max_pixels * min(n_frames, MAX_FRAME_BUDGETS)``.
    """
    per_frame = max_pixels * min(n_frames, MAX_FRAME_BUDGETS) / n_frames
    per_frame = max(1.0, min(per_frame, max_pixels))
    factor = max(1, math.ceil(math.sqrt(height * width / per_frame)) - 1)
    while -(-height // factor) * -(-width // factor) > per_frame:
        factor += 1
    return factor


def encode_array(values: np.ndarray) -> str:
    """Pack an ``(H, W)`` or ``(H, W, C)`` float array: float16, byte-shuffled (low bytes,
    then high bytes), zlib level 6, base64."""
    half = np.clip(np.asarray(values, dtype=np.float64), -_FLOAT16_MAX, _FLOAT16_MAX)
    pairs = np.ascontiguousarray(half.astype("<f2")).reshape(-1).view(np.uint8).reshape(-1, 2)
    shuffled = np.ascontiguousarray(pairs.T).tobytes()
    return base64.b64encode(zlib.compress(shuffled, 6)).decode("ascii")


def decode_array(text: str, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`encode_array` (float32 result); raises ``ValueError`` on bad data."""
    try:
        data = zlib.decompress(base64.b64decode(text.encode("ascii"), validate=True))
    except (ValueError, zlib.error) as exc:
        raise ValueError(f"not {ENCODING} data: {exc}") from None
    count = math.prod(shape)
    if len(data) != 2 * count:
        raise ValueError(f"holds {len(data) // 2} values, expected {count} for shape {shape}")
    pairs = np.frombuffer(data, dtype=np.uint8).reshape(2, count).T
    return np.ascontiguousarray(pairs).view("<f2").astype(np.float32).reshape(shape)


def _reduce_mean(values: np.ndarray, factor: int) -> np.ndarray:
    return _images.reduce_image(values, factor, srgb=False)


def _reduce_stderr(values: np.ndarray, factor: int) -> np.ndarray:
    """Stderr of a block mean: sqrt(sum se^2) / n = sqrt(mean se^2 / n)."""
    if factor == 1:
        return values
    mean_sq = _images.reduce_image(np.square(values.astype(np.float64)), factor, srgb=False)
    return np.sqrt(mean_sq / (factor * factor)).astype(np.float32)


def _check_frame(index: int, frame: Mapping, shape: tuple[int, ...] | None) -> tuple:
    """The frame's arrays as float32, checked against ``shape`` (the first frame's)."""
    where = f"viewer frame {index}"
    if not isinstance(frame, Mapping):
        raise TypeError(f"{where} must be a dict, got {type(frame).__name__}")
    if shape is None:
        shape = np.shape(frame.get("reference"))
        if len(shape) not in (2, 3) or (len(shape) == 3 and shape[2] != 3):
            raise ValueError(f"{where}['reference'] must be (H, W) or (H, W, 3), got {shape}")
    arrays = {}
    for key in ("reference", "candidate", "stderr", "error"):
        value = frame.get(key)
        if value is None and key == "stderr":
            arrays[key] = None
            continue
        value = np.asarray(value, dtype=np.float32)
        want = tuple(shape[:2]) if key == "error" else tuple(shape)
        if value.shape != want:
            raise ValueError(f"{where}['{key}'] must have shape {want}, got {value.shape}")
        arrays[key] = value
    return arrays, tuple(shape)


def viewer_record(
    frames: Sequence[Mapping],
    *,
    error_name: str,
    error_style: str,
    error_range: Sequence[float],
    exposure: float = 0.0,
    tone_mapper: str = "clip",
    srgb: bool = False,
    max_pixels: int = MAX_VIEWER_PIXELS,
) -> dict:
    """Pack the linear images of one case (one or more frames) for the pixel viewer.

    Parameters
    ----------
    frames : sequence of dict
        Per frame: ``"reference"``, ``"candidate"`` (linear, ``(H, W)`` or ``(H, W, 3)``),
        ``"stderr"`` (the reference's per-pixel standard error, same shape, or None),
        ``"error"`` (``(H, W)``: the error map the viewer draws), optional ``"metrics"``
        (``name -> number or None``: that frame's values) and ``"label"``.
    error_name, error_style, error_range
        The error map's name, palette (``"signed"`` or ``"magma"``) and fixed range.
    exposure : float
        Default exposure of the slider, in stops (the scoring's exposure).
    tone_mapper : {"aces", "reinhard", "clip"}
        The curve after the exposure, as :func:`metrics.tonemap.tonemap`.
    srgb : bool
        Whether the display encodes with the sRGB transfer function (colour radiance) or
        shows the clipped value as is (visibility and coverage data).
    max_pixels : int
        Pixel budget of one frame (see :func:`viewer_factor`).

    Returns
    -------
    dict
        The viewer record (module docstring); JSON-safe.
    """
    if not isinstance(frames, Sequence) or isinstance(frames, str | Mapping) or not frames:
        raise ValueError("viewer frames must be a non-empty list of dicts")
    if tone_mapper not in _TONE_MAPPERS:
        raise ValueError(f"tone_mapper must be one of {list(_TONE_MAPPERS)}, got {tone_mapper!r}")
    if not math.isfinite(exposure):
        raise ValueError(f"exposure must be finite, got {exposure!r}")
    if not isinstance(max_pixels, int) or isinstance(max_pixels, bool) or max_pixels < 1:
        raise ValueError(f"max_pixels must be a positive integer, got {max_pixels!r}")
    lo, hi = (float(v) for v in error_range)
    palette = _images.palette(error_style)  # raises on an unknown style
    checked, shape = [], None
    for i, frame in enumerate(frames):
        arrays, shape = _check_frame(i, frame, shape)
        checked.append((frame, arrays))
    height, width = shape[:2]
    factor = viewer_factor(height, width, max_pixels=max_pixels, n_frames=len(frames))
    packed = []
    for i, (frame, arrays) in enumerate(checked):
        stderr = arrays["stderr"]
        metrics = frame.get("metrics")
        packed.append(
            {
                "label": str(frame.get("label") or f"frame {i + 1}"),
                "metrics": None if metrics is None else _jsonable_metrics(metrics),
                "reference": encode_array(_reduce_mean(arrays["reference"], factor)),
                "candidate": encode_array(_reduce_mean(arrays["candidate"], factor)),
                "stderr": None if stderr is None else encode_array(_reduce_stderr(stderr, factor)),
                "error": encode_array(_images.reduce_error(np.nan_to_num(arrays["error"]), factor)),
            }
        )
    return {
        "schema": VIEWER_SCHEMA,
        "factor": factor,
        "width": -(-width // factor),
        "height": -(-height // factor),
        "full_width": int(width),
        "full_height": int(height),
        "channels": 1 if len(shape) == 2 else 3,
        "encoding": ENCODING,
        "exposure": float(exposure),
        "tone_mapper": tone_mapper,
        "srgb": bool(srgb),
        "max_pixels": int(max_pixels),
        "error": {"name": str(error_name), "style": error_style, "range": [lo, hi]},
        "palette": base64.b64encode(palette.tobytes()).decode("ascii"),
        "frames": packed,
    }


def _jsonable_metrics(metrics: Mapping) -> dict:
    out = {}
    for key, value in metrics.items():
        if value is None or isinstance(value, bool):
            out[str(key)] = None
        elif isinstance(value, int | float | np.integer | np.floating):
            v = float(value)
            out[str(key)] = v if math.isfinite(v) else None
    return out


def _finite_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def check_viewer(name: str, viewer: object) -> dict | None:
    """Check a viewer record read back from JSON (untrusted): keys, types and that every
    packed array decodes to its shape. Returns it, or None for None; ``ValueError`` names
    the first bad key."""
    if viewer is None:
        return None
    if not isinstance(viewer, Mapping) or viewer.get("schema") != VIEWER_SCHEMA:
        raise ValueError(f"{name} must be a viewer record ({VIEWER_SCHEMA}) or null")
    for key in ("factor", "width", "height", "full_width", "full_height", "channels"):
        value = viewer.get(key)
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{name}[{key!r}] must be a positive integer, got {value!r}")
    if viewer["channels"] not in (1, 3) or viewer.get("encoding") != ENCODING:
        raise ValueError(f"{name}: channels must be 1 or 3 and encoding {ENCODING!r}")
    if viewer.get("tone_mapper") not in _TONE_MAPPERS:
        raise ValueError(f"{name}['tone_mapper'] must be one of {list(_TONE_MAPPERS)}")
    err = viewer.get("error")
    if not isinstance(err, Mapping) or err.get("style") not in ("signed", "magma"):
        raise ValueError(f"{name}['error'] must hold a style 'signed' or 'magma'")
    rng = err.get("range")
    if not (isinstance(err.get("name"), str) and isinstance(rng, list) and len(rng) == 2):
        raise ValueError(f"{name}['error'] must hold a name and a range [lo, hi]")
    if not all(_finite_number(v) for v in rng) or not rng[0] < rng[1]:
        raise ValueError(f"{name}['error']['range'] must be two increasing numbers, got {rng}")
    if not _finite_number(viewer.get("exposure")) or not isinstance(viewer.get("srgb"), bool):
        raise ValueError(f"{name}: exposure must be a number and srgb a boolean")
    try:
        lut = base64.b64decode(str(viewer.get("palette")).encode("ascii"), validate=True)
    except ValueError:
        lut = b""
    if not lut or len(lut) % 3:
        raise ValueError(f"{name}['palette'] must be base64 of RGB byte triples")
    frames = viewer.get("frames")
    if not isinstance(frames, list) or not frames:
        raise ValueError(f"{name}['frames'] must be a non-empty list")
    shape = (viewer["height"], viewer["width"])
    image_shape = shape if viewer["channels"] == 1 else (*shape, 3)
    for i, frame in enumerate(frames):
        if not isinstance(frame, Mapping) or not isinstance(frame.get("label"), str):
            raise ValueError(f"{name}['frames'][{i}] must be a dict with a label")
        metrics = frame.get("metrics")
        if metrics is not None and not (
            isinstance(metrics, Mapping)
            and all(v is None or _finite_number(v) for v in metrics.values())
        ):
            raise ValueError(f"{name}['frames'][{i}]['metrics'] must map names to numbers or null")
        for key, want in (("reference", image_shape), ("candidate", image_shape),
                          ("stderr", image_shape), ("error", shape)):  # fmt: skip
            value = frame.get(key)
            if value is None and key == "stderr":
                continue
            if not isinstance(value, str):
                raise ValueError(f"{name}['frames'][{i}][{key!r}] must be a string")
            try:
                decode_array(value, want)
            except ValueError as exc:
                raise ValueError(f"{name}['frames'][{i}][{key!r}]: {exc}") from None
    return dict(viewer)


#: Budget of all viewers of one page, in packed (base64) characters: with the thumbnails of
#: ten cases (reduced to MAX_THUMBNAIL_BYTES_WITH_VIEWER when a case has a viewer) the page
#: stays under 15 MB.
MAX_VIEWER_PAGE_BYTES = 8_000_000

_ARRAYS = ("reference", "candidate", "stderr", "error")


def viewer_bytes(viewer: Mapping | None) -> int:
    """Packed size of a viewer record's arrays (base64 characters); 0 for None."""
    if viewer is None:
        return 0
    return sum(len(frame.get(key) or "") for frame in viewer["frames"] for key in _ARRAYS)


def shrink_viewer(viewer: Mapping, extra: int) -> dict:
    """Reduce a viewer record's arrays by a further integer factor ``extra`` (the same rules
    as :func:`viewer_record`: box mean, stderr of the mean, largest-magnitude error)."""
    h, w, c = viewer["height"], viewer["width"], viewer["channels"]
    shape = (h, w) if c == 1 else (h, w, c)
    frames = []
    for frame in viewer["frames"]:
        out = dict(frame)
        for key in _ARRAYS:
            if frame.get(key) is None:
                continue
            values = decode_array(frame[key], shape if key != "error" else (h, w))
            if key == "stderr":
                values = _reduce_stderr(values, extra)
            elif key == "error":
                values = _images.reduce_error(values, extra)
            else:
                values = _reduce_mean(values, extra)
            out[key] = encode_array(values)
        frames.append(out)
    return {
        **viewer,
        "factor": viewer["factor"] * extra,
        "width": -(-w // extra),
        "height": -(-h // extra),
        "frames": frames,
    }


def fit_viewers(viewers: Sequence[Mapping | None], *, max_bytes: int) -> list[dict | None]:
    """The viewers reduced (all by the same further factor) until together they hold at most
    ``max_bytes`` packed characters; unchanged when they fit."""
    out = list(viewers)
    total = sum(map(viewer_bytes, out))
    extra = 1
    while total > max_bytes and any(v and (v["width"] > 1 or v["height"] > 1) for v in out):
        # packed size scales roughly with the pixel count, i.e. with 1 / factor^2
        extra = max(extra + 1, math.ceil(extra * math.sqrt(total / max_bytes)))
        out = [None if v is None else shrink_viewer(v, extra) for v in viewers]
        total = sum(map(viewer_bytes, out))
    return out


def viewer_cases(
    cases: Sequence[tuple[str, str, Mapping]], *, max_bytes: int = MAX_VIEWER_PAGE_BYTES
) -> list[dict]:
    """The ``viewer_cases`` of ``templates/viewer_section.html`` (pixel viewers on a page
    without ``report.js``, e.g. the sweep report): ``(id, name, viewer record)`` triples
    checked and fitted to one page budget. ``id`` must be unique on the page."""
    ids = [case_id for case_id, _, _ in cases]
    if len(set(ids)) != len(ids):
        raise ValueError(f"viewer case ids must be unique, got {ids}")
    checked = [check_viewer(f"viewer of {case_id}", v) for case_id, _, v in cases]
    fitted = fit_viewers(checked, max_bytes=max_bytes)
    return [
        {"id": case_id, "name": str(name), "viewer": viewer}
        for (case_id, name, _), viewer in zip(cases, fitted, strict=True)
        if viewer is not None
    ]
