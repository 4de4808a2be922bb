"""raster-oracle: ground truth for real-time shadows and anti-aliasing.

The Python API (:mod:`raster_oracle.api`, documented in ``docs/python-api.md``) is importable
from here: ``raster_oracle.load_scene``, ``reference``, ``score_image``, ... (the names of
:data:`raster_oracle.api_names.API_NAMES`, loaded on first use); errors are
:class:`InputError` and :class:`ModelError`.

The installed import package. Its subpackages are the repository's top-level folders:
``raster_oracle.oracle`` (references, scoring, sweeps, studies, CLI),
``raster_oracle.raster_models`` (the technique models), ``raster_oracle.metrics``,
``raster_oracle.scenes`` and ``raster_oracle.reports``.
"""

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from .api_names import API_NAMES

# A source checkout keeps the subpackages beside this folder (the wheel puts them inside it):
# there, look them up in the checkout's root too, so the checkout's own code is what runs.
_checkout = Path(__file__).resolve().parent.parent
if not (Path(__file__).parent / "oracle").is_dir() and (_checkout / "setup.py").is_file():
    __path__.append(str(_checkout))

try:
    __version__ = version("raster-oracle")
except PackageNotFoundError:  # a source tree that was not installed
    __version__ = "0+unknown"

# The API's names are loaded on first use so that ``import raster_oracle`` stays cheap (no
# Mitsuba, no Dr.Jit until a function runs); they are listed once, in API_NAMES.
__all__ = ["__version__", *API_NAMES]


def __getattr__(name: str):
    if name in API_NAMES:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'raster_oracle' has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *API_NAMES})
