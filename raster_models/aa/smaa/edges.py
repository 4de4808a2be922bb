"""SMAA's first pass: edge detection (``SMAALumaEdgeDetectionPS``, ``SMAAColorEdgeDetectionPS``,
``SMAADepthEdgeDetectionPS`` and ``SMAACalculatePredicatedThreshold`` of ``SMAA.hlsl``).

Every fetch is a point fetch with clamp addressing (a pixel on the border compares with
itself). The result is the edges texture (RG8): R = an edge between the pixel and its left
neighbour, G = between the pixel and the one above, each 0 or 1. Arithmetic is float32, as
in the shader.
"""

from __future__ import annotations

import numpy as np

from ._sampling import Fetches

__all__ = ["EDGE_METHODS", "LUMA_WEIGHTS", "detect_edges"]

#: Edge detection inputs ``SMAA.hlsl`` offers.
EDGE_METHODS = ("luma", "color", "depth")
#: Luma weights of the gamma-encoded colour in ``SMAALumaEdgeDetectionPS`` (Rec. 709).
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722], np.float32)


def _at(a: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """``a`` fetched at (x + dx, y + dy) for every pixel, clamp addressing."""
    h, w = a.shape[:2]
    ys = np.clip(np.arange(h) + dy, 0, h - 1)
    xs = np.clip(np.arange(w) + dx, 0, w - 1)
    return a[ys][:, xs]


def _predicated_threshold(pred: np.ndarray, threshold: float, predication: dict) -> np.ndarray:
    """``SMAACalculatePredicatedThreshold``: (H, W, 2) thresholds for the left and top edges,
    lowered where the predication input has an edge of its own."""
    p = pred.astype(np.float32)
    delta = np.stack([np.abs(p - _at(p, -1, 0)), np.abs(p - _at(p, 0, -1))], axis=-1)
    edges = (delta >= np.float32(predication["threshold"])).astype(np.float32)
    scale = np.float32(predication["scale"] * threshold)
    return scale * (np.float32(1.0) - np.float32(predication["strength"]) * edges)


def _contrast(a: np.ndarray, b: np.ndarray, method: str) -> np.ndarray:
    if method == "luma":
        return np.abs(a - b)
    return np.max(np.abs(a - b), axis=-1)


def detect_edges(
    image: np.ndarray | None,
    *,
    method: str = "luma",
    threshold: float = 0.1,
    local_contrast_factor: float = 2.0,
    depth: np.ndarray | None = None,
    depth_threshold: float | None = None,
    predication: dict | None = None,
    fetches: Fetches | None = None,
) -> np.ndarray:
    """The edges texture of ``image``.

    Parameters
    ----------
    image : (H, W, 3) float32 gamma-encoded display colour in [0, 1] (``luma``, ``color``).
    method : ``luma`` (Rec. 709 luma of the encoded colour), ``color`` (largest channel
        difference) or ``depth``.
    threshold : ``SMAA_THRESHOLD``, a contrast in [0, 0.5].
    local_contrast_factor : ``SMAA_LOCAL_CONTRAST_ADAPTATION_FACTOR``: an edge is dropped
        where a neighbouring edge has this many times its contrast.
    depth : (H, W) depth-buffer values in [0, 1] (``depth`` method, and the predication
        input when ``predication`` is given).
    depth_threshold : ``SMAA_DEPTH_THRESHOLD`` (default ``0.1 * threshold``).
    predication : None, or a dict ``threshold``, ``scale``, ``strength``
        (``SMAA_PREDICATION_*``): thresholds lowered where ``depth`` has an edge.
    fetches : counter of texture fetches (pass ``edges``).

    Returns
    -------
    (H, W, 2) float32: R (left edge), G (top edge), each 0 or 1.
    """
    count = fetches.add if fetches is not None else (lambda name, n: None)
    if method == "depth":
        d = np.asarray(depth, np.float32)
        delta = np.stack([np.abs(d - _at(d, -1, 0)), np.abs(d - _at(d, 0, -1))], axis=-1)
        dt = 0.1 * threshold if depth_threshold is None else depth_threshold
        count("edges:depth", 3 * d.size)
        return (delta >= np.float32(dt)).astype(np.float32)
    img = np.asarray(image, np.float32)
    n_pix = img.shape[0] * img.shape[1]
    val = img @ LUMA_WEIGHTS if method == "luma" else img
    if predication is not None:
        thr = _predicated_threshold(np.asarray(depth, np.float32), threshold, predication)
        count("edges:depth", 3 * n_pix)
    else:
        thr = np.float32(threshold)
    left, top = _at(val, -1, 0), _at(val, 0, -1)
    delta_xy = np.stack([_contrast(val, left, method), _contrast(val, top, method)], axis=-1)
    edges = (delta_xy >= thr).astype(np.float32)
    kept = edges.any(axis=-1)  # the shader discards the others
    delta_zw = np.stack(
        [_contrast(val, _at(val, 1, 0), method), _contrast(val, _at(val, 0, 1), method)], axis=-1
    )
    max_delta = np.maximum(delta_xy, delta_zw)
    if method == "luma":
        far = [_contrast(left, _at(val, -2, 0), method), _contrast(top, _at(val, 0, -2), method)]
    else:  # SMAAColorEdgeDetectionPS compares the centre with the pixels two away
        far = [_contrast(val, _at(val, -2, 0), method), _contrast(val, _at(val, 0, -2), method)]
    max_delta = np.maximum(max_delta, np.stack(far, axis=-1))
    final = np.max(max_delta, axis=-1, keepdims=True)
    edges *= (np.float32(local_contrast_factor) * delta_xy >= final).astype(np.float32)
    edges[~kept] = 0.0
    count("edges:color", 3 * n_pix + 4 * int(kept.sum()))
    return edges
