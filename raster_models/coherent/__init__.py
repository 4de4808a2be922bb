"""Coherent shadow maps.

Modules (package internals, one step each): ``model`` (parameters, run, orderings, cost),
``directions`` (map directions, id texture, projections), ``surfaces`` (the maps' rendering
and visibility intervals), ``kernels`` (the intervals and run-compression Dr.Jit kernels),
``shading`` (the receivers' lookup and depth test), ``rays`` (the maps' ray grids),
``hilbert`` (the Hilbert curve).
"""

from .model import CoherentParams, run

__all__ = ["CoherentParams", "run"]
