"""Sweep specs: a TOML file of scenes x techniques x parameter grids x frames, expanded into
cases.

Format::

    name = "shadow maps"
    [defaults]                 # width, height, spp, seed (and light: the light index)
    width = 640
    height = 360
    spp = 16
    seed = 0

    [[case]]
    scenes = ["plate", "city"]          # built-in names or Mitsuba XML files (relative to
    technique = "shadow-map"            # the spec's folder)
    frames = [0, 4]                     # optional, with camera_path (or light_path)
    camera_path = "dolly"
    n_frames = 8                        # optional: frames of the path (default 8)
    [case.params]
    resolution = {logrange = [256, 4096, 5]}   # 256, 512, 1024, 2048, 4096
    filter = ["hw_pcf", "pcf"]                 # a list: each value
    bias = {range = [0.001, 0.003, 0.001]}     # inclusive: 0.001, 0.002, 0.003
    depth_clamp = true                         # a scalar: one value

A case table may also set ``width``, ``height``, ``spp``, ``seed`` or ``light`` for itself.
The grid of a case table is the cartesian product of its parameter values, for every scene
and frame. ``logrange = [lo, hi, n]`` gives ``n`` geometrically spaced values (rounded and
deduplicated for integer parameters). For a parameter whose value is itself a list
(``floats``, e.g. manual split depths), a flat list of numbers is one value and a list of
lists is a list of values. Techniques that do not support a scene's light kind are skipped
on that scene (:attr:`Expansion.skipped` says which).

Every error is a :class:`SpecError` whose message starts with the key at fault
(``case[2].params.resolution: ...``).
"""

from __future__ import annotations

import itertools
import math
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ...scenes.light_paths import LIGHT_PATHS, check_light_path
from ..errors import InputError
from ..reference.render import MAX_SEED

__all__ = ["Case", "Expansion", "SpecError", "expand_spec", "expand_values", "load_spec"]

_TOP_KEYS = ("name", "defaults", "case")
_DEFAULT_KEYS = ("width", "height", "spp", "seed", "light")
_CASE_KEYS = (
    "scenes",
    "technique",
    "params",
    "frames",
    "camera_path",
    "light_path",
    "n_frames",
    *_DEFAULT_KEYS,
)
#: Built-in defaults of a spec without a ``[defaults]`` table: the scene's own resolution
#: (``None``), 64 spp and seed 0, as ``raster-oracle score``.
BUILTIN_DEFAULTS = {"width": None, "height": None, "spp": 64, "seed": 0, "light": 0}
#: Largest number of cases one spec may expand to (a typo in a range must not make a
#: billion-row grid before anything runs).
MAX_CASES = 100_000
#: Largest ``spp`` of a spec (as ``--spp``: 2^20).
MAX_SPP = 2**20
#: Relative slack of an inclusive ``range`` end: ``range = [0.1, 0.3, 0.1]`` includes 0.3
#: although 0.1 + 2 * 0.1 rounds to 0.30000000000000004.
RANGE_END_SLACK = 1e-9
#: Decimal places float grid values are rounded to, so they print and hash as written.
FLOAT_DIGITS = 12


class SpecError(InputError):
    """A malformed sweep spec; the message starts with the offending key."""


@dataclass(frozen=True)
class Case:
    """One unit of work: one technique configuration on one scene frame."""

    scene: str
    technique: str
    params: dict
    width: int | None
    height: int | None
    spp: int
    seed: int
    light: int = 0
    camera_path: str | None = None
    light_path: str | None = None
    frame: int = 0
    n_frames: int = 8

    def record(self) -> dict:
        """Plain JSON-serialisable record (what Dask ships to a worker)."""
        return {
            "scene": self.scene,
            "technique": self.technique,
            "params": dict(self.params),
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "seed": self.seed,
            "light": self.light,
            "camera_path": self.camera_path,
            "light_path": self.light_path,
            "frame": self.frame,
            "n_frames": self.n_frames,
        }

    def label(self) -> str:
        p = " ".join(f"{k}={_short(v)}" for k, v in self.params.items())
        where = f" {self.camera_path or self.light_path}#{self.frame}" if self.frame_path else ""
        return f"{self.technique} {p} @ {self.scene}{where}".replace("  ", " ")

    @property
    def frame_path(self) -> str | None:
        return self.camera_path or self.light_path


