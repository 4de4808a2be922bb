"""Irregular z-buffer shadows (IZB) and frustum-traced IZB: model, list build, lists and
traversal, sample-triangle kernel, occluder geometry."""

from .model import IzbParams, run

__all__ = ["IzbParams", "run"]
