"""The Python API of raster-oracle: references, model runs and scores as function calls.

Every function takes keyword options (the command line's, in Python spelling) and wraps the
library functions the command line calls, so a script and ``raster-oracle score`` give the
same numbers for the same inputs and seed. Documented with examples in ``docs/python-api.md``
(the tests run those examples).

Errors: bad input (an unknown scene, a wrong candidate size, a bad option, a metric that does
not apply) raises :class:`InputError`; an unknown technique or a bad technique parameter
raises :class:`ModelError`. Both are ``ValueError`` subclasses with a one-line message; the
API never calls ``sys.exit``.

The backend (Mitsuba variant) is chosen on first use as the command line's ``--backend auto``
does; set the environment variable ``RASTER_ORACLE_BACKEND`` to force one.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .api_names import API_NAMES
from .oracle.errors import InputError
from .raster_models.errors import ModelError  # noqa: F401 (an API name: API_NAMES)
from .scenes.loader import LoadOptions, with_load_options

__all__ = list(API_NAMES)  # the one list of the API's names (raster_oracle.api_names)


@contextlib.contextmanager
def _library():
    """Run library code as the command line does: the backend selected, NumPy's
    RuntimeWarnings hidden, the other packages' input errors raised as :class:`InputError`
    (ModelError kept), and the scratch folders of uncached references removed at the end."""
    from .metrics import MetricError
    from .oracle.reference.cache import remove_scratch, scratch_mark
    from .scenes import SceneError, backend

    mark = scratch_mark()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            try:
                backend.active()
                yield
            except (SceneError, backend.BackendError, MetricError) as exc:
                raise InputError(str(exc)) from exc
    finally:
        remove_scratch(mark)


def _cache(cache):
    """``True``: the default cache folder; ``False``/``None``: no cache; else a folder."""
    from .oracle.reference.cache import ReferenceCache

    if cache is True:
        return ReferenceCache()
    if cache is None or cache is False:
        return None
    if isinstance(cache, ReferenceCache):
        return cache
    if isinstance(cache, str | os.PathLike):
        return ReferenceCache(cache)
    raise InputError(f"cache must be True, False, None or a folder, got {cache!r}")


@with_load_options
def load_scene(scene, **options):
    """Load a scene: a built-in name (``"plate"``), a Mitsuba XML file, a glTF 2.0 file
    (``.gltf``, ``.glb``), or an ``export`` folder (or its ``scene.xml``/``scene.glb``: the
    exported size and light, named after the folder), as the command line's ``SCENE`` is. A
    loaded scene is returned as it is.

    The options are those of ``raster_oracle.scenes.loader.LoadOptions``: ``width`` and
    ``height``; ``light`` picks a light (default 0, an export's own light); ``camera_path``,
    ``frame``, ``n_frames`` and ``light_path`` pick a frame of a camera or light path;
    ``camera_file`` a camera sequence file; ``camera`` a glTF file's camera.

    Returns a ``raster_oracle.scenes.LoadedScene`` (``.width``, ``.height``, ``.light``,
    ``.camera``, ``.name``); pass it to the other functions to load a scene once.
    """
    from . import scenes
    from .scenes.inputs import load_input

    try:
        opts = LoadOptions.of(options)
    except scenes.SceneError as exc:
        raise InputError(str(exc)) from None
    if isinstance(scene, scenes.LoadedScene):
        given = [k for k in opts.given() if k != "n_frames"]
        if given:
            many = len(given) > 1
            raise InputError(
                f"the option{'s' if many else ''} {', '.join(given)} appl{'y' if many else 'ies'}"
                " to a scene name or file; pass them to load_scene instead of a loaded scene"
            )
        return scene
    if not isinstance(scene, str | os.PathLike):
        raise InputError(f"scene must be a name, a file, a folder or a loaded scene: {scene!r}")
    with _library():
        return load_input(os.fspath(scene), **options)


@dataclass
class ReferenceImages:
    """A reference: its channels as float32 arrays and its provenance record.

    ``channels`` maps the EXR channel names (``visibility``, ``color.R``, ...; see
    ``docs/conventions.md``) to ``(H, W)`` arrays; ``meta`` is ``reference.json`` (scene,
    spp, seed, backend, versions, cache key). The properties give the common ones as images.
    """

    channels: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def _rgb(self, name: str) -> np.ndarray:
        return np.stack([self.channels[f"{name}.{c}"] for c in "RGB"], -1)

    @property
    def visibility(self) -> np.ndarray:
        """``(H, W)`` lit fraction of each pixel's samples, 1 = lit."""
        return self.channels["visibility"]

    @property
    def visibility_stderr(self) -> np.ndarray:
        """``(H, W)`` standard error of :attr:`visibility`."""
        return self.channels["visibility_stderr"]

    @property
    def coverage(self) -> np.ndarray:
        """``(H, W)`` fraction of each pixel's samples that hit geometry."""
        return self.channels["coverage"]

    @property
    def coverage_stderr(self) -> np.ndarray:
        """``(H, W)`` standard error of :attr:`coverage`."""
        return self.channels["coverage_stderr"]

    @property
    def color(self) -> np.ndarray:
        """``(H, W, 3)`` box-filtered linear radiance."""
        return self._rgb("color")

    @property
    def color_stderr(self) -> np.ndarray:
        """``(H, W, 3)`` standard error of :attr:`color`."""
        return self._rgb("color_stderr")


def reference(
    scene,
    *,
    width: int | None = None,
    height: int | None = None,
    spp: int = 64,
    seed: int = 0,
    channels: Sequence[str] | None = None,
    adaptive: bool = False,
    target_stderr: float = 0.01,
    max_spp: int = 4096,
    cache=True,
    quiet: bool = True,
) -> ReferenceImages:
    """Render (or fetch from the cache) the reference of ``scene``, as ``raster-oracle
    reference`` does.

    Parameters
    ----------
    scene : a name, XML file, export folder or loaded scene (see :func:`load_scene`).
    channels : channel groups (``visibility``, ``coverage``, ``coverage_exact``, ``color``,
        ``edge``, ``id``, ``depth``, ``position``, ``normal``, ``albedo``, and the opt-in
        ``tangent32``, ``motion`` and ``soft``: ``soft_visibility`` and ``light_fraction``
        under an area light); default: all but the opt-in ones.
    cache : True (the default cache folder), False (no cache) or a cache folder.
    """
    from .oracle.reference.render import ALL_CHANNELS, ReferenceSettings
    from .oracle.reference.store import get_reference

    if isinstance(channels, str):
        channels = [channels]
    settings = ReferenceSettings(
        spp=spp,
        seed=seed,
        channels=tuple(channels) if channels is not None else ALL_CHANNELS,
        adaptive=adaptive,
        target_stderr=target_stderr,
        max_spp=max_spp,
    )
    loaded = load_scene(scene, width=width, height=height)
    with _library():
        ref = get_reference(loaded, settings.validate(), cache=_cache(cache), quiet=quiet)
        return ReferenceImages(channels=ref.channels(), meta=dict(ref.meta))


def export(scene, out, *, width: int | None = None, height: int | None = None) -> dict:
    """Write ``scene`` for an engine to render (``raster-oracle export``): ``meshes/*.ply``,
    ``camera.json``, ``lights.json``, ``materials.json`` and a ``scene.xml`` that loads the
    export back (pass the folder to :func:`score_image`). Returns the export's summary."""
    from .scenes.formats.export import export as export_scene

    loaded = load_scene(scene, width=width, height=height)
    with _library():
        return export_scene(loaded, Path(out))


def techniques() -> list[dict]:
    """Every technique model with its description and parameters (name, default, source)."""
    from . import raster_models

    return raster_models.list_techniques()


def run_model(technique: str, scene, **params):
    """Run a technique model on ``scene`` (``raster-oracle model``) with its parameters as
    keywords (``run_model("shadow-map", scene, resolution=1024)``).

    Returns a ``ModelResult``: ``outputs`` (name -> float32 image: ``visibility`` for the
    shadow family, ``color`` ``(H, W, 3)`` and ``coverage`` for anti-aliasing), ``cost``,
    ``diagnostics``, ``params`` (every parameter with its value), ``wall_seconds``.
    Raises :class:`ModelError` for an unknown technique or parameter, or a bad value.
    """
    from . import raster_models

    loaded = load_scene(scene)
    with _library():
        return raster_models.run(technique, loaded, **params)


def _write_frames(images, channel: str | None, folder: Path) -> tuple[str, str]:
    """Engine-like EXR files of in-memory candidate frames; returns (pattern, channel)."""
    from .oracle.reference.exr import write_exr

    if channel not in (None, "visibility", "color", "coverage"):
        raise InputError(
            f"channel of an array candidate must be visibility, color or coverage, got {channel!r}"
        )
    folder.mkdir(parents=True, exist_ok=True)
    frames = []
    for k, image in enumerate(images):
        arr = np.asarray(image, dtype=np.float32)
        if arr.ndim == 3 and arr.shape[-1] == 1:
            arr = arr[..., 0]
        if arr.ndim == 2:
            kind = channel or "visibility"
            frames.append({kind if kind in ("visibility", "coverage") else "Y": arr})
        elif arr.ndim == 3 and arr.shape[-1] in (3, 4):
            kind = channel or "color"
            frames.append({c: np.ascontiguousarray(arr[..., i]) for i, c in enumerate("RGB")})
        else:
            raise InputError(
                f"candidate frame {k} must be (H, W) or (H, W, 3), got shape {arr.shape}"
            )
        write_exr(folder / f"frame_{k:03d}.exr", frames[-1])
    pattern = "frame_{frame:03d}.exr" if len(frames) > 1 else "frame_000.exr"
    return str(folder / pattern), kind


def _is_image(obj) -> bool:
    return isinstance(obj, np.ndarray) or (
        isinstance(obj, Sequence) and not isinstance(obj, str) and np.ndim(obj) >= 2
    )


def score_image(
    scene,
    candidate,
    *,
    channel: str | None = None,
    width: int | None = None,
    height: int | None = None,
    spp: int = 64,
    seed: int = 0,
    frames: int | None = None,
    camera_path: str | None = "dolly",
    flip_mode: str = "LDR",
    ppd: float | None = None,
    out=None,
    cache=True,
    quiet: bool = True,
    visibility: str = "1-is-lit",
    transfer: str | None = None,
    expect: str | None = None,
) -> dict:
    """Score an engine's image against the reference of ``scene`` (``raster-oracle score
    --candidate``); returns the ``metrics.json`` record as a dict.

    Parameters
    ----------
    scene : a name, XML file, export folder or loaded scene (see :func:`load_scene`).
    candidate : an array (``(H, W)`` visibility or coverage, ``(H, W, 3)`` linear colour),
        a list of arrays (one a frame, with ``frames``), or an EXR/PNG file name (a
        ``{frame}`` pattern with ``frames``), read exactly as the command line reads it.
    channel : what the candidate holds (``visibility``, ``color``, ``coverage``, or for a
        file an EXR channel or layer name); default: an array's shape decides (2-D:
        visibility, RGB: colour); a file's channels, as the command line decides.
    frames, camera_path : score that many frames of the camera path and add the temporal
        metrics (a list of arrays gives the frame count itself).
    out : a folder for the score folder (metrics.json, report.html, error maps); default: a
        temporary one, deleted.
    cache : True (the default cache folder), False (no cache) or a cache folder.
    visibility : what a shadow mask's 1 means, ``"1-is-lit"`` (the default) or
        ``"1-is-shadowed"`` (``--visibility``).
    transfer : how a PNG file's colour is made linear: ``"srgb"`` (default), ``"gamma2.2"``
        or ``"linear"`` (``--transfer``).
    expect : the technique the engine claims, ``"shadow-map:resolution=2048,filter=pcf"``
        (``--expect``): adds the ``conformance_*`` metrics.

    Gate the record with :func:`check`.
    """
    frame_list = None
    if isinstance(candidate, list | tuple) and candidate and _is_image(candidate[0]):
        frame_list = list(candidate)
        frames = frames or len(frame_list)
        if frames != len(frame_list):
            raise InputError(f"frames={frames} but {len(frame_list)} candidate frames given")
    elif _is_image(candidate):
        frame_list = [candidate]
    elif isinstance(candidate, str | os.PathLike):
        candidate = os.fspath(candidate)
    else:
        raise InputError(
            f"candidate must be an array, a list of arrays or a file name, got {candidate!r}"
        )
    return _score(
        scene,
        dict(candidate=candidate, channel=channel),
        frame_list=frame_list,
        load=dict(width=width, height=height),
        opts=dict(
            spp=spp,
            seed=seed,
            frames=frames,
            camera_path=camera_path,
            visibility=visibility,
            transfer=transfer,
            expect=expect,
        ),
        flip_mode=flip_mode,
        ppd=ppd,
        out=out,
        cache=cache,
        quiet=quiet,
    )


def score_technique(
    technique: str,
    scene,
    *,
    params: dict | None = None,
    channel: str | None = None,
    width: int | None = None,
    height: int | None = None,
    spp: int = 64,
    seed: int = 0,
    frames: int | None = None,
    camera_path: str | None = "dolly",
    flip_mode: str = "LDR",
    ppd: float | None = None,
    out=None,
    cache=True,
    quiet: bool = True,
) -> dict:
    """Score a technique model (``raster-oracle score --technique``) with ``params`` (a dict
    of parameter values); returns the ``metrics.json`` record, with ``cost`` and ``params``.
    Options as in :func:`score_image`."""
    return _score(
        scene,
        dict(technique=technique, params=dict(params or {}), channel=channel),
        frame_list=None,
        load=dict(width=width, height=height),
        opts=dict(spp=spp, seed=seed, frames=frames, camera_path=camera_path),
        flip_mode=flip_mode,
        ppd=ppd,
        out=out,
        cache=cache,
        quiet=quiet,
    )


def _score(scene, what, *, frame_list, load, opts, flip_mode, ppd, out, cache, quiet) -> dict:
    """Score into ``out`` (or a temporary folder) with the command line's own request and
    function: the record returned is the ``metrics.json`` the command line writes."""
    from . import metrics as M
    from .oracle.scoring.options import ScoreOptions
    from .oracle.scoring.request import ScoreRequest
    from .oracle.scoring.to_folder import score_to_folder
    from .scenes import CAMERA_PATHS

    loaded = load_scene(scene, **load)
    if opts["frames"] and opts["frames"] > 1 and opts["camera_path"] not in (None, *CAMERA_PATHS):
        raise InputError(
            f"unknown camera path {opts['camera_path']!r}; choose one of {', '.join(CAMERA_PATHS)}"
        )
    with contextlib.ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="raster-oracle-")))
        if frame_list is not None:
            what["candidate"], what["channel"] = _write_frames(
                frame_list, what["channel"], tmp / "candidate"
            )
        folder = Path(out) if out is not None else tmp / "score"
        with _library():
            options = ScoreOptions(
                **opts, quiet=quiet, flip_mode=flip_mode, ppd=ppd or M.DEFAULT_PPD
            )
            if "technique" in what:
                request = ScoreRequest.for_model(
                    loaded, **what, options=options, cache=_cache(cache)
                )
            else:
                request = ScoreRequest.for_files(
                    loaded,
                    what["candidate"],
                    channel=what["channel"],
                    options=options,
                    cache=_cache(cache),
                )
            return score_to_folder(request, out=folder)[1]


