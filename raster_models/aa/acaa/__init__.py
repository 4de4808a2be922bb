"""Accumulative anti-aliasing (ACAA): the model, its tie search and its ray work."""

from .model import AcaaParams, run

__all__ = ["AcaaParams", "run"]
