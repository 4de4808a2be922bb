"""Text formatting of numbers and records for the HTML page (used as jinja2 filters).

Every function returns plain ``str`` (except :func:`json_script`, whose JSON is safe inside
a ``<script>`` element); escaping is left to jinja2's autoescape (or to the SVG builder, which
escapes what it embeds).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

from markupsafe import Markup

from ._validate import decode_float

__all__ = [
    "flatten",
    "fmt_bytes",
    "fmt_cost",
    "fmt_json",
    "fmt_mb",
    "fmt_number",
    "fmt_summary",
    "fmt_threshold",
    "fmt_value",
    "json_script",
    "sort_key",
]

# JSON inside <script type="application/json">: "</script>", "<!--" and HTML entities must
# not appear literally, and U+2028/U+2029 break older JS parsers.
_JSON_SCRIPT_ESCAPES = {
    ord("<"): "\\u003c",
    ord(">"): "\\u003e",
    ord("&"): "\\u0026",
    ord("'"): "\\u0027",
    0x2028: "\\u2028",
    0x2029: "\\u2029",
}


def json_script(value: object) -> Markup:
    """Serialise ``value`` as JSON safe to place verbatim inside a ``<script>`` element."""
    text = json.dumps(value, ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    return Markup(text.translate(_JSON_SCRIPT_ESCAPES))


_NONFINITE_TEXT = {"inf": "∞", "-inf": "−∞", "nan": "NaN"}


def fmt_number(value: object) -> str:
    """Four significant digits; ``"inf"``/``"nan"`` encodings shown as ∞ / NaN; None as —."""
    if value is None:
        return "—"
    if isinstance(value, str):
        return _NONFINITE_TEXT.get(value, value)
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return f"{value:,}"
    value = float(value)
    if not math.isfinite(value):
        return _NONFINITE_TEXT["nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")]
    if value == 0.0:
        return "0"
    text = f"{value:.4g}"
    for digits in (6, 9):  # an SSIM of 0.99996 is not 1: more digits until told apart
        if abs(value) >= 10 or float(text) != round(float(text)) or float(text) == value:
            break
        text = f"{value:.{digits}g}"
    return text.replace("-", "−")


def fmt_bytes(value: float) -> str:
    """Binary units: ``"512 B"``, ``"4 MiB"``, ``"1.5 GiB"`` (three significant digits)."""
    value = float(value)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(value) < 1024.0 or unit == "TiB":
            return f"{value:.3g} {unit}"
        value /= 1024.0
    raise AssertionError("unreachable")


def fmt_cost(value: object, key: str) -> str:
    """Cost values: ``*_bytes`` keys in binary units, integers with thousands separators."""
    if value is None:
        return "—"
    if key.endswith("bytes") and not isinstance(value, str):
        return fmt_bytes(value)
    return fmt_number(value)


def fmt_threshold(bounds: object) -> str:
    """``{"max": 0.05}`` -> ``"≤ 0.05"``; ``{"min": 30}`` -> ``"≥ 30"``; ``"varies"`` kept."""
    if not isinstance(bounds, Mapping):
        return "per case" if bounds == "varies" else fmt_number(bounds)
    parts = []
    if "min" in bounds:
        parts.append(f"≥ {fmt_number(bounds['min'])}")
    if "max" in bounds:
        parts.append(f"≤ {fmt_number(bounds['max'])}")
    return ", ".join(parts)


def fmt_value(value: object) -> str:
    """Provenance and parameter values: numbers to 6 digits, lists comma-separated."""
    if value is None:
        return "—"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return ", ".join(fmt_value(v) for v in value)
    return json.dumps(value, ensure_ascii=False, sort_keys=True)


def flatten(record: Mapping, prefix: str = "") -> list[tuple[str, object]]:
    """``{"a": {"b": 1}}`` -> ``[("a.b", 1)]``: nested dicts as dotted keys, in order."""
    rows: list[tuple[str, object]] = []
    for key, value in record.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping) and value:
            rows.extend(flatten(value, prefix=f"{name}."))
        else:
            rows.append((name, value))
    return rows


def sort_key(value: object) -> str:
    """The ``data-sort`` attribute of a numeric table cell: a float JS ``Number()`` parses."""
    if value is None:
        return ""
    number = decode_float(value)
    if math.isnan(number):
        return ""
    if math.isinf(number):
        return "Infinity" if number > 0 else "-Infinity"
    return repr(number)


def fmt_mb(value: float) -> str:
    """Megabytes (or mebibytes) to one decimal: ``41.0``."""
    return f"{float(value):.1f}"


def fmt_json(value: object) -> str:
    """Any JSON-like value as indented JSON text (non-JSON values by ``str``)."""
    return json.dumps(value, indent=1, default=str, ensure_ascii=False)


def fmt_summary(value: object) -> str:
    """``mean ± stderr (n = N, min .. max)`` of a ``{"mean", "stderr", "n", "min", "max"}``
    summary record (:func:`oracle.studies.claims.run.summary`); — when it has no mean."""
    if not isinstance(value, Mapping) or value.get("mean") is None:
        return "—"
    text = f"{fmt_number(value['mean'])} ± {fmt_number(value.get('stderr'))}"
    if value.get("n", 0) > 1:
        low, high = fmt_number(value.get("min")), fmt_number(value.get("max"))
        text += f" (n = {value['n']}, {low} .. {high})"
    return text
