"""Boundary checks and conversion of user records to JSON-safe values.

Every public function of the package validates its inputs here, once, and raises with a
message that names the parameter, what was expected and what was received.

Non-finite floats cannot be stored in strict JSON, so they are encoded as the strings
``"nan"``, ``"inf"`` and ``"-inf"`` (:func:`encode_float`) and decoded back where numbers
are compared (:func:`decode_float`).

URL safety: a report embeds only ``data:image/...;base64`` URIs (:func:`check_image_uri`) and
links relative to its own folder (:func:`check_link`); case records read back from a score
folder's JSON are checked key by key (:func:`check_case_record`) and their links must stay
inside that folder, so a crafted ``report.json`` cannot make a combined report load remote
content or carry a script link.
"""

from __future__ import annotations

import math
import posixpath
import re
import urllib.parse
from collections.abc import Mapping, Sequence
from numbers import Real

import numpy as np

from ..scenes.base.records import encode_float, jsonable

__all__ = [
    "KINDS",
    "RANGE_TOLERANCE",
    "STYLES",
    "check_case_record",
    "check_checks",
    "check_texts",
    "check_cost",
    "check_error_maps",
    "check_image",
    "check_image_uri",
    "check_link",
    "check_metrics",
    "check_name",
    "check_report_urls",
    "check_thresholds",
    "decode_float",
    "encode_float",
    "to_jsonable",
]

#: Valid values of ``make_case(kind=...)``.
KINDS = ("visibility", "color")

#: Valid error-map styles and their default fixed display range.
STYLES = {"signed": (-1.0, 1.0), "magma": (0.0, 1.0)}

#: How far reference/candidate values may leave [0, 1] before they are rejected; tone mappers
#: and reconstruction filters overshoot by float rounding (~1e-7), never by 1e-3.
RANGE_TOLERANCE = 1e-3

_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def decode_float(value: object) -> float:
    """Inverse of :func:`encode_float`; ``None`` and unknown strings decode to NaN."""
    if isinstance(value, str):
        return _NONFINITE.get(value, math.nan)
    if value is None or isinstance(value, bool):
        return math.nan
    return float(value)


def check_name(name: str, value: object) -> str:
    """Check that ``value`` is a non-empty string."""
    if not isinstance(value, str) or not value:
        raise TypeError(f"{name} must be a non-empty string, got {value!r}")
    return value


def _is_number(value: object) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool | np.bool_)


def _check_array(name: str, value: object) -> np.ndarray:
    if not isinstance(value, np.ndarray):
        raise TypeError(f"{name} must be a numpy array, got {type(value).__name__}")
    if not np.issubdtype(value.dtype, np.floating):
        raise TypeError(f"{name} must be a float array (float32 expected), got dtype {value.dtype}")
    if value.size == 0:
        raise ValueError(f"{name} must not be empty, got shape {value.shape}")
    if not np.isfinite(value).all():
        raise ValueError(f"{name} must be finite, got {int((~np.isfinite(value)).sum())} NaN/inf")
    return value


def check_image(name: str, value: object, *, kind: str) -> np.ndarray:
    """Check a reference or candidate image and return it as float32 clipped to [0, 1].

    ``kind="visibility"`` expects ``(H, W)``; ``kind="color"`` expects ``(H, W, 3)``. Values
    must lie in [0, 1] within :data:`RANGE_TOLERANCE`.
    """
    value = _check_array(name, value)
    if kind == "visibility" and value.ndim != 2:
        raise ValueError(f"{name} must have shape (H, W) for kind='visibility', got {value.shape}")
    if kind == "color" and (value.ndim != 3 or value.shape[2] != 3):
        raise ValueError(f"{name} must have shape (H, W, 3) for kind='color', got {value.shape}")
    lo, hi = float(value.min()), float(value.max())
    if lo < -RANGE_TOLERANCE or hi > 1.0 + RANGE_TOLERANCE:
        raise ValueError(f"{name} must lie in [0, 1], got values in [{lo:.6g}, {hi:.6g}]")
    return np.clip(value, 0.0, 1.0).astype(np.float32, copy=False)