@dataclass
class Expansion:
    """An expanded spec: its name, the cases in order, and the skipped combinations."""

    name: str
    cases: list[Case]
    skipped: list[str] = field(default_factory=list)


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | tuple):
        return ",".join(_short(x) for x in v)
    return str(v)


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _int_value(where: str, v, *, minimum: int, maximum: int | None = None) -> int:
    if not isinstance(v, int) or isinstance(v, bool):
        raise SpecError(f"{where}: expected an integer, got {v!r}")
    if v < minimum or (maximum is not None and v > maximum):
        upper = f" and <= {maximum}" if maximum is not None else ""
        raise SpecError(f"{where}: must be >= {minimum}{upper}, got {v}")
    return v


def _finite(where: str, v) -> float:
    if not _is_number(v) or not math.isfinite(float(v)):
        raise SpecError(f"{where}: expected a finite number, got {v!r}")
    return float(v)


def expand_values(where: str, value, *, kind: str = "float") -> list:
    """The values of one grid entry: a scalar, a list, ``{range}`` or ``{logrange}``.

    Parameters
    ----------
    where : the key for messages (``case[0].params.resolution``).
    value : the TOML value.
    kind : the parameter's kind (``int``, ``float``, ``str``, ``bool``, ``floats``): integer
        parameters get integer values (rounded for ``logrange``, deduplicated in order).
    """
    if isinstance(value, dict):
        if set(value) == {"range"}:
            lo, hi, step = _triple(where + ".range", value["range"])
            if not step > 0:
                raise SpecError(f"{where}.range: step must be > 0, got {step:g}")
            if hi < lo:
                raise SpecError(f"{where}.range: end {hi:g} is below start {lo:g}")
            span = (hi - lo) / step  # inf when (hi - lo) or the quotient overflows
            if not span < MAX_CASES:
                raise SpecError(
                    f"{where}.range: (end - start) / step = {span:g} values (more than {MAX_CASES})"
                )
            n = math.floor(span * (1 + RANGE_END_SLACK) + RANGE_END_SLACK) + 1
            if n > MAX_CASES:
                raise SpecError(f"{where}.range: {n} values (more than {MAX_CASES})")
            vals = [lo + i * step for i in range(n)]
        elif set(value) == {"logrange"}:
            lo, hi, count = _triple(where + ".logrange", value["logrange"])
            if not (lo > 0 and hi > 0):
                raise SpecError(f"{where}.logrange: bounds must be > 0, got {lo:g} and {hi:g}")
            if hi < lo:
                raise SpecError(f"{where}.logrange: end {hi:g} is below start {lo:g}")
            if not float(count).is_integer() or not 1 <= count <= MAX_CASES:
                raise SpecError(
                    f"{where}.logrange: the count must be an integer in [1, {MAX_CASES}], "
                    f"got {count:g}"
                )
            n = int(count)
            ratio = hi / lo
            if not math.isfinite(ratio):
                raise SpecError(
                    f"{where}.logrange: end / start overflows a float ({hi:g} / {lo:g})"
                )
            vals = [lo] if n == 1 else [lo * ratio ** (i / (n - 1)) for i in range(n)]
            if n > 1:
                vals[-1] = hi
        else:
            keys = ", ".join(sorted(value)) or "(none)"
            raise SpecError(
                f"{where}: a table value must be {{range = [lo, hi, step]}} or "
                f"{{logrange = [lo, hi, n]}}, got keys {keys}"
            )
        if kind == "int":
            out = []
            for v in vals:
                r = int(round(v))
                if r not in out:
                    out.append(r)
            return out
        if kind not in ("float", "int"):
            raise SpecError(f"{where}: ranges apply to number parameters, this one is {kind}")
        return [round(v, FLOAT_DIGITS) for v in vals]
    if kind == "floats":
        if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            return [list(v) for v in value]
        return [value]
    if isinstance(value, list):
        if not value:
            raise SpecError(f"{where}: an empty list gives no case")
        return list(value)
    return [value]


def _triple(where: str, v) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise SpecError(f"{where}: expected three numbers [lo, hi, step or n], got {v!r}")
    return tuple(_finite(f"{where}[{i}]", x) for i, x in enumerate(v))


def _check_keys(where: str, table, allowed) -> None:
    if not isinstance(table, dict):
        raise SpecError(f"{where}: expected a table, got {type(table).__name__}")
    for key in table:
        if key not in allowed:
            prefix = f"{where}." if where else ""
            raise SpecError(f"{prefix}{key}: unknown key; valid keys: {', '.join(allowed)}")


