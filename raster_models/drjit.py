"""Small Dr.Jit helpers the model families share."""

from __future__ import annotations

import numpy as np

__all__ = ["numpy_view"]


def numpy_view(a) -> np.ndarray:
    """NumPy view of an evaluated Dr.Jit array (a ``Vector3f`` gives ``(3, N)``).

    ``.numpy()`` exposes the evaluated array's own memory (the view keeps it alive), where
    ``np.array`` on a Dr.Jit vector goes through the array protocol component by component
    (~20x slower at 1080p). Callers that write into the result copy it first.
    """
    to_numpy = getattr(a, "numpy", None)
    return np.asarray(to_numpy() if to_numpy is not None else a)
