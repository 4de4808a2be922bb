"""The one exception type of :mod:`raster_models`."""

from __future__ import annotations

__all__ = ["ModelError"]


class ModelError(ValueError):
    """A technique, parameter or scene a model cannot run with (one clear line for the user).

    Messages name what was expected and what was received: the valid techniques, the valid
    parameters, or the expected type, range or choices of a value.
    """
