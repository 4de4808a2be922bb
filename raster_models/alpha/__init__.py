"""Models of the alpha-tested foliage rules real-time engines ship (issue 44): the plain alpha
test, three.js and Filament alpha-to-coverage and hashed alpha, sampled where a rasterizer
samples, with box-filtered or coverage-preserving mipmaps (:mod:`.rules`, :mod:`.model`)."""

from .rules import RULES

__all__ = ["RULES"]
