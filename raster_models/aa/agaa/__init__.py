"""Aggregate G-buffer anti-aliasing (AGAA): the model, its Dr.Jit frame and per-pixel work."""

from .model import AgaaParams, run

__all__ = ["AgaaParams", "run"]
