"""One scored case (a technique or an engine image against a reference) as a report record."""

from __future__ import annotations

import math
import urllib.parse
from collections.abc import Mapping, Sequence

import numpy as np

from . import images as _images
from . import stats
from ._validate import (
    KINDS,
    check_checks,
    check_cost,
    check_directions,
    check_error_maps,
    check_image,
    check_metrics,
    check_name,
    check_texts,
    check_thresholds,
    decode_float,
    to_jsonable,
)
from .viewer import check_viewer

__all__ = ["CASE_SCHEMA", "MAX_THUMBNAIL_BYTES", "MAX_THUMBNAIL_BYTES_WITH_VIEWER", "make_case"]

#: Value of the ``"schema"`` key of every case record.
CASE_SCHEMA = "raster-oracle.report-case/1"

#: Default budget of one case's thumbnails, in data-URI characters: ten cases plus their
#: full-resolution tile crops (12 crops of 32 x 32 px, under 70 kB) and the page stay under
#: 15 MB whatever the content.
MAX_THUMBNAIL_BYTES = 1_300_000

#: The same for a case with a pixel viewer, whose float data (page budget
#: :data:`reports.viewer.MAX_VIEWER_PAGE_BYTES`) is then the way to inspect pixels.
MAX_THUMBNAIL_BYTES_WITH_VIEWER = 400_000


def _default_error_maps(reference: np.ndarray, candidate: np.ndarray, kind: str) -> dict:
    if kind == "visibility":
        return {"visibility_error": {"data": candidate - reference, "style": "signed"}}
    difference = np.abs(candidate - reference).mean(axis=2)
    return {"abs_difference": {"data": difference, "style": "magma"}}


def _failing(metrics: Mapping, thresholds: Mapping) -> list[str]:
    failing = []
    for name, bounds in thresholds.items():
        value = decode_float(metrics[name])
        too_low = "min" in bounds and not value >= bounds["min"]
        too_high = "max" in bounds and not value <= bounds["max"]
        if too_low or too_high or math.isnan(value):
            failing.append(name)
    return failing


def _within_noise(metrics: Mapping, noise_floor: Mapping, directions: Mapping) -> list[str]:
    """Metrics no worse than their noise floor, in their direction: ``value <= floor``
    (lower is better, the default), ``value >= floor`` (higher: SSIM, PSNR), ``|value| <=
    |floor|`` (zero: a bias); never an ``info`` metric or a NaN (the same rule as
    ``metrics.catalog.within_noise``, which this package cannot import)."""
    out = []
    for key, floor in noise_floor.items():
        if key not in metrics:
            continue
        value, direction = decode_float(metrics[key]), directions.get(key, "lower")
        if direction == "higher":
            quiet = value >= floor
        elif direction == "zero":
            quiet = abs(value) <= abs(floor)
        else:
            quiet = direction == "lower" and value <= floor
        if quiet:
            out.append(key)
    return out


def _exr_links(value: object) -> list[dict]:
    if value is None:
        return []
    if not isinstance(value, Mapping):
        raise TypeError(f"exr_links must be a dict label -> relative path, got {value!r}")
    links = []
    for label, path in value.items():
        check_name("exr_links key", label)
        if not isinstance(path, str) and not hasattr(path, "__fspath__"):
            raise TypeError(f"exr_links[{label!r}] must be a path, got {path!r}")
        text = str(path).replace("\\", "/")
        # Quote everything but "/": a "javascript:" or "http:" prefix becomes a harmless
        # relative file name.
        links.append({"label": label, "path": text, "href": urllib.parse.quote(text, safe="/")})
    return links


def _encode_image(values: np.ndarray, kind: str, *, lossless: bool = False) -> str:
    if kind == "visibility":
        return _images.encode_visibility(values)
    return _images.encode_color(values, lossless=lossless)


