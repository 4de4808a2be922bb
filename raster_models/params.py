"""Technique parameters: frozen dataclasses whose fields carry their source, help and range.

Every parameter is declared with :func:`param`, which stores in the field's metadata where the
default comes from (``"Intel SDSM sample default"``), a help line, and what is valid (choices
or a numeric range). :func:`make` builds and validates an instance from keyword arguments,
:func:`parse_pairs` from ``"key=value"`` strings, and :func:`describe` lists the fields for
``raster-oracle techniques``. Every message names the parameter, what was expected and what
was received.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from ..scenes.base.numbers import NumberError, parse_float, parse_int
from .errors import ModelError

__all__ = ["as_dict", "describe", "make", "param", "parse_pairs"]

_KINDS = ("bool", "int", "float", "str", "floats")


def param(
    default: Any,
    *,
    source: str,
    help: str,
    choices: tuple[str, ...] | None = None,
    lo: float | None = None,
    hi: float | None = None,
    kind: str | None = None,
    allow_inf: bool = False,
) -> Any:
    """A dataclass field with its provenance and validity in the metadata.

    ``lo``/``hi`` are inclusive bounds for numbers (``floats``: for every element); ``kind``
    is inferred from the default (``bool``, ``int``, ``float``, ``str``; a tuple is ``floats``).
    Numbers must be finite: NaN and infinities are refused, except ``+inf`` for a ``float``
    declared with ``allow_inf=True`` (documented as "no limit" in its help).
    """
    if kind is None:
        if isinstance(default, bool):
            kind = "bool"
        elif isinstance(default, int):
            kind = "int"
        elif isinstance(default, float):
            kind = "float"
        elif isinstance(default, str):
            kind = "str"
        elif isinstance(default, tuple):
            kind = "floats"
        else:  # pragma: no cover - programming error
            raise TypeError(f"unsupported parameter default {default!r}")
    if kind not in _KINDS:  # pragma: no cover - programming error
        raise TypeError(f"unknown parameter kind {kind!r}")
    meta = {
        "source": source,
        "help": help,
        "choices": choices,
        "lo": lo,
        "hi": hi,
        "kind": kind,
        "allow_inf": allow_inf,
    }
    return dataclasses.field(default=default, metadata=meta)


def _fields(cls) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls) if f.metadata.get("kind")]


def _range_text(meta) -> str:
    lo, hi = meta["lo"], meta["hi"]
    if lo is not None and hi is not None:
        return f" in [{lo:g}, {hi:g}]"
    if lo is not None:
        return f" >= {lo:g}"
    if hi is not None:
        return f" <= {hi:g}"
    return ""


def _expected(meta) -> str:
    kind = meta["kind"]
    if meta["choices"]:
        return "one of " + ", ".join(meta["choices"])
    if kind == "floats":
        return "a comma-separated list of numbers" + _range_text(meta)
    if kind == "bool":
        return "a boolean (true/false)"
    word = "an integer" if kind == "int" else "a number"
    text = word + _range_text(meta)
    if kind == "float" and meta.get("allow_inf"):
        text += " (inf = no limit)"
    return text


def _check(technique: str, f: dataclasses.Field, value: Any) -> Any:
    """Validate one value (already of a Python type) and return it normalized."""
    meta = f.metadata
    kind = meta["kind"]
    bad = ModelError(f"{technique}: parameter {f.name} must be {_expected(meta)}, got {value!r}")
    # NaN and infinities: refused by name ("a finite number"), unless documented.
    not_finite = ModelError(
        f"{technique}: parameter {f.name} must be "
        f"{_expected(meta).replace('number', 'finite number', 1)}, got {value!r}"
    )
    if kind == "bool":
        if not isinstance(value, bool):
            raise bad
        return value
    if kind == "str":
        if not isinstance(value, str) or (meta["choices"] and value not in meta["choices"]):
            raise bad
        return value
    if kind == "floats":
        try:
            items = tuple(float(v) for v in value)
        except (TypeError, ValueError):
            raise bad from None
        for v in items:
            if not math.isfinite(v):
                raise not_finite
            if (meta["lo"] is not None and v < meta["lo"]) or (
                meta["hi"] is not None and v > meta["hi"]
            ):
                raise bad
        return items
    if isinstance(value, bool):
        raise bad
    if kind == "int":
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int):
            raise bad
    else:
        if not isinstance(value, int | float):
            raise bad
        value = float(value)
        if math.isnan(value) or (math.isinf(value) and not (value > 0 and meta.get("allow_inf"))):
            raise bad if meta.get("allow_inf") else not_finite
    if (meta["lo"] is not None and value < meta["lo"]) or (
        meta["hi"] is not None and value > meta["hi"]
    ):
        raise bad
    return value


def _parse_text(technique: str, f: dataclasses.Field, text: str) -> Any:
    """Convert a command-line string to the field's Python type (then :func:`_check`)."""
    kind = f.metadata["kind"]
    s = text.strip()
    bad = ModelError(
        f"{technique}: parameter {f.name} must be {_expected(f.metadata)}, got {text!r}"
    )
    if kind == "bool":
        low = s.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise bad
    if kind == "str":
        return s
    try:
        if kind == "floats":
            parts = [p.strip() for p in s.replace(";", ",").split(",") if p.strip()]
            return tuple(_float_text(p, f.name) for p in parts)
        if kind == "int":
            try:
                return parse_int(s, what=f.name, signed=True)
            except NumberError:
                v = parse_float(s, what=f.name)  # 2.0 is the integer 2; 2.5 is refused
                if v.is_integer():
                    return int(v)
                raise
        return _float_text(s, f.name)
    except NumberError:
        raise bad from None