def check_error_maps(value: object, *, shape: tuple[int, int]) -> dict[str, dict]:
    """Check ``error_maps`` and return ``name -> {"data", "style", "range", "primary"}``.

    Each entry is a mapping with ``"data"`` (an ``(H, W)`` float array), ``"style"`` (one of
    :data:`STYLES`) and optionally ``"range"`` (``[lo, hi]``, symmetric for ``"signed"``) and
    ``"primary"`` (bool: the map the worst tiles are taken from; default: the first map).
    """
    if not isinstance(value, Mapping) or not value:
        raise TypeError(f"error_maps must be a non-empty dict name -> spec, got {value!r}")
    out: dict[str, dict] = {}
    for key, spec in value.items():
        name = f"error_maps[{key!r}]"
        check_name(f"{name} key", key)
        if not isinstance(spec, Mapping) or "data" not in spec or "style" not in spec:
            raise TypeError(f"{name} must be a dict with 'data' and 'style', got {spec!r}")
        unknown = set(spec) - {"data", "style", "range", "primary"}
        if unknown:
            raise ValueError(
                f"{name} has unknown keys {sorted(unknown)}; "
                "valid keys: 'data', 'style', 'range', 'primary'"
            )
        style = spec["style"]
        if style not in STYLES:
            raise ValueError(f"{name}['style'] must be one of {sorted(STYLES)}, got {style!r}")
        data = _check_array(f"{name}['data']", spec["data"])
        if data.shape != shape:
            raise ValueError(f"{name}['data'] must have shape {shape}, got {data.shape}")
        rng = spec.get("range", STYLES[style])
        if (
            not isinstance(rng, list | tuple)
            or len(rng) != 2
            or not all(_is_number(v) and math.isfinite(v) for v in rng)
            or not rng[0] < rng[1]
        ):
            raise ValueError(f"{name}['range'] must be [lo, hi] with lo < hi, got {rng!r}")
        if style == "signed" and rng[0] != -rng[1]:
            raise ValueError(f"{name}['range'] must be symmetric for style 'signed', got {rng!r}")
        out[key] = {
            "data": data.astype(np.float32, copy=False),
            "style": style,
            "range": [float(rng[0]), float(rng[1])],
            "primary": bool(spec.get("primary", False)),
        }
    if sum(spec["primary"] for spec in out.values()) > 1:
        raise ValueError("error_maps may mark at most one map as 'primary'")
    if not any(spec["primary"] for spec in out.values()):
        next(iter(out.values()))["primary"] = True
    return out


def check_metrics(name: str, value: object, *, allow_nonfinite: bool) -> dict[str, float | str]:
    """Check a mapping ``str -> number``; return it with floats encoded by :func:`encode_float`."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a dict name -> number, got {type(value).__name__}")
    out: dict[str, float | str] = {}
    for key, v in value.items():
        check_name(f"{name} key", key)
        if not _is_number(v):
            raise TypeError(f"{name}[{key!r}] must be a number, got {v!r}")
        if not allow_nonfinite and not math.isfinite(v):
            raise ValueError(f"{name}[{key!r}] must be finite, got {v!r}")
        out[key] = encode_float(v)
    return out


#: ``make_case(directions=...)`` values: which way a metric is better.
DIRECTIONS = ("lower", "higher", "zero", "info")


def check_directions(value: object) -> dict[str, str]:
    """Check ``directions``: ``name -> "lower" | "higher" | "zero" | "info"`` (None: ``{}``)."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"directions must be a dict name -> direction, got {value!r}")
    for key, d in value.items():
        check_name("directions key", key)
        if d not in DIRECTIONS:
            raise ValueError(f"directions[{key!r}] must be one of {list(DIRECTIONS)}, got {d!r}")
    return dict(value)


