"""Thumbnails and the pixel viewer's data of a scored case, kept in the sweep store for the
report (the case table's thumbnails, the summary cases' pixel viewers)."""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

from ... import metrics as M
from ...reports import images
from ...reports.viewer import viewer_record
from ..reference.exr import ExrError, read_exr

__all__ = ["KEPT_REFERENCES", "THUMBNAIL_SIZE", "case_images", "case_viewer"]

#: Longer side of the thumbnails kept per case, in pixels (the image is reduced by the
#: smallest integer factor that fits). The pixel viewer's arrays have the same resolution.
THUMBNAIL_SIZE = 320
#: Primary error map of each scored channel: map name, palette, fixed range.
_ERROR_MAPS = {
    "visibility": ("visibility_error", "signed", (-1.0, 1.0)),
    "soft_visibility": ("visibility_error", "signed", (-1.0, 1.0)),
    "light_fraction": ("visibility_error", "signed", (-1.0, 1.0)),
    "color": ("flip", "magma", (0.0, 1.0)),
    "coverage": ("coverage_error", "signed", (-1.0, 1.0)),
}


#: Reference-side thumbnail parts a process keeps (the cases of a sweep judged against one
#: reference share them): the last ``KEPT_REFERENCES``.
KEPT_REFERENCES = 32

_KEPT: OrderedDict = OrderedDict()


def _kept(key, make):
    """``make()``, kept under ``key`` for the next case (keys name everything it reads)."""
    if key in _KEPT:
        _KEPT.move_to_end(key)
        return _KEPT[key]
    value = _KEPT[key] = make()
    while len(_KEPT) > KEPT_REFERENCES:
        _KEPT.popitem(last=False)
    return value


def _stderr(result, channel: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """The first frame's reference stderr (read back from its EXR), or None when the EXR or
    the channel is missing (the viewer then shows no stderr; nothing else depends on it).
    Kept by reference folder (content-addressed: its EXR never changes) and channel."""
    if not result.reference_folders:
        return None
    folder = result.reference_folders[0]
    key = ("stderr", str(folder), channel, shape)
    return _kept(key, lambda: _read_stderr(folder, channel, shape))


def _read_stderr(folder, channel: str, shape: tuple[int, ...]) -> np.ndarray | None:
    try:
        ch = read_exr(folder / "reference.exr")
    except ExrError:
        return None
    if len(shape) == 3:
        names = [f"{channel}_stderr.{c}" for c in "RGB"]
        se = np.stack([ch[n] for n in names], -1) if all(n in ch for n in names) else None
    else:
        se = ch.get(f"{channel}_stderr")
    if se is None or se.shape != shape:
        return None
    se.setflags(write=False)  # kept for the next case: nobody writes into it
    return se


def case_viewer(result, *, max_size: int = THUMBNAIL_SIZE) -> dict | None:
    """The pixel viewer record (:func:`reports.viewer.viewer_record`) of a score result's
    first frame at the thumbnails' resolution: linear reference, candidate, the reference's
    stderr and the primary error map, reduced by the thumbnails' factor (box mean, stderr of
    the mean, largest-magnitude error). None when the channel has no primary error map."""
    frame = result.frames[0]
    channel = result.record["channel"]
    key, style, value_range = _ERROR_MAPS[channel]
    if key not in frame.maps:
        return None
    shape = frame.reference.shape
    factor = images.downscale_factor(shape, max_size=max_size)
    budget = -(-shape[0] // factor) * -(-shape[1] // factor)
    tm = result.record.get("tone_mapping") or {}
    return viewer_record(
        [
            {
                "label": "frame 1",
                "metrics": frame.metrics,
                "reference": frame.reference,
                "candidate": frame.candidate,
                "stderr": _stderr(result, channel, shape),
                "error": frame.maps[key],
            }
        ],
        error_name=key,
        error_style=style,
        error_range=value_range,
        exposure=tm.get("exposure_stops") or 0.0,
        tone_mapper=(tm.get("tone_mapper") or "aces") if frame.reference.ndim == 3 else "clip",
        srgb=frame.reference.ndim == 3,
        max_pixels=budget,
    )


def _thumbnail(image: np.ndarray, factor: int, exposure: float) -> str:
    """One thumbnail: visibility as grey PNG, colour through the shared tone mapper."""
    if image.ndim == 2:
        return images.encode_visibility(
            images.reduce_image(np.clip(image, 0.0, 1.0), factor, srgb=False)
        )
    shown = M.tonemap(image, exposure=exposure)
    return images.encode_color(images.reduce_image(shown, factor, srgb=True))


def case_images(result) -> dict:
    """Thumbnails of a score result as data URIs: ``reference``, ``candidate``, ``error``
    (visibility as grey PNG, colour through the shared tone mapper as WebP/JPEG, the primary
    error map with its fixed-range palette, reduced keeping the largest error per block),
    and under ``"viewer"`` the pixel viewer's record (:func:`case_viewer`; the store keeps
    it in a table of its own)."""
    frame = result.frames[0]
    channel = result.record["channel"]
    factor = images.downscale_factor(frame.reference.shape, max_size=THUMBNAIL_SIZE)
    exposure = (result.record.get("tone_mapping") or {}).get("exposure_stops") or 0.0
    ref = np.ascontiguousarray(frame.reference)
    digest = hashlib.blake2b(ref.data, digest_size=20).digest()
    key = ("thumbnail", digest, ref.shape, ref.dtype.str, factor, exposure)
    out = {"reference": _kept(key, lambda: _thumbnail(ref, factor, exposure))}
    out["candidate"] = _thumbnail(frame.candidate, factor, exposure)
    key, style, value_range = _ERROR_MAPS[channel]
    if key in frame.maps:
        data = images.reduce_error(np.nan_to_num(frame.maps[key]), factor)
        out["error"] = images.encode_heatmap(data, style=style, value_range=value_range)
        out["error_map"] = key
    viewer = case_viewer(result)
    if viewer is not None:
        out["viewer"] = viewer
    return out
