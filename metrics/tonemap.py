"""The one tone-mapping pipeline applied to reference and candidate before any LDR metric.

The display transform itself lives in :mod:`scenes.base.display` (techniques that run in display
space, FXAA and SMAA, use it too); this module re-exports it for the metrics, with the
metrics' error class: every invalid input raises :class:`MetricError` with the message of
:class:`scenes.base.display.DisplayError`.

Pipeline (the same for both images, with one exposure taken from the reference): drop alpha,
clamp negative radiance to 0, scale by ``2**exposure``, tone map (``"aces"``, ``"reinhard"``
or ``"clip"``), clip to [0, 1], sRGB-encode. See :mod:`scenes.base.display` for each step.
"""

from __future__ import annotations

import functools

from ..scenes.base import display as _display
from .validate import MetricError

__all__ = [
    "LUMINANCE_WEIGHTS",
    "TONE_MAPPERS",
    "exposure_from_reference",
    "luminance",
    "srgb_decode",
    "srgb_encode",
    "tonemap",
    "tonemap_inverse",
]

LUMINANCE_WEIGHTS = _display.LUMINANCE_WEIGHTS
TONE_MAPPERS = _display.TONE_MAPPERS


def _metric_errors(fn):
    """``fn`` with :class:`DisplayError` raised again as :class:`MetricError` (same text)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except _display.DisplayError as exc:
            raise MetricError(str(exc)) from None

    return wrapper


luminance = _metric_errors(_display.luminance)
exposure_from_reference = _metric_errors(_display.exposure_from_reference)
srgb_encode = _metric_errors(_display.srgb_encode)
srgb_decode = _metric_errors(_display.srgb_decode)
tonemap = _metric_errors(_display.tonemap)
tonemap_inverse = _metric_errors(_display.tonemap_inverse)