def check_thresholds(value: object, *, metrics: Mapping[str, object]) -> dict[str, dict]:
    """Check ``thresholds``: ``name -> max`` or ``name -> {"min": lo, "max": hi}``.

    A bare number is the largest value that passes. Returns ``name -> {"min"?, "max"?}``.
    """
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"thresholds must be a dict name -> number, got {type(value).__name__}")
    out: dict[str, dict] = {}
    for key, v in value.items():
        name = f"thresholds[{key!r}]"
        if key not in metrics:
            raise ValueError(f"{name} names no metric; metrics are {sorted(metrics)}")
        spec = {"max": v} if not isinstance(v, Mapping) else dict(v)
        if not spec or set(spec) - {"min", "max"}:
            raise ValueError(f"{name} must be a number or a dict with 'min'/'max', got {v!r}")
        for bound, number in spec.items():
            if not _is_number(number) or not math.isfinite(number):
                raise ValueError(f"{name}[{bound!r}] must be a finite number, got {number!r}")
            spec[bound] = float(number)
        out[key] = spec
    return out


def check_cost(value: object) -> dict[str, int | float] | None:
    """Check ``cost``: ``name -> finite number``; integers stay integers (bytes, counts)."""
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise TypeError(f"cost must be a dict name -> number or None, got {type(value).__name__}")
    out: dict[str, int | float] = {}
    for key, v in value.items():
        check_name("cost key", key)
        if not _is_number(v) or not math.isfinite(v):
            raise ValueError(f"cost[{key!r}] must be a finite number, got {v!r}")
        out[key] = int(v) if isinstance(v, int | np.integer) else float(v)
    return out


def to_jsonable(value: object, name: str) -> object:
    """A plain record (params, provenance) as JSON values: :func:`scenes.base.records.jsonable`
    (NumPy scalars to numbers, tuples and arrays to lists, paths to strings, non-finite
    floats to ``"nan"``/``"inf"``/``"-inf"``), with ``name`` in the error message."""
    try:
        return jsonable(value)
    except TypeError as exc:
        raise TypeError(
            f"{name} must hold only str, number, bool, None, list or dict values: {exc}"
        ) from None


#: The only URIs a report embeds: base64 PNG, WebP or JPEG images.
_IMAGE_URI = re.compile(r"data:image/(?:png|webp|jpeg);base64,[A-Za-z0-9+/]*={0,2}")


def check_image_uri(name: str, value: object) -> str:
    """Check that ``value`` is a ``data:image/(png|webp|jpeg);base64,...`` URI."""
    if not isinstance(value, str) or not _IMAGE_URI.fullmatch(value):
        shown = value[:60] + "..." if isinstance(value, str) and len(value) > 60 else value
        raise ValueError(f"{name} must be a data:image/...;base64 URI, got {shown!r}")
    return value


def check_link(name: str, link: object, *, inside: bool) -> dict:
    """Check an EXR link ``{"label", "path", "href"}``: a relative link to a local file.

    ``href`` must be the URL-quoted ``path`` (only ``[A-Za-z0-9_.~/%-]`` then remain) and
    must not start with ``/`` (``//host`` loads remote content, ``/x`` leaves the report).
    With ``inside=True`` (a score folder's own links) ``path`` must also have no URL scheme,
    be relative and not leave the folder through ``..``.
    """
    if not isinstance(link, Mapping) or not {"label", "path", "href"} <= set(link):
        raise ValueError(f"{name} must be a dict with 'label', 'path' and 'href', got {link!r}")
    check_name(f"{name}['label']", link["label"])
    path, href = link["path"], link["href"]
    check_name(f"{name}['path']", path)
    if not isinstance(href, str) or href != urllib.parse.quote(path, safe="/"):
        raise ValueError(f"{name}['href'] must be the URL-quoted path {path!r}, got {href!r}")
    if href.startswith("/"):
        raise ValueError(f"{name} must be a relative link, got {path!r}")
    if inside:
        split = urllib.parse.urlsplit(path)
        normal = posixpath.normpath(path)
        if split.scheme or split.netloc or posixpath.isabs(path) or "\\" in path:
            raise ValueError(f"{name} must be a relative file path, got {path!r}")
        if normal == ".." or normal.startswith("../"):
            raise ValueError(f"{name} must stay inside the report's folder, got {path!r}")
    return dict(link)


def check_report_urls(report: Mapping) -> None:
    """Check every URI and link of a report record before it is rendered (see module doc)."""
    for style, uri in dict(report.get("colorbars") or {}).items():
        check_image_uri(f"colorbars[{style!r}]", uri)
    for i, case in enumerate(report.get("cases") or []):
        _check_case_urls(f"cases[{i}]", case, inside=False)


