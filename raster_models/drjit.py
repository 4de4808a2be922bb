"""Small Dr.Jit helpers the model families share."""

from __future__ import annotations

import numpy as np

__all__ = ["DRJIT_ALIGN", "aligned", "numpy_view"]

#: Bytes of alignment Dr.Jit's LLVM backend gives its own arrays. An array made from NumPy
#: memory at such an address compiles into kernels with aligned loads, one at any other
#: address into a second variant of the same kernel: NumPy inputs at varying addresses made
#: a model recompile kernels from one frame to the next.
DRJIT_ALIGN = 64


def aligned(a, dtype=np.float32) -> np.ndarray:
    """A contiguous copy of ``a`` (as ``dtype``) whose data starts on a :data:`DRJIT_ALIGN`
    byte boundary: what Dr.Jit reads from it compiles to one kernel whatever the address."""
    a = np.asarray(a, dtype=dtype)
    item = a.dtype.itemsize
    raw = np.empty(a.size + DRJIT_ALIGN // item, dtype=dtype)
    start = (-raw.ctypes.data % DRJIT_ALIGN) // item
    out = raw[start : start + a.size].reshape(a.shape)
    out[...] = a
    return out


def numpy_view(a) -> np.ndarray:
    """NumPy view of an evaluated Dr.Jit array (a ``Vector3f`` gives ``(3, N)``, a copy).

    ``.numpy()`` exposes the evaluated array's own memory (the view keeps it alive), where
    ``np.array`` on a Dr.Jit vector goes through the array protocol component by component
    (~20x slower at 1080p). Callers that write into the result copy it first.
    """
    import drjit as dr

    if dr.is_array_v(a) and dr.depth_v(a) == 2 and dr.size_v(a) > 0:
        # component by component: a vector's own .numpy() packs it with a kernel whose
        # literal is the array's length, so every new length compiled a kernel again
        # a component may be narrower (a literal of width 1): broadcast it as Dr.Jit does
        width = dr.width(a)
        parts = [numpy_view(a[i]) for i in range(dr.size_v(a))]
        return np.stack([np.broadcast_to(p, (width, *p.shape[1:])) for p in parts])
    to_numpy = getattr(a, "numpy", None)
    return np.asarray(to_numpy() if to_numpy is not None else a)