def score_folder(
    root,
    *,
    out,
    manifest=None,
    exports=None,
    channel: str | None = None,
    kind: str | None = None,
    camera_path: str | None = None,
    visibility: str | None = None,
    spp: int | None = None,
    seed: int | None = None,
    flip_mode: str | None = None,
    transfer: str | None = None,
    expect: str | None = None,
    fail_above: dict[str, float] | None = None,
    fail_below: dict[str, float] | None = None,
    profiles: Sequence[str] = (),
    baseline=None,
    baseline_metrics: Sequence[str] | str | None = None,
    baseline_tolerance: dict | None = None,
    baseline_strict: bool = False,
    platform: str | None = None,
    cache=True,
    quiet: bool = True,
) -> dict:
    """Score a folder of engine images as ``raster-oracle score-folder ROOT`` does (the same
    library function, :func:`oracle.scoring.inputs.folder_cases.run_folder`): ``ROOT``'s layout, or
    the CI manifest ``manifest``; every case into ``out/<case>/``, the combined record into
    ``out/metrics.json`` and ``out/report.html``.

    Options are the command line's (``None``: the manifest's, else the default).
    ``fail_above`` / ``fail_below``: ``{metric: limit}``; ``profiles``: gate profiles;
    ``baseline``: a previous folder run's ``metrics.json``, its folder or a baseline folder;
    ``baseline_metrics``: the metrics it compares (a list, ``"all"``; None: the gated ones);
    ``baseline_tolerance``: ``{metric: 0.01 or "5%"}``; ``baseline_strict``: a case missing
    or new fails.

    Returns the combined record (``scenes``: case -> its ``metrics.json`` record,
    ``failed``, ``errors``, ``baseline``, ``exit_code``); bad input raises
    :class:`InputError` before anything is scored.
    """
    from .oracle.scoring.ci.checks import GateError
    from .oracle.scoring.ci.gates import limit_texts, parse_gates
    from .oracle.scoring.ci.profiles import profile_gates
    from .oracle.scoring.ci.regression import (
        BaselineOptions,
        parse_baseline_metrics,
        parse_tolerance,
    )
    from .oracle.scoring.inputs.folder_cases import run_folder
    from .scenes.base.records import jsonable

    gates = profile_gates(profiles, error=GateError)
    gates += parse_gates(limit_texts(fail_above, "<="), limit_texts(fail_below, ">="))
    gates = list({(g.metric, g.op): g for g in gates}.values())
    keys = [baseline_metrics] if isinstance(baseline_metrics, str) else baseline_metrics
    tolerances = dict(parse_tolerance(f"{k}={v}") for k, v in (baseline_tolerance or {}).items())
    bo = BaselineOptions(parse_baseline_metrics(keys), tolerances, bool(baseline_strict))
    options = dict(
        spp=spp,
        seed=seed,
        flip_mode=flip_mode,
        transfer=transfer,
        expect=expect,
        channel=channel,
        kind=kind,
        camera_path=camera_path,
        visibility=visibility,
        exports=None if exports is None else Path(exports),
        quiet=quiet,
        platform=platform,
    )
    with _library():
        _, run = run_folder(
            Path(root),
            out=Path(out),
            manifest=manifest,
            options=options,
            gates=gates,
            baseline=baseline,
            baseline_options=bo,
            cache=_cache(cache),
            log=None,
        )
    return jsonable(run.record)


