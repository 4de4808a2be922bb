"""``raster-oracle``: the command line, a thin layer over the library (``main(argv) -> int``)."""

from .app import main

__all__ = ["main"]
