"""Plain records every result carries: JSON-ready values and the package provenance.

One rule for each, shared by the oracle, the models and the reports:

- :func:`jsonable`: NumPy scalars and arrays become Python numbers and lists, tuples and sets
  become lists, paths become strings, dictionary keys become strings and non-finite floats
  become the strings ``"nan"``, ``"inf"`` and ``"-inf"`` (JSON has no literal for them).
- :func:`package_versions`: the Python and package versions a result was computed with (the
  backend's part of the provenance record is :func:`scenes.backend.provenance`).

Pure: imports nothing of the project and never Mitsuba.
"""

from __future__ import annotations

import functools
import math
import os
import platform
from importlib import metadata

import numpy as np

__all__ = ["encode_float", "PACKAGES", "jsonable", "package_versions"]

#: Packages whose versions every result records (distribution names).
PACKAGES = (
    "raster-oracle",
    "mitsuba",
    "drjit",
    "numpy",
    "scipy",
    "OpenEXR",
    "scikit-image",
    "colour-science",
    "flip-evaluator",
    "pygltflib",
)


def encode_float(value: float) -> float | str:
    """``value`` as a float, or as ``"nan"``/``"inf"``/``"-inf"`` when not finite (strict JSON
    has no non-finite numbers)."""
    value = float(value)
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return value


def jsonable(obj):
    """``obj`` as plain JSON values (see the module docstring for the conversions).

    Parameters
    ----------
    obj : a nest of dicts, lists, tuples, sets, strings, numbers (Python or NumPy), NumPy
        arrays, paths and None.

    Raises
    ------
    TypeError
        For any other type (an object that JSON cannot hold).
    """
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return encode_float(obj)
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    if isinstance(obj, set | frozenset):
        return [jsonable(v) for v in sorted(obj, key=str)]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")


@functools.cache
def _installed() -> tuple[tuple[str, str | None], ...]:
    # looked up once per process (each lookup scans the installed distributions, ~1 ms):
    # the packages a running process imported do not change under it
    out: list[tuple[str, str | None]] = [("python", platform.python_version())]
    for name in PACKAGES:
        try:
            out.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((name, None))
    return tuple(out)


def package_versions() -> dict[str, str | None]:
    """``{"python": ..., name: version}`` of every package in :data:`PACKAGES` (None when one
    is not installed); a new dict each call."""
    return dict(_installed())