def check(
    record: dict,
    *,
    fail_above: dict[str, float] | None = None,
    fail_below: dict[str, float] | None = None,
    baseline=None,
):
    """Judge a ``metrics.json`` record as ``score`` does with ``--fail-above``,
    ``--fail-below`` and ``--baseline`` (the same library function).

    Parameters
    ----------
    fail_above : ``{metric: limit}``: fails when a lower-is-better metric is above it.
    fail_below : ``{metric: limit}``: fails when a higher-is-better metric (``ssim``,
        ``psnr_db``) is below it.
    baseline : a previous run's record (a dict) or the path of its ``metrics.json``: fails
        where a metric is worse by more than both runs' noise floors.

    Returns the verdict: ``exit_code`` (0 every check passed, 1 otherwise), ``failed`` (the
    names of the failed checks; the verdict itself is that list), ``lines`` (``FAIL
    visibility_mae 0.0719 > 0.02 (noise floor 0.0011)``, ``PASS ...``, ``REGRESSION ...``)
    and ``checks``; :func:`write_junit` writes verdicts as JUnit XML. A gate that cannot be
    judged (an unknown metric, one against its direction such as ``fail_above={"ssim":
    0.9}``, one that does not apply to the record's channel or frame count, a null value) or
    a baseline of another run raises :class:`InputError`, never a silent pass.
    """
    from .oracle.scoring.ci.gates import judge

    with _library():
        return judge(record, fail_above=fail_above, fail_below=fail_below, baseline=baseline)


def write_junit(path, verdicts) -> None:
    """Write JUnit XML of :func:`check` verdicts (one, or a list of them) to ``path``
    atomically: one test case per scene x check, as ``score --junit`` does."""
    from .oracle.scoring.ci.junit import write_junit as write

    verdicts = [verdicts] if hasattr(verdicts, "checks") else list(verdicts)
    write(Path(path), verdicts)
