"""raster-oracle: ground truth for real-time shadows and anti-aliasing.

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

__all__ = ["__version__"]
