"""The cases of a folder run, built in the library: from a folder's layout
(:func:`oracle.scoring.inputs.folder_layout.discover`) or a CI manifest
(:mod:`oracle.scoring.inputs.manifest`).

Each case's scene is loaded, its candidate layout resolved once (frame 0's file, its size
checked against the scene's) and its options fixed; the command line (``score-folder``) and
the Python API (``raster_oracle.score_folder``) both call :func:`folder_cases`, so they
score the same cases into the same records.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from .... import metrics as M
from ..ci.regression import BaselineOptions
from ..folder import FolderCase
from ..options import ScoreOptions
from ..result import ScoreError
from .candidates import CandidateError, MissingChannelError
from .folder_layout import discover

__all__ = [
    "FolderOptions",
    "folder_cases",
    "resolve_layout",
    "run_folder",
]


def _candidate_size(path: Path):
    from .layout import candidate_format

    try:
        return candidate_format(path).size(path)
    except Exception:  # unreadable: the candidate reader says why, in one line
        return None


def resolve_layout(pattern: str, *, channel, kind, loaded, log=print, folder: bool = False):
    """The layout of a candidate file or ``{frame}`` pattern (frame 0's file) with
    ``channel`` / ``kind``, logged as one line, after checking its size against
    ``loaded``'s (a :class:`ScoreError` naming the export or, for ``score``, the size to
    pass; ``folder``: a score-folder case, which takes no --width/--height)."""
    from ....scenes.inputs import nearest_export
    from .frames import frame_file
    from .layout import candidate_layout

    first = Path(frame_file(pattern, 0))
    layout = candidate_layout(first, channel=channel, kind=kind)
    size = _candidate_size(first)
    if size is not None and size != (loaded.width, loaded.height):
        w, h = size
        found = nearest_export(first, size)
        export = (
            f"score the export folder {found} that wrote it"
            if found
            else "score the export folder that wrote it (`score EXPORT_DIR`)"
        )
        # score-folder takes no --width/--height: its scenes come at their export's size
        fix = export if folder else f"pass --width {w} --height {h}, or {export}"
        raise ScoreError(
            f"candidate is {w}x{h}, the reference is {loaded.width}x{loaded.height} "
            f"({first.name}): {fix}"
        )
    if log is not None:
        log(layout.message(first.name), flush=True)
    return layout


class FolderOptions(dict):
    """Options of a folder run given by the caller (command line or API), each None where
    the manifest (or the default) decides: ``spp``, ``seed``, ``flip_mode``, ``transfer``,
    ``expect``, ``channel``, ``kind``, ``camera_path``, ``visibility``, ``exports``;
    ``quiet``, ``platform`` and ``exact_budget``."""

    def pick(self, key, manifest_value=None, default=None):
        given = self.get(key)
        if given is not None:
            return given
        return manifest_value if manifest_value is not None else default


def _score_options(fo: FolderOptions, manifest=None, **case) -> ScoreOptions:
    return ScoreOptions(
        spp=fo.pick("spp", getattr(manifest, "spp", None), 64),
        seed=fo.pick("seed", getattr(manifest, "seed", None), 0),
        flip_mode=fo.pick("flip_mode", getattr(manifest, "flip_mode", None), "LDR"),
        ppd=M.DEFAULT_PPD,
        quiet=bool(fo.get("quiet", True)),
        platform=fo.get("platform"),
        exact_budget=fo.get("exact_budget"),
        **case,
    ).validate()


def _discovered(root: Path, fo: FolderOptions, gates, log) -> list[FolderCase]:
    """The cases of ``root``'s layout (every one checked: a problem is a
    :class:`ScoreError`, except a file that lacks the channel asked for: that scene's own
    error, the others scored)."""
    from ....scenes.inputs import load_input, named_input

    entries = discover(root)
    if {e.name for e in entries} & {"metrics.json", "report.html", "report.json"}:
        raise ScoreError("score-folder: a scene may not be named metrics or report")
    channel, kind = fo.get("channel"), fo.get("kind")
    cases = []
    for entry in entries:
        scene = named_input(entry.name, exports=fo.get("exports"))
        loaded = load_input(scene, n_frames=entry.frames or 8)
        error = layout = None
        try:
            layout = resolve_layout(
                entry.pattern, channel=channel, kind=kind, loaded=loaded, log=log, folder=True
            )
        except MissingChannelError as exc:
            if channel is None:
                raise
            if log is not None:
                log(f"{entry.name}: error: {exc}")
            error = str(exc)
        camera_path = fo.get("camera_path") or loaded.camera_path
        if entry.frames and camera_path is None:
            raise ScoreError(
                f"score-folder: {entry.name} holds {entry.frames} frames: give the camera path "
                "they were rendered along (--camera-path, or a manifest's camera_path)"
            )
        options = _score_options(
            fo,
            frames=entry.frames,
            camera_path=camera_path,
            visibility=fo.get("visibility") or "1-is-lit",
            transfer=fo.get("transfer"),
            expect=fo.get("expect"),
            family=fo.get("family"),
        )
        case = FolderCase(entry.name, entry.name, loaded, entry.pattern, channel, layout, options)
        cases.append(replace(case, gates=tuple(gates), error=error))
    return cases


def _manifest(root: Path, path, fo: FolderOptions, gates, log) -> list[FolderCase]:
    """The cases of a manifest: a bad manifest, scene or option is a :class:`ScoreError`; a
    missing file or layer is that case's own error."""
    from ....scenes.inputs import load_input
    from .frames import frame_file
    from .manifest import read_manifest

    if fo.get("channel") is not None or fo.get("kind") is not None:
        raise ScoreError("--channel and --kind are given per scene in --manifest")
    if not root.is_dir():
        raise ScoreError(f"score-folder: {root} is not a folder")
    manifest = read_manifest(path)
    cases, scenes = [], {}
    for mc in manifest.cases:
        if mc.scene_key not in scenes:
            scenes[mc.scene_key] = load_input(mc.scene, n_frames=mc.frames or 8)
        loaded = scenes[mc.scene_key]
        pattern = str(root / mc.file)
        camera_path = mc.camera_path or loaded.camera_path
        if mc.frames and camera_path is None:
            raise ScoreError(
                f"--manifest {path}: scene {mc.scene_key} has frames = {mc.frames} "
                "but no camera_path (nor an export made with one)"
            )
        options = _score_options(
            fo,
            manifest,
            frames=mc.frames,
            camera_path=camera_path,
            visibility=mc.visibility,
            transfer=fo.pick("transfer", mc.transfer),
            expect=fo.pick("expect", mc.expect),
            family=fo.pick("family", mc.family),
        )
        case = FolderCase(mc.name, mc.scene_key, loaded, pattern, mc.channel, None, options)
        case = replace(case, gates=tuple(gates) + mc.gates, baseline=mc.baseline)
        try:
            if not Path(frame_file(pattern, 0)).is_file():
                raise CandidateError(f"candidate file not found: {frame_file(pattern, 0)}")
            layout = resolve_layout(
                pattern, channel=mc.channel, kind=mc.kind, loaded=loaded, log=log, folder=True
            )
            case = replace(case, layout=layout)
        except CandidateError as exc:
            if log is not None:
                log(f"{mc.name}: error: {exc}")
            case = replace(case, error=str(exc))
        cases.append(case)
    return cases