def _check_case_urls(name: str, case: Mapping, *, inside: bool) -> None:
    images = case["images"]
    if not isinstance(images, Mapping):
        raise ValueError(f"{name}['images'] must be a dict, got {images!r}")
    for key in ("reference", "candidate"):
        check_image_uri(f"{name}['images'][{key!r}]", images.get(key))
    for j, m in enumerate(case["error_maps"]):
        check_image_uri(f"{name}['error_maps'][{j}]['image']", m.get("image"))
    for j, tile in enumerate(case["worst_tiles"]["tiles"]):
        for key in ("reference", "candidate", "error"):
            check_image_uri(f"{name}['worst_tiles']['tiles'][{j}][{key!r}]", tile.get(key))
    for j, link in enumerate(case["exr_links"]):
        check_link(f"{name}['exr_links'][{j}]", link, inside=inside)


def _expect(name: str, value: object, types, what: str) -> None:
    if not isinstance(value, types) or isinstance(value, bool) and bool not in types:
        raise ValueError(f"{name} must be {what}, got {value!r:.80}")


def _check_number_map(name: str, value: object) -> None:
    _expect(name, value, (dict,), "a dict name -> number")
    for key, v in value.items():
        if isinstance(v, str) and v in _NONFINITE:
            continue
        _expect(f"{name}[{key!r}]", v, (int, float), "a number")


def check_case_record(name: str, case: object, *, schema: str) -> dict:
    """Check a case record read back from JSON: every key :func:`make_case` writes, with its
    type, and every URI and link (links must stay inside the folder the JSON came from).

    Returns a shallow copy; raises ``ValueError`` naming the first bad key.
    """
    if not isinstance(case, Mapping) or case.get("schema") != schema:
        got = case.get("schema") if isinstance(case, Mapping) else type(case).__name__
        raise ValueError(f"{name} must be a case record ({schema}), got {got!r}")
    missing = [k for k in _CASE_KEYS if k not in case]
    if missing:
        raise ValueError(f"{name} lacks the key(s) {', '.join(missing)}")
    for key in ("name", "scene"):
        check_name(f"{name}[{key!r}]", case[key])
    if case["kind"] not in KINDS:
        raise ValueError(f"{name}['kind'] must be one of {list(KINDS)}, got {case['kind']!r}")
    for key in ("technique", "family"):
        _expect(f"{name}[{key!r}]", case[key], (str, type(None)), "a string or null")
    _expect(f"{name}['params']", case["params"], (dict,), "a dict")
    for key in ("width", "height"):
        _expect(f"{name}[{key!r}]", case[key], (int,), "a positive integer")
        if case[key] <= 0:
            raise ValueError(f"{name}[{key!r}] must be a positive integer, got {case[key]!r}")
    thumb = case["thumbnail"]
    _expect(f"{name}['thumbnail']", thumb, (dict,), "a dict")
    for key in ("factor", "width", "height"):
        _expect(f"{name}['thumbnail'][{key!r}]", thumb.get(key), (int,), "an integer")
    _check_number_map(f"{name}['metrics']", case["metrics"])
    _check_number_map(f"{name}['noise_floor']", case["noise_floor"])
    _expect(f"{name}['thresholds']", case["thresholds"], (dict,), "a dict")
    for key, bounds in case["thresholds"].items():
        _check_number_map(f"{name}['thresholds'][{key!r}]", bounds)
    if case["cost"] is not None:
        _check_number_map(f"{name}['cost']", case["cost"])
    if "directions" in case:  # optional: reports written before it lack it
        check_directions(case["directions"])
    for key in ("failing", "within_noise"):
        _expect(f"{name}[{key!r}]", case[key], (list,), "a list of names")
        for v in case[key]:
            check_name(f"{name}[{key!r}] item", v)
    case = {**case, "checks": check_checks(case.get("checks"), where=f"{name}['checks']")}
    case["diagnoses"] = check_texts(f"{name}['diagnoses']", case.get("diagnoses"))
    if case["status"] not in ("pass", "fail", "unchecked"):
        raise ValueError(
            f"{name}['status'] must be pass, fail or unchecked, got {case['status']!r}"
        )
    _expect(f"{name}['error_maps']", case["error_maps"], (list,), "a list")
    for j, m in enumerate(case["error_maps"]):
        where = f"{name}['error_maps'][{j}]"
        _expect(where, m, (dict,), "a dict")
        check_name(f"{where}['name']", m.get("name"))
        if m.get("style") not in STYLES:
            raise ValueError(
                f"{where}['style'] must be one of {sorted(STYLES)}, got {m.get('style')!r}"
            )
        for key in ("range", "histogram", "summary"):
            if key not in m:
                raise ValueError(f"{where} lacks the key {key}")
        hist = m["histogram"]
        _expect(f"{where}['histogram']", hist, (dict,), "a dict")
        for key in ("edges", "counts"):
            _expect(f"{where}['histogram'][{key!r}]", hist.get(key), (list,), "a list")
    tiles = case["worst_tiles"]
    _expect(f"{name}['worst_tiles']", tiles, (dict,), "a dict")
    _expect(f"{name}['worst_tiles']['tiles']", tiles.get("tiles"), (list,), "a list")
    for j, tile in enumerate(tiles["tiles"]):
        where = f"{name}['worst_tiles']['tiles'][{j}]"
        _expect(where, tile, (dict,), "a dict")
        for key in ("rank", "x", "y", "w", "h"):
            _expect(f"{where}[{key!r}]", tile.get(key), (int,), "an integer")
        _expect(f"{where}['mean_abs_error']", tile.get("mean_abs_error"), (int, float), "a number")
    _expect(f"{name}['images']", case["images"], (dict,), "a dict")
    _expect(f"{name}['exr_links']", case["exr_links"], (list,), "a list")
    _check_case_urls(name, case, inside=True)
    return dict(case)


