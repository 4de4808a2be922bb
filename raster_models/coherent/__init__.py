"""Coherent shadow maps: the model, the map and compression kernels, the ray grids and the
Hilbert curve."""

from .model import CoherentParams, run

__all__ = ["CoherentParams", "run"]
