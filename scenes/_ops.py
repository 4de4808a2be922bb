"""Tiny array operations shared by NumPy ``(N, 3)`` arrays and Dr.Jit ``Vector3f``.

The shading model and the lights are written once against these helpers so that the oracle
(Dr.Jit) and the models (NumPy) evaluate the same formulas.
"""

from __future__ import annotations

import numpy as np


def is_np(x) -> bool:
    return isinstance(x, np.ndarray | float | int | np.floating)


def _dr():
    import drjit as dr

    return dr


def _vec3_type(x):
    import mitsuba as mi

    return mi.Vector3f


def dot(a, b):
    if is_np(a):
        return np.sum(a * b, axis=-1)
    return _dr().dot(a, b)


def dot_const(a, c: np.ndarray):
    if is_np(a):
        return a @ np.asarray(c, dtype=a.dtype)
    return a.x * float(c[0]) + a.y * float(c[1]) + a.z * float(c[2])


def norm(a):
    if is_np(a):
        return np.linalg.norm(a, axis=-1)
    return _dr().norm(a)


def normalize(a):
    if is_np(a):
        return a / np.linalg.norm(a, axis=-1, keepdims=True)
    return _dr().normalize(a)


def scale(a, s):
    """Vector times scalar field (``(N,)`` array or Dr.Jit Float)."""
    if is_np(a):
        return a * np.asarray(s)[..., None]
    return a * s


def sub_const(a, c: np.ndarray):
    if is_np(a):
        return a - np.asarray(c, dtype=a.dtype)
    return a - _vec3_type(a)(float(c[0]), float(c[1]), float(c[2]))


def const_vec(like, c: np.ndarray):
    if is_np(like):
        return np.broadcast_to(np.asarray(c, dtype=like.dtype), like.shape).copy()
    v = _vec3_type(like)(float(c[0]), float(c[1]), float(c[2]))
    return v + 0.0 * like


def full_like_x(like, value: float):
    """Scalar field with one value per element of ``like`` (vector or scalar field)."""
    if is_np(like):
        shape = like.shape[:-1] if like.ndim > 1 else like.shape
        return np.full(shape, value, dtype=np.float64)
    dr = _dr()
    import mitsuba as mi

    n = dr.width(like)
    return dr.full(mi.Float, value, n)


def maximum(a, b):
    if is_np(a):
        return np.maximum(a, b)
    return _dr().maximum(a, b)


def clip(a, lo, hi):
    if is_np(a):
        return np.clip(a, lo, hi)
    return _dr().clip(a, lo, hi)


def arccos(a):
    if is_np(a):
        return np.arccos(a)
    return _dr().acos(a)


def power(a, e: float):
    if is_np(a):
        return np.power(a, e)
    return _dr().power(a, e)


def where(cond, a, b):
    if is_np(cond):
        return np.where(cond, a, b)
    return _dr().select(cond, a, b)