_CHECK_TEXT = ("name", "kind", "metric", "line")
_CHECK_NUMBERS = ("value", "limit", "noise_floor", "previous", "previous_noise_floor")


def check_texts(where: str, texts: object) -> list[str]:
    """A list of strings (None: empty); ``TypeError`` naming the first that is not one."""
    if texts is None:
        return []
    if isinstance(texts, str) or not isinstance(texts, Sequence):
        raise TypeError(f"{where} must be a list of strings, got {type(texts).__name__}")
    for i, t in enumerate(texts):
        if not isinstance(t, str):
            raise TypeError(f"{where}[{i}] must be a string, got {t!r:.80}")
    return list(texts)


def check_checks(checks: object, *, where: str = "checks") -> list[dict]:
    """A case's judged checks: a list of ``{"name", "kind", "metric", "line": str,
    "passed": bool, "value", "limit", "noise_floor", "previous", "previous_noise_floor":
    number or None}`` (None or absent: no check). Returns plain copies; raises
    ``ValueError`` / ``TypeError`` naming the first bad entry."""
    if checks is None:
        return []
    if isinstance(checks, Mapping | str) or not isinstance(checks, Sequence):
        raise TypeError(f"{where} must be a list of check records, got {type(checks).__name__}")
    out = []
    for i, c in enumerate(checks):
        _expect(f"{where}[{i}]", c, (Mapping,), "a dict")
        for key in _CHECK_TEXT:
            _expect(f"{where}[{i}][{key!r}]", c.get(key), (str,), "a string")
        _expect(f"{where}[{i}]['passed']", c.get("passed"), (bool,), "true or false")
        rec = {key: c[key] for key in _CHECK_TEXT}
        rec["passed"] = c["passed"]
        for key in _CHECK_NUMBERS:
            v = c.get(key)
            if v is not None:
                _expect(f"{where}[{i}][{key!r}]", v, (int, float), "a number or null")
            rec[key] = None if v is None else float(v)
        out.append(rec)
    return out


#: Keys of a case record (see the :mod:`reports` module docstring).
_CASE_KEYS = (
    "schema",
    "name",
    "scene",
    "kind",
    "technique",
    "family",
    "params",
    "width",
    "height",
    "thumbnail",
    "metrics",
    "thresholds",
    "noise_floor",
    "cost",
    "failing",
    "within_noise",
    "status",
    "images",
    "error_maps",
    "worst_tiles",
    "exr_links",
)