def folder_cases(
    root,
    *,
    manifest=None,
    options: FolderOptions | dict | None = None,
    gates=(),
    log=print,
) -> list[FolderCase]:
    """The checked cases of a folder run: ``root``'s layout, or the manifest ``manifest``
    (files relative to ``root``). ``options``: :class:`FolderOptions` (a plain dict is
    taken as one); ``gates``: every case's gates (a manifest adds its own); ``log``: where
    the layout lines go (None: nowhere)."""
    fo = FolderOptions(options or {})
    root = Path(root)
    if manifest is not None:
        return _manifest(root, manifest, fo, gates, log)
    return _discovered(root, fo, gates, log)


def run_folder(
    root,
    *,
    out,
    manifest=None,
    options: FolderOptions | dict | None = None,
    gates=(),
    baseline=None,
    baseline_options: BaselineOptions | None = None,
    cache=None,
    log=print,
    title: str | None = None,
):
    """Build the cases (:func:`folder_cases`), check them against the ``baseline`` (a
    previous folder run's ``metrics.json``, its folder, or a baseline folder of ``baseline
    accept``: the platform's) before anything is rendered, and score them
    (:func:`oracle.scoring.folder.score_folder`); returns ``(cases, run)``."""
    from ..ci.baseline import check_platform, resolve_baseline
    from ..ci.regression import check_baseline_scene, load_folder_baseline
    from ..folder import score_folder

    fo = FolderOptions(options or {})
    platform = check_platform(fo.get("platform"))
    baselines = None
    if baseline is not None:
        baselines = load_folder_baseline(resolve_baseline(baseline, platform=platform))
    cases = folder_cases(root, manifest=manifest, options=fo, gates=gates, log=log)
    for case in cases:  # everything checked before the first reference is rendered
        if case.error is None and baselines is not None and case.name in baselines:
            check_baseline_scene(
                baselines[case.name],
                case.loaded,
                frames=case.options.frames or 1,
                kinds=(case.layout.kind,),
                source=f"{baseline} scene {case.name}",
                platform=platform,
            )
    run = score_folder(
        cases,
        out=out,
        cache=cache,
        baselines=baselines,
        baseline_source=str(baseline),
        baseline_options=baseline_options,
        root=str(root),
        title=title or f"{Path(root).name}: engine images",
    )
    return cases, run
