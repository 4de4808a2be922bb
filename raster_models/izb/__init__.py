"""Irregular z-buffer shadows (IZB) and frustum-traced IZB.

Modules (package internals, one step each): ``model`` (parameters, run, traversal, outputs,
cost), ``samples`` (receivers and their light-frame samples, view-depth partitions),
``grids`` (one grid per partition and its lists), ``build`` (the orthographic 32-sample list
build, Dr.Jit kernels), ``lists`` (the grid of lists and the join), ``kernel`` (the
sample-triangle tests), ``geometry`` (occluder triangles, shadow volumes, conservative
rasterization).
"""

from .model import IzbParams, run

__all__ = ["IzbParams", "run"]