def _float_text(text: str, name: str) -> float:
    """A strict decimal number (:func:`parse_float`), or ``inf``/``nan`` (refused or taken by
    :func:`_check`, which names them)."""
    if text.lower().lstrip("+-") in ("inf", "infinity", "nan"):
        return float(text)
    return parse_float(text, what=name)


def _unknown(technique: str, cls, name: str) -> ModelError:
    names = ", ".join(f.name for f in _fields(cls))
    return ModelError(f"{technique}: unknown parameter {name!r}; valid parameters: {names}")


def make(technique: str, cls, values: dict | None = None):
    """Validated instance of the parameter dataclass ``cls`` from Python values."""
    values = dict(values or {})
    known = {f.name: f for f in _fields(cls)}
    out = {}
    for name, value in values.items():
        if name not in known:
            raise _unknown(technique, cls, name)
        out[name] = _check(technique, known[name], value)
    inst = cls(**out)
    check = getattr(inst, "check", None)
    if check is not None:
        check(technique)
    return inst


def parse_pairs(technique: str, cls, pairs: list[str] | tuple[str, ...]) -> dict:
    """Typed, validated values from ``"key=value"`` strings (later pairs win)."""
    known = {f.name: f for f in _fields(cls)}
    values: dict = {}
    for pair in pairs:
        if not isinstance(pair, str) or "=" not in pair:
            raise ModelError(f"{technique}: parameters are given as key=value, got {pair!r}")
        key, text = pair.split("=", 1)
        key = key.strip().replace("-", "_")
        if key not in known:
            raise _unknown(technique, cls, key)
        values[key] = _check(technique, known[key], _parse_text(technique, known[key], text))
    make(technique, cls, values)  # cross-field checks
    return values


def describe(cls) -> list[dict]:
    """One JSON-serialisable record per parameter: name, default, type, choices, source, help."""
    out = []
    for f in _fields(cls):
        meta = f.metadata
        default = f.default
        if isinstance(default, float) and math.isinf(default):
            default = "inf"
        elif isinstance(default, tuple):
            default = list(default)
        out.append(
            {
                "name": f.name,
                "default": default,
                "type": meta["kind"],
                "choices": list(meta["choices"]) if meta["choices"] else None,
                "range": [meta["lo"], meta["hi"]]
                if (meta["lo"] is not None or meta["hi"] is not None)
                else None,
                "source": meta["source"],
                "help": meta["help"],
            }
        )
    return out


def as_dict(inst) -> dict:
    """Every parameter with its value, JSON-serialisable (``inf`` as the string ``"inf"``)."""
    out = {}
    for f in _fields(type(inst)):
        v = getattr(inst, f.name)
        if isinstance(v, float) and math.isinf(v):
            v = "inf"
        elif isinstance(v, tuple):
            v = list(v)
        out[f.name] = v
    return out