def _settings(where: str, table: dict, base: dict) -> dict:
    out = dict(base)
    for key in _DEFAULT_KEYS:
        if key not in table:
            continue
        v = table[key]
        if key in ("width", "height"):
            out[key] = _int_value(f"{where}.{key}", v, minimum=1, maximum=16384)
        elif key == "spp":
            out[key] = _int_value(f"{where}.{key}", v, minimum=1, maximum=MAX_SPP)
        elif key == "seed":
            out[key] = _int_value(f"{where}.{key}", v, minimum=0, maximum=MAX_SEED)
        else:
            out[key] = _int_value(f"{where}.{key}", v, minimum=0)
    if (out["width"] is None) != (out["height"] is None):
        raise SpecError(f"{where}: give both width and height, or neither")
    return out


def _frames(where: str, table: dict) -> tuple[str | None, str | None, list[int], int]:
    from ... import scenes

    camera_path, light_path = table.get("camera_path"), table.get("light_path")
    if camera_path is not None and light_path is not None:
        raise SpecError(f"{where}: give camera_path or light_path, not both")
    if camera_path is not None and camera_path not in scenes.CAMERA_PATHS:
        raise SpecError(
            f"{where}.camera_path: unknown camera path {camera_path!r}; choose one of "
            f"{', '.join(scenes.CAMERA_PATHS)}"
        )
    if light_path is not None and light_path not in LIGHT_PATHS:
        raise SpecError(
            f"{where}.light_path: unknown light path {light_path!r}; choose one of "
            f"{', '.join(LIGHT_PATHS)}"
        )
    path = camera_path or light_path
    n_frames = _int_value(f"{where}.n_frames", table.get("n_frames", 8), minimum=1)
    if "frames" not in table:
        if path is not None:
            raise SpecError(f"{where}.frames: a {where}.camera_path/light_path needs frames")
        return None, None, [0], 1
    frames = table["frames"]
    if not isinstance(frames, list) or not frames:
        raise SpecError(f"{where}.frames: expected a non-empty list of frame numbers")
    frames = [_int_value(f"{where}.frames", k, minimum=0) for k in frames]
    if path is None:
        if frames != [0]:
            raise SpecError(f"{where}.frames: frames other than 0 need camera_path or light_path")
        return None, None, [0], 1
    if "n_frames" not in table:
        n_frames = max(n_frames, max(frames) + 1)
    bad = [k for k in frames if k >= n_frames]
    if bad:
        raise SpecError(f"{where}.frames: frame {bad[0]} is outside [0, {n_frames}) (n_frames)")
    return camera_path, light_path, list(dict.fromkeys(frames)), n_frames


def _scene_name(where: str, name, base_dir: Path | None) -> str:
    from ... import scenes

    if not isinstance(name, str) or not name:
        raise SpecError(f"{where}: expected a scene name, got {name!r}")
    try:
        if scenes.builtin_scene(name) is not None:  # meadow:n=100000 too
            return name
    except scenes.SceneParamError as exc:
        raise SpecError(f"{where}: {exc}") from None
    path = Path(name)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    if path.suffix.lower() not in (".xml", ".gltf", ".glb") or not path.is_file():
        raise SpecError(
            f"{where}: unknown scene {name!r}: not a built-in scene "
            f"({', '.join(scenes.BUILTIN_SCENES)}), a Mitsuba XML file nor a glTF file"
        )
    return str(path.resolve())


def _scene_light(scene: str, light: int, memo: dict):
    """The light of a scene (loaded once per scene; small film, only the light counts)."""
    from ... import scenes

    key = (scene, light)
    if key not in memo:
        try:
            memo[key] = scenes.load(scene, width=16, height=16, light=light).light
        except scenes.SceneError as exc:
            raise SpecError(f"scene {scene}: {exc}") from None
    return memo[key]