def _thumbnails(
    reference: np.ndarray, candidate: np.ndarray, maps: dict, *, kind: str, factor: int
) -> tuple[dict[str, str], dict[str, str]]:
    """Encode the images and the error maps reduced by ``factor`` as data URIs."""
    srgb = kind == "color"
    images = {
        "reference": _encode_image(_images.reduce_image(reference, factor, srgb=srgb), kind),
        "candidate": _encode_image(_images.reduce_image(candidate, factor, srgb=srgb), kind),
    }
    heatmaps = {
        name: _images.encode_heatmap(
            _images.reduce_error(spec["data"], factor),
            style=spec["style"],
            value_range=tuple(spec["range"]),
        )
        for name, spec in maps.items()
    }
    return images, heatmaps


def _check_labels(name, scene, kind, technique, family) -> None:
    check_name("name", name)
    if not isinstance(scene, str):
        raise TypeError(f"scene must be a string, got {scene!r}")
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {list(KINDS)}, got {kind!r}")
    for label, value in (("technique", technique), ("family", family)):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{label} must be a string or None, got {value!r}")


def _check_sizes(**sizes: int) -> None:
    for label, value in sizes.items():
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{label} must be a positive integer, got {value!r}")


def _fit_thumbnails(
    reference: np.ndarray,
    candidate: np.ndarray,
    maps: dict,
    *,
    kind: str,
    factor: int,
    max_bytes: int,
) -> tuple[dict[str, str], dict[str, str], int, int]:
    """Thumbnails reduced by the smallest factor from ``factor`` up whose encoded size fits
    ``max_bytes``: ``(images, heatmaps, factor, size)``."""
    height, width = reference.shape[:2]
    while True:
        images, heatmaps = _thumbnails(reference, candidate, maps, kind=kind, factor=factor)
        size = sum(map(len, images.values())) + sum(map(len, heatmaps.values()))
        if size <= max_bytes or factor >= max(height, width):
            return images, heatmaps, factor, size
        # Encoded size scales roughly with the pixel count, i.e. with 1 / factor^2.
        factor = max(factor + 1, math.ceil(factor * math.sqrt(size / max_bytes)))


def _map_records(maps: dict, heatmaps: dict[str, str]) -> list[dict]:
    return [
        {
            "name": name,
            "style": spec["style"],
            "range": spec["range"],
            "primary": spec["primary"],
            "image": heatmaps[name],
            "histogram": stats.histogram(
                spec["data"], style=spec["style"], value_range=tuple(spec["range"])
            ),
            "summary": stats.error_summary(spec["data"]),
        }
        for name, spec in maps.items()
    ]


def _worst_tiles(
    reference: np.ndarray,
    candidate: np.ndarray,
    maps: dict,
    *,
    kind: str,
    tile_size: int,
    n_tiles: int,
) -> dict:
    """The worst tiles of the primary error map with full-resolution crops of each image."""
    map_name, spec = next((name, spec) for name, spec in maps.items() if spec["primary"])
    tiles = stats.worst_tiles(spec["data"], tile=tile_size, count=n_tiles)
    for tile in tiles:
        rows = slice(tile["y"], tile["y"] + tile["h"])
        cols = slice(tile["x"], tile["x"] + tile["w"])
        tile["reference"] = _encode_image(reference[rows, cols], kind, lossless=True)
        tile["candidate"] = _encode_image(candidate[rows, cols], kind, lossless=True)
        tile["error"] = _images.encode_heatmap(
            spec["data"][rows, cols], style=spec["style"], value_range=tuple(spec["range"])
        )
    return {"map": map_name, "tile_size": tile_size, "tiles": tiles}


