"""raster-oracle: ground truth for real-time shadows and anti-aliasing.

``raster_oracle.reference``, ``score_image``, ``score_folder``, ``score_technique``,
``run_model``, ``check``, ``write_junit``, ``export`` and ``load_scene`` are the Python API
(:mod:`raster_oracle.api`, documented in ``docs/python-api.md``); errors are
:class:`InputError` and :class:`ModelError`.

The installed import package. Its subpackages are the repository's top-level folders:
``raster_oracle.oracle`` (references, scoring, sweeps, studies, CLI),
``raster_oracle.raster_models`` (the technique models), ``raster_oracle.metrics``,
``raster_oracle.scenes`` and ``raster_oracle.reports``.
"""

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

# A source checkout keeps the subpackages beside this folder (the wheel puts them inside it):
# there, look them up in the checkout's root too, so the checkout's own code is what runs.
_checkout = Path(__file__).resolve().parent.parent
if not (Path(__file__).parent / "oracle").is_dir() and (_checkout / "setup.py").is_file():
    __path__.append(str(_checkout))

try:
    __version__ = version("raster-oracle")
except PackageNotFoundError:  # a source tree that was not installed
    __version__ = "0+unknown"

#: The Python API (``raster_oracle.api``), importable from here; loaded on first use so that
#: ``import raster_oracle`` stays cheap (no Mitsuba, no Dr.Jit until a function runs).
_API = (
    "InputError",
    "ModelError",
    "ReferenceImages",
    "check",
    "export",
    "load_scene",
    "reference",
    "run_model",
    "score_folder",
    "score_image",
    "score_technique",
    "techniques",
    "write_junit",
)

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'raster_oracle' has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *_API})