def expand_spec(
    data: dict, *, base_dir: Path | None = None, skip_unregistered: bool = False
) -> Expansion:
    """Validate a parsed spec and expand it into cases (see the module docstring).

    ``skip_unregistered``: a case table whose technique is not registered is skipped (and
    listed in :attr:`Expansion.skipped`) instead of being an error; the main job's built-in
    spec names techniques that may not be there in every version.
    """
    from ... import raster_models
    from ...raster_models import params as _params

    _check_keys("", data, _TOP_KEYS)
    name = data.get("name", "sweep")
    if not isinstance(name, str) or not name.strip():
        raise SpecError(f"name: expected a non-empty string, got {name!r}")
    defaults = data.get("defaults", {})
    _check_keys("defaults", defaults, _DEFAULT_KEYS)
    base = _settings("defaults", defaults, BUILTIN_DEFAULTS)
    tables = data.get("case")
    if not isinstance(tables, list) or not tables:
        raise SpecError("case: a spec needs at least one [[case]] table")
    cases: list[Case] = []
    skipped: list[str] = []
    kinds: dict = {}
    for i, table in enumerate(tables):
        where = f"case[{i}]"
        _check_keys(where, table, _CASE_KEYS)
        settings = _settings(where, table, base)
        technique = table.get("technique")
        if skip_unregistered and isinstance(technique, str):
            if technique not in raster_models.TECHNIQUES:
                skipped.append(f"{technique}: not a registered technique")
                continue
        if not isinstance(technique, str) or technique not in raster_models.TECHNIQUES:
            raise SpecError(
                f"{where}.technique: unknown technique {technique!r}; choose one of "
                f"{', '.join(raster_models.TECHNIQUES)}"
            )
        tech = raster_models.TECHNIQUES[technique]
        names = table.get("scenes")
        if isinstance(names, str):
            names = [names]
        if not isinstance(names, list) or not names:
            raise SpecError(f"{where}.scenes: expected a non-empty list of scene names")
        scene_list = [_scene_name(f"{where}.scenes[{j}]", s, base_dir) for j, s in enumerate(names)]
        camera_path, light_path, frames, n_frames = _frames(where, table)
        params = table.get("params", {})
        if not isinstance(params, dict):
            raise SpecError(f"{where}.params: expected a table of parameter values")
        fields = {p["name"]: p for p in _params.describe(tech.params)}
        axes = []
        for key, value in params.items():
            if key not in fields:
                raise SpecError(
                    f"{where}.params.{key}: unknown parameter of {technique}; valid "
                    f"parameters: {', '.join(fields)}"
                )
            axes.append(expand_values(f"{where}.params.{key}", value, kind=fields[key]["type"]))
        n_grid = math.prod(len(a) for a in axes) * len(scene_list) * len(frames)
        if len(cases) + n_grid > MAX_CASES:
            raise SpecError(f"{where}: the spec expands to more than {MAX_CASES} cases")
        grid = []
        for combo in itertools.product(*axes):
            values = dict(zip(params, combo, strict=True))
            try:
                _params.make(technique, tech.params, values)
            except raster_models.ModelError as exc:
                raise SpecError(f"{where}.params: {exc}") from None
            grid.append({k: list(v) if isinstance(v, tuple) else v for k, v in values.items()})
        for scene in scene_list:
            light = _scene_light(scene, settings["light"], kinds)
            kind = light.kind
            if light_path is not None:
                try:
                    check_light_path(light_path, light)
                except ValueError as exc:
                    skipped.append(f"{technique} on {Path(scene).name}: {exc}")
                    continue
            if kind not in tech.lights:
                skipped.append(
                    f"{technique} on {Path(scene).name}: needs a "
                    f"{' or '.join(tech.lights)} light, the scene's is {kind}"
                )
                continue
            for values in grid:
                for k in frames:
                    cases.append(
                        Case(
                            scene=scene,
                            technique=technique,
                            params=values,
                            width=settings["width"],
                            height=settings["height"],
                            spp=settings["spp"],
                            seed=settings["seed"],
                            light=settings["light"],
                            camera_path=camera_path,
                            light_path=light_path,
                            frame=k,
                            n_frames=n_frames,
                        )
                    )
    return Expansion(name=name.strip(), cases=cases, skipped=skipped)


#: Largest spec file read (a spec is a few kilobytes; this refuses /dev/zero and the like).
MAX_SPEC_BYTES = 1 << 20


def _read_spec(path: Path) -> str:
    """The text of a spec file: a regular file (not a FIFO or device, which could block or
    never end) of at most :data:`MAX_SPEC_BYTES`, in UTF-8."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise SpecError(f"spec {path}: no such file") from None
    except OSError as exc:
        raise SpecError(f"spec {path}: cannot read: {exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise SpecError(f"spec {path}: not a regular file")
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        raise SpecError(f"spec {path}: cannot read: {exc}") from None
    if len(data) > MAX_SPEC_BYTES:
        raise SpecError(f"spec {path}: larger than {MAX_SPEC_BYTES} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(f"spec {path}: cannot read: {exc}") from None


def load_spec(path: str | Path, *, skip_unregistered: bool = False) -> Expansion:
    """Read, validate and expand the TOML spec at ``path``.

    Raises
    ------
    SpecError
        The file is missing or not TOML, or a key is wrong (the message names it).
    """
    path = Path(path)
    text = _read_spec(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"spec {path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise SpecError(f"spec {path}: nested too deeply") from None
    return expand_spec(data, base_dir=path.parent, skip_unregistered=skip_unregistered)
