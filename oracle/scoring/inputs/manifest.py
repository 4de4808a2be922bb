"""A CI manifest for ``score-folder ROOT --manifest ci.toml``: each scene's file, channels,
gates, frames and camera path.

.. code-block:: toml

    [defaults]                      # optional; every key may be given per scene too
    spp = 16
    profiles = ["unreal-low"]       # gate profiles (--gate-profile)
    exports = "exports"             # folder of `export` folders, relative to the manifest
    fail_above = { flip_mean = 0.1 }

    [scenes.plate]                  # a built-in scene, EXPORTS/plate, or `scene = "..."`
    file = "plate.exr"              # relative to ROOT; a {frame} pattern with frames
    [scenes.plate.channels.shadow]  # a layer or channel of the file: one scored case each
    fail_above = { misclassified_fraction = 0.01 }
    [scenes.plate.channels.msaa]
    fail_below = { ssim = 0.95 }

    [scenes.pan]
    scene = "exports/plate"         # relative to the manifest
    file = "pan/frame_{frame:03d}.exr"
    frames = 4
    camera_path = "subpixel-pan"    # needed with frames (unless the export records one)
    channels = { shadow = {} }

Also at every level: ``transfer`` (``srgb``, ``gamma2.2``, ``linear``: how a PNG's colour
is decoded), ``expect`` (``"shadow-map:resolution=2048,filter=pcf"``: the technique the
engine claims, scored for conformance), ``family`` (``"rtshadows"``: the technique family
the frames come from, whose record decides the passes), ``baseline_metrics`` (a list, or
``"all"``) and ``baseline_tolerance`` (``{ flip_mean = 0.005, ssim = "1%" }``: absolute, or
relative to the baseline's error).

Every key is checked (an unknown key, a wrong type or an unknown metric is a
:class:`ManifestError` naming it, before anything is scored). The manifest is untrusted
input (:mod:`scenes.base.untrusted`): a regular file of at most :data:`LIMITS` ``bytes``,
tables and arrays at most ``nesting`` deep, at most ``cases`` scored cases; scene and
channel keys name one folder each under ``--out``, ``file`` stays inside ROOT with
``{frame}`` its only field (:mod:`.out_names`); ``spp`` is at most :data:`MAX_SPP` (the
command line's limit), ``frames`` at most :data:`MAX_FRAMES`. Gates add up from
``[defaults]`` to the scene to the channel; a later limit of the same metric and direction
replaces an earlier one.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from ....scenes import SceneError
from ....scenes.base.numbers import MAX_FRAMES
from ....scenes.base.untrusted import LIMITS as FILE_LIMITS
from ....scenes.base.untrusted import json_depth, read_text
from ....scenes.inputs import named_input
from ..ci.checks import Gate, GateError
from ..ci.gates import parse_gates
from ..options import VISIBILITY_CONVENTIONS
from .candidates import TRANSFERS
from .out_names import check_out_name, relative_file

__all__ = [
    "LIMITS",
    "MAX_FRAMES",
    "MAX_SPP",
    "Manifest",
    "ManifestCase",
    "ManifestError",
    "read_manifest",
]

#: Limits of a manifest: its bytes, nesting depth and scored cases.
LIMITS = {"bytes": FILE_LIMITS["manifest_bytes"], "nesting": 16, "cases": 1000}
#: Largest ``spp`` (the command line's ``--spp`` limit, 2^20).
MAX_SPP = 2**20
#: Largest ``frames`` (as ``--frames``: :data:`scenes.base.numbers.MAX_FRAMES`).

_COMMON = {
    "fail_above",
    "fail_below",
    "profiles",
    "visibility",
    "camera_path",
    "spp",
    "seed",
    "flip_mode",
    "transfer",
    "expect",
    "family",
    "baseline_metrics",
    "baseline_tolerance",
}
_DEFAULT_KEYS = _COMMON | {"exports"}
_SCENE_KEYS = _COMMON | {"scene", "file", "frames", "channels"}
_CHANNEL_KEYS = {
    "kind",
    "fail_above",
    "fail_below",
    "profiles",
    "visibility",
    "transfer",
    "expect",
    "family",
    "baseline_metrics",
    "baseline_tolerance",
}
_KINDS = ("visibility", "color", "coverage")


class ManifestError(GateError):
    """A manifest that cannot be used (exit 2 before anything is scored)."""


@dataclass(frozen=True)
class ManifestCase:
    """One scored case: ``scene`` key x ``channel`` (None: the file's only image)."""

    name: str
    scene_key: str
    scene: str
    file: str
    channel: str | None
    kind: str | None
    frames: int | None
    camera_path: str | None
    visibility: str
    gates: tuple[Gate, ...]
    transfer: str | None = None
    expect: str | None = None
    #: the technique family the frames come from (``rtshadows``): its record decides the passes
    family: str | None = None
    #: ``{"metrics": keys, "all" or None, "tolerances": metric -> (t, relative)}``
    baseline: dict | None = None


@dataclass(frozen=True)
class Manifest:
    """The cases of a manifest and its reference options (``spp``, ``seed``,
    ``flip_mode``: None where the manifest leaves them to the command line)."""

    path: Path
    cases: list[ManifestCase] = field(default_factory=list)
    spp: int | None = None
    seed: int | None = None
    flip_mode: str | None = None


def _table(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ManifestError(f"{where} must be a table, got {type(value).__name__}")
    return value


def _keys(table: dict, allowed: set, where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ManifestError(
            f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(allowed))}"
        )


def _int(value, where: str, *, minimum: int, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ManifestError(f"{where} must be an integer >= {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        raise ManifestError(f"{where} must be at most {maximum}, got {value}")
    return value


def _text(value, where: str, choices=None) -> str:
    if not isinstance(value, str) or not value:
        raise ManifestError(f"{where} must be a non-empty string, got {value!r}")
    if choices is not None and value not in choices:
        raise ManifestError(f"{where} must be one of {', '.join(choices)}, got {value!r}")
    return value


def _gates(table: dict, where: str) -> list[Gate]:
    texts = {}
    for key, option in (("fail_above", "--fail-above"), ("fail_below", "--fail-below")):
        limits = _table(table.get(key, {}), f"{where}.{key}")
        for metric, limit in limits.items():
            if isinstance(limit, bool) or not isinstance(limit, int | float):
                raise ManifestError(f"{where}.{key}.{metric} must be a number, got {limit!r}")
        texts[option] = [f"{m}={float(v)!r}" for m, v in limits.items()]
    profiles = table.get("profiles", [])
    if not isinstance(profiles, list) or not all(isinstance(p, str) for p in profiles):
        raise ManifestError(f"{where}.profiles must be a list of names, got {profiles!r}")
    from ..ci.profiles import profile_gates

    try:
        gates = profile_gates(profiles, error=ManifestError, origin=f"{where}.profiles")
        limits = parse_gates(texts["--fail-above"], texts["--fail-below"])
    except GateError as exc:
        raise ManifestError(f"{where}: {exc}") from None
    key = {"<=": "fail_above", ">=": "fail_below"}
    return gates + [replace(g, origin=f"{where}.{key[g.op]}") for g in limits]


def _baseline(table: dict, where: str) -> dict:
    """``baseline_metrics`` (a list of keys or ``"all"``) and ``baseline_tolerance`` (metric
    -> a number or a percentage string such as ``"5%"``) of one level."""
    from ..ci.regression import parse_baseline_metrics, parse_tolerance

    out = {}
    try:
        if "baseline_metrics" in table:
            keys = table["baseline_metrics"]
            if not (
                keys == "all" or isinstance(keys, list) and all(isinstance(k, str) for k in keys)
            ):
                raise ManifestError(f'{where}.baseline_metrics must be a list of metrics or "all"')
            out["metrics"] = parse_baseline_metrics(
                [keys] if keys == "all" else keys, option=f"{where}.baseline_metrics"
            )
        if "baseline_tolerance" in table:
            tols = _table(table["baseline_tolerance"], f"{where}.baseline_tolerance")
            for k, v in tols.items():
                if isinstance(v, bool) or not isinstance(v, int | float | str):
                    raise ManifestError(
                        f"{where}.baseline_tolerance.{k} must be a number or a percentage"
                    )
            out["tolerances"] = dict(
                parse_tolerance(f"{k}={v}", option=f"{where}.baseline_tolerance")
                for k, v in tols.items()
            )
    except GateError as exc:
        if isinstance(exc, ManifestError):
            raise
        raise ManifestError(str(exc)) from None
    return out


def _merge_baseline(*levels: dict) -> dict | None:
    merged: dict = {}
    for level in levels:
        if "metrics" in level:
            merged["metrics"] = level["metrics"]
        if "tolerances" in level:
            merged["tolerances"] = {**merged.get("tolerances", {}), **level["tolerances"]}
    return merged or None


def _merge(*levels: list[Gate]) -> tuple[Gate, ...]:
    merged: dict = {}
    for gates in levels:
        for g in gates:
            merged[(g.metric, g.op)] = g
    return tuple(merged.values())


def _relative_file(text: str, where: str) -> str:
    return relative_file(text, where, error=ManifestError)


def _scene_ref(table: dict, key: str, where: str, *, base: Path, exports: Path | None) -> str:
    if "scene" in table:
        text = _text(table["scene"], f"{where}.scene")
        local = base / text
        return str(local) if local.exists() else text
    try:
        return named_input(key, exports=exports)
    except SceneError as exc:
        raise ManifestError(f'{where}: {exc} (or give scene = "...")') from None


def _opt(table: dict, key: str, check, *args, **kw):
    """``check(table[key], ...)`` when the key is given, else None."""
    return check(table[key], *args, **kw) if key in table else None


def _scene_cases(key: str, table, defaults: dict, ctx: dict) -> list[ManifestCase]:
    where = f"[scenes.{key}]"
    check_out_name(key, "[scenes]", error=ManifestError)
    table = _table(table, where)
    _keys(table, _SCENE_KEYS, where)
    for k in ("spp", "seed", "flip_mode"):
        if k in table:
            raise ManifestError(f"{where}.{k}: give {k} in [defaults] (one setting a run)")
    merged = {**defaults, **table}
    file = _relative_file(_text(table.get("file", f"{key}.exr"), f"{where}.file"), f"{where}.file")
    frames = _opt(table, "frames", _int, f"{where}.frames", minimum=1, maximum=MAX_FRAMES)
    camera = _opt(merged, "camera_path", _text, f"{where}.camera_path")
    scene = _scene_ref(table, key, where, base=ctx["base"], exports=ctx["exports"])
    scene_gates = _gates(table, where)
    cases = []
    for channel, ctable in _table(table.get("channels", {None: {}}), f"{where}.channels").items():
        # the key path of what is wrong (no channels table: the scene's own table)
        cwhere = where if channel is None else f"{where}.channels.{channel}"
        if channel is not None:
            check_out_name(channel, f"{where}.channels", error=ManifestError)
        ctable = _table(ctable, cwhere)
        _keys(ctable, _CHANNEL_KEYS, cwhere)
        visibility = ctable.get("visibility", merged.get("visibility", "1-is-lit"))
        cmerged = {**merged, **ctable}
        cases.append(
            ManifestCase(
                name=key if channel is None else f"{key}/{channel}",
                scene_key=key,
                scene=scene,
                file=file,
                channel=channel,
                kind=_opt(ctable, "kind", _text, f"{cwhere}.kind", _KINDS),
                frames=frames if frames and frames > 1 else None,
                camera_path=camera,
                visibility=_text(visibility, f"{cwhere}.visibility", VISIBILITY_CONVENTIONS),
                gates=_merge(ctx["gates"], scene_gates, _gates(ctable, cwhere)),
                transfer=_opt(cmerged, "transfer", _text, f"{cwhere}.transfer", TRANSFERS),
                expect=_opt(cmerged, "expect", _text, f"{cwhere}.expect"),
                family=_opt(cmerged, "family", _text, f"{cwhere}.family"),
                baseline=_merge_baseline(
                    ctx["baseline"], _baseline(table, where), _baseline(ctable, cwhere)
                ),
            )
        )
    return cases


def read_manifest(path) -> Manifest:
    """Read and check a manifest (see the module docstring); :class:`ManifestError` names
    the first problem."""
    path = Path(path)
    what = "--manifest"
    text = read_text(path, limit=LIMITS["bytes"], what=what, error=ManifestError)
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ManifestError(f"{what} {path}: nested deeper than {LIMITS['nesting']}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"{what} {path} is not TOML: {exc}") from None
    if json_depth(data, LIMITS["nesting"]) > LIMITS["nesting"]:
        raise ManifestError(f"{what} {path}: nested deeper than {LIMITS['nesting']}")
    _keys(data, {"defaults", "scenes"}, f"--manifest {path}")
    defaults = _table(data.get("defaults", {}), "[defaults]")
    _keys(defaults, _DEFAULT_KEYS, "[defaults]")
    scenes = _table(data.get("scenes", {}), "[scenes]")
    if not scenes:
        raise ManifestError(f"--manifest {path} names no scene ([scenes.NAME] tables)")
    base = path.resolve().parent
    exports = _opt(defaults, "exports", _text, "[defaults].exports")
    ctx = {
        "base": base,
        "exports": base / exports if exports else None,
        "gates": _gates(defaults, "[defaults]"),
        "baseline": _baseline(defaults, "[defaults]"),
    }
    cases = []
    for key, table in scenes.items():
        cases += _scene_cases(key, table, defaults, ctx)
        if len(cases) > LIMITS["cases"]:
            raise ManifestError(f"{what} {path}: more than {LIMITS['cases']} cases (the limit)")
    return Manifest(
        path=path,
        cases=cases,
        spp=_opt(defaults, "spp", _int, "[defaults].spp", minimum=1, maximum=MAX_SPP),
        seed=_opt(defaults, "seed", _int, "[defaults].seed", minimum=0, maximum=2**32 - 1),
        flip_mode=_opt(defaults, "flip_mode", _text, "[defaults].flip_mode", ("LDR", "HDR")),
    )
