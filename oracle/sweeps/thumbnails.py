"""Thumbnails of a scored case, kept in the sweep store for the report's case table."""

from __future__ import annotations

import numpy as np

from ... import metrics as M
from ...reports import images

__all__ = ["THUMBNAIL_SIZE", "case_images"]

#: Longer side of the thumbnails kept per case, in pixels (the image is reduced by the
#: smallest integer factor that fits).
THUMBNAIL_SIZE = 320
#: Primary error map of each scored channel: map name, palette, fixed range.
_ERROR_MAPS = {
    "visibility": ("visibility_error", "signed", (-1.0, 1.0)),
    "color": ("flip", "magma", (0.0, 1.0)),
    "coverage": ("coverage_error", "signed", (-1.0, 1.0)),
}


def case_images(result) -> dict:
    """Thumbnails of a score result as data URIs: ``reference``, ``candidate``, ``error``
    (visibility as grey PNG, colour through the shared tone mapper as WebP/JPEG, the primary
    error map with its fixed-range palette, reduced keeping the largest error per block)."""
    frame = result.frames[0]
    channel = result.record["channel"]
    factor = images.downscale_factor(frame.reference.shape, max_size=THUMBNAIL_SIZE)
    out = {}
    for name, image in (("reference", frame.reference), ("candidate", frame.candidate)):
        if image.ndim == 2:
            out[name] = images.encode_visibility(
                images.reduce_image(np.clip(image, 0.0, 1.0), factor, srgb=False)
            )
        else:
            exposure = (result.record.get("tone_mapping") or {}).get("exposure_stops") or 0.0
            shown = M.tonemap(image, exposure=exposure)
            out[name] = images.encode_color(images.reduce_image(shown, factor, srgb=True))
    key, style, value_range = _ERROR_MAPS[channel]
    if key in frame.maps:
        data = images.reduce_error(np.nan_to_num(frame.maps[key]), factor)
        out["error"] = images.encode_heatmap(data, style=style, value_range=value_range)
        out["error_map"] = key
    return out