def make_case(
    *,
    name: str,
    scene: str,
    reference: np.ndarray,
    candidate: np.ndarray,
    kind: str,
    metrics: Mapping[str, float],
    error_maps: Mapping[str, Mapping] | None = None,
    noise_floor: Mapping[str, float] | None = None,
    thresholds: Mapping[str, float | Mapping[str, float]] | None = None,
    directions: Mapping[str, str] | None = None,
    cost: Mapping[str, float] | None = None,
    technique: str | None = None,
    family: str | None = None,
    params: Mapping[str, object] | None = None,
    exr_links: Mapping[str, str] | None = None,
    tile_size: int = 32,
    n_tiles: int = 4,
    max_size: int = 960,
    max_bytes: int | None = None,
    viewer: Mapping | None = None,
    checks: Sequence[Mapping] | None = None,
    diagnoses: Sequence[str] | None = None,
) -> dict:
    """Compute everything the report shows about one case and return it as a JSON-safe dict.

    Parameters
    ----------
    name, scene : str
        Case label and scene name (shown as text, never interpreted as HTML).
    reference, candidate : ndarray, float32
        ``kind="visibility"``: ``(H, W)`` hard-shadow visibility in [0, 1], 1 = lit.
        ``kind="color"``: ``(H, W, 3)`` tone-mapped, sRGB-encoded colour in [0, 1].
    kind : {"visibility", "color"}
    metrics : dict str -> float
        Scalar metrics of the candidate; NaN/inf are kept (encoded ``"nan"``/``"inf"``).
    error_maps : dict str -> dict, optional
        ``name -> {"data": (H, W) float array, "style": "signed" | "magma", "range": [lo, hi]
        (optional; default [-1, 1] signed, [0, 1] magma), "primary": bool (optional)}``.
        Signed: green = positive (false-lit), red = negative (false-shadowed). The worst
        tiles come from the primary map (default: the first). Default when omitted:
        ``candidate - reference`` (signed) for visibility, mean |candidate - reference| over
        channels (magma) for colour.
    noise_floor : dict str -> float, optional
        Value of each metric for the reference's own noise (two independent references).
    thresholds : dict str -> float or {"min": float, "max": float}, optional
        A number is the largest passing value. NaN metrics fail.
    directions : dict str -> str, optional
        Which way each metric is better: ``"lower"`` (the default), ``"higher"`` (SSIM,
        PSNR), ``"zero"`` (a signed bias) or ``"info"`` (not a score). ``within_noise`` is
        judged in that direction: a bad SSIM below its floor is not within the noise floor.
    cost : dict str -> number, optional
        The technique's GPU budget (``memory_bytes``, ``texels_rendered``, ...).
    technique, family : str, optional
        Technique name and the family whose Pareto front it belongs to (default: technique).
    params : dict, optional
        Technique parameters (JSON-compatible values).
    exr_links : dict str -> str, optional
        ``label -> path`` of full-resolution EXRs, relative to the report's folder.
    tile_size : int
        Side of the square tiles, in pixels, ranked for the worst-tile crops.
    n_tiles : int
        Number of worst tiles kept.
    max_size : int
        Longest side of the embedded thumbnails, in pixels; larger images are reduced by an
        integer factor (box filter in linear light for images, largest-magnitude value per
        block for error maps, so thin errors stay visible). Tile crops stay full resolution.
    max_bytes : int, optional
        Budget of the encoded thumbnails (images and error maps, data-URI characters); the
        reduction factor grows until they fit. Only noise-like content needs it. Default
        :data:`MAX_THUMBNAIL_BYTES`, or :data:`MAX_THUMBNAIL_BYTES_WITH_VIEWER` with a viewer.
    viewer : dict, optional
        The linear float images for the page's pixel viewer (zoom, exposure, readout), from
        :func:`reports.viewer.viewer_record`; its full size must be the case's. Without it the
        page shows the thumbnails only.
    checks : list of dict, optional
        The judged checks of the run (gates and baseline comparisons), each ``{"name",
        "kind" ("gate" | "baseline"), "metric", "passed", "line", ...}``: a failed one fails
        the case and is listed first on the page, with the same name and line as the exit
        code's verdict, JUnit and ``metrics.json``.

    Returns
    -------
    dict
        The case record; its keys are documented in the :mod:`reports` module docstring.
    """
    _check_labels(name, scene, kind, technique, family)
    if max_bytes is None:
        max_bytes = MAX_THUMBNAIL_BYTES if viewer is None else MAX_THUMBNAIL_BYTES_WITH_VIEWER
    _check_sizes(tile_size=tile_size, n_tiles=n_tiles, max_size=max_size, max_bytes=max_bytes)
    reference = check_image("reference", reference, kind=kind)
    candidate = check_image("candidate", candidate, kind=kind)
    if reference.shape != candidate.shape:
        raise ValueError(
            "reference and candidate must have the same shape, "
            f"got {reference.shape} and {candidate.shape}"
        )
    height, width = reference.shape[:2]
    if error_maps is None:
        error_maps = _default_error_maps(reference, candidate, kind)
    maps = check_error_maps(error_maps, shape=(height, width))
    metrics = check_metrics("metrics", metrics, allow_nonfinite=True)
    if not metrics:
        raise ValueError("metrics must hold at least one metric, got an empty dict")
    noise_floor = check_metrics("noise_floor", noise_floor, allow_nonfinite=False)
    thresholds = check_thresholds(thresholds, metrics=metrics)
    if params is not None and not isinstance(params, Mapping):
        raise TypeError(f"params must be a dict or None, got {type(params).__name__}")
    viewer = check_viewer("viewer", viewer)
    if viewer is not None and (viewer["full_width"], viewer["full_height"]) != (width, height):
        raise ValueError(
            f"viewer images are {viewer['full_width']}x{viewer['full_height']}, "
            f"the case's {width}x{height}"
        )

    images, heatmaps, factor, size = _fit_thumbnails(
        reference,
        candidate,
        maps,
        kind=kind,
        factor=_images.downscale_factor((height, width), max_size=max_size),
        max_bytes=max_bytes,
    )
    return {
        "schema": CASE_SCHEMA,
        "name": name,
        "scene": scene,
        "kind": kind,
        "technique": technique,
        "family": family if family is not None else technique,
        "params": to_jsonable(dict(params or {}), "params"),
        "width": int(width),
        "height": int(height),
        "thumbnail": {
            "factor": factor,
            "width": -(-width // factor),
            "height": -(-height // factor),
            "bytes": size,
        },
        **_judgement(metrics, thresholds, noise_floor, cost, directions, check_checks(checks)),
        "diagnoses": check_texts("diagnoses", diagnoses),
        "images": images,
        "error_maps": _map_records(maps, heatmaps),
        "worst_tiles": _worst_tiles(
            reference, candidate, maps, kind=kind, tile_size=tile_size, n_tiles=n_tiles
        ),
        "exr_links": _exr_links(exr_links),
        "viewer": viewer,
    }


def _judgement(metrics, thresholds, noise_floor, cost, directions, checks) -> dict:
    """The case record's verdict fields: its metrics, thresholds, noise floor and cost, the failing
    metrics (thresholds and failed checks), which metrics lie within the noise floor, and the
    status (``"unchecked"`` without thresholds or checks, else ``"pass"`` or ``"fail"``)."""
    failing = _failing(metrics, thresholds)
    failed_checks = [c for c in checks if not c["passed"]]
    failing += [c["metric"] for c in failed_checks if c["metric"] not in failing]
    directions = {k: d for k, d in check_directions(directions).items() if k in metrics}
    if not thresholds and not checks:
        status = "unchecked"
    else:
        status = "fail" if failing or failed_checks else "pass"
    return {
        "metrics": metrics,
        "thresholds": thresholds,
        "noise_floor": noise_floor,
        "cost": check_cost(cost),
        "failing": failing,
        "within_noise": _within_noise(metrics, noise_floor, directions),
        "directions": directions,
        "status": status,
        "checks": checks,
    }
