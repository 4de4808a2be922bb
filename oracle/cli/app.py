"""``raster-oracle``: the command line, a thin layer over the library.

Every command returns an exit code: 0 success, 1 a ``--fail-above`` threshold exceeded,
2 bad input (one line on stderr, nothing written to the output folder).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

__all__ = ["main"]


class CliError(ValueError):
    """Bad command-line input."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (raised, not printed with the usage)."""

    def error(self, message):
        where = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        raise CliError(f"{where}{message}")


def _number(kind: type, *, minimum: float, strict: bool):
    """An argparse type: ``kind`` parsed from text, bounded below by ``minimum``."""
    noun = "an integer" if kind is int else "a number"
    relation = ">" if strict else ">="

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if not (value > minimum if strict else value >= minimum):
            raise argparse.ArgumentTypeError(f"must be {relation} {minimum:g}, got {value}")
        return value

    return parse


_positive_int = _number(int, minimum=0, strict=True)
_nonneg_int = _number(int, minimum=0, strict=False)
_positive_float = _number(float, minimum=0.0, strict=True)

#: Largest ``--spp`` / ``--max-spp``: 2^20 samples per pixel (a 1-pixel reference then takes
#: seconds; beyond it the standard error, 0.0005 at worst, stops mattering).
MAX_SPP = 2**20


def _spp(text: str) -> int:
    """An argparse type: samples per pixel, an integer in [1, MAX_SPP]."""
    value = _positive_int(text)
    if value > MAX_SPP:
        raise argparse.ArgumentTypeError(f"must be <= {MAX_SPP} (2^20), got {value}")
    return value


def _path(text: str) -> Path:
    """An argparse type: a non-empty path without control characters."""
    if not text:
        raise argparse.ArgumentTypeError("expected a path, got ''")
    if any(ord(c) < 32 for c in text):
        raise argparse.ArgumentTypeError(f"path contains control characters: {text!r}")
    return Path(text)


def _add_scene_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", metavar="SCENE", help="built-in scene name or Mitsuba XML file")
    p.add_argument("--light", type=_nonneg_int, default=0, help="index of the light (default 0)")
    p.add_argument("--width", type=_positive_int, help="film width in pixels")
    p.add_argument("--height", type=_positive_int, help="film height in pixels")
    p.add_argument(
        "--camera-path",
        choices=None,
        default=None,
        help="camera path for temporal work: subpixel-pan, subtexel-pan, rotate, dolly",
    )
    p.add_argument(
        "--light-path",
        default=None,
        help="light path for moving-light work: orbit-sun (directional), moving-point "
        "(point/spot); --frame K picks its frame",
    )
    p.add_argument(
        "--frame", type=_nonneg_int, default=0, help="frame of the camera and/or light path"
    )
    p.add_argument(
        "--frames",
        type=_positive_int,
        default=None,
        help="frames in the camera path (default 8); for `score`: score that many frames of "
        "the path (default dolly) and add the temporal metrics",
    )


def _add_set_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--set",
        dest="params",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="technique parameter (repeatable)",
    )


def _add_reference_args(p: argparse.ArgumentParser, *, default_spp: int = 64) -> None:
    p.add_argument(
        "--spp",
        type=_spp,
        default=default_spp,
        help=f"sub-pixel samples per pixel (default {default_spp})",
    )
    p.add_argument("--seed", type=_nonneg_int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--adaptive",
        action="store_true",
        help="adaptive sampling: more samples only where pixels are not uniform",
    )
    p.add_argument(
        "--target-stderr",
        type=_positive_float,
        default=0.01,
        help="adaptive: target standard error (default 0.01)",
    )
    p.add_argument(
        "--max-spp",
        type=_spp,
        default=4096,
        help="adaptive: most samples a pixel gets (default 4096)",
    )
    p.add_argument(
        "--cache-dir",
        type=_path,
        default=None,
        help="reference cache (default ~/.cache/raster-oracle)",
    )
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="raster-oracle",
        description="Ground truth for real-time shadows and anti-aliasing.",
    )
    parser.add_argument(
        "--backend",
        default=None,
        help="Mitsuba variant: auto, cuda_ad_rgb, llvm_ad_rgb or scalar_rgb "
        "(default: $RASTER_ORACLE_BACKEND or auto)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    sub.add_parser("doctor", help="print the backend, libLLVM, versions and cores")
    sub.add_parser("scenes", help="list the built-in scenes and camera paths")

    p = sub.add_parser("reference", help="render (or fetch from the cache) a reference")
    _add_scene_args(p)
    _add_reference_args(p)
    p.add_argument(
        "--channels",
        default=None,
        help="comma-separated channel groups (default: all): visibility, coverage, "
        "color, edge, id, depth, position, normal, albedo",
    )
    p.add_argument("--out", type=_path, default=Path("out/reference"), help="output folder")

    p = sub.add_parser("export", help="write meshes (PLY), camera.json and lights.json")
    _add_scene_args(p)
    p.add_argument("--out", type=_path, required=True, help="output folder")

    sub.add_parser("techniques", help="list the technique models with their parameters")

    p = sub.add_parser("model", help="run a technique model: output.exr + model.json")
    p.add_argument("technique", metavar="TECHNIQUE")
    _add_scene_args(p)
    _add_set_arg(p)
    p.add_argument("--out", type=_path, default=Path("out/model"), help="output folder")

    p = sub.add_parser("score", help="score a model or an engine image against the reference")
    _add_scene_args(p)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--technique", help="a technique model (see `techniques`)")
    what.add_argument(
        "--candidate",
        help="an EXR or PNG from your engine; with --frames use "
        "a pattern such as frame_{frame:03d}.exr",
    )
    _add_set_arg(p)
    p.add_argument(
        "--channel",
        choices=["visibility", "color", "coverage"],
        default=None,
        help="what the candidate holds (default: color; visibility for shadow models, "
        "color and coverage for anti-aliasing models)",
    )
    p.add_argument("--spp", type=_spp, default=64, help="reference spp (default 64)")
    p.add_argument("--seed", type=_nonneg_int, default=0, help="reference seed (default 0)")
    p.add_argument("--flip-mode", choices=["LDR", "HDR", "ldr", "hdr"], default="LDR")
    p.add_argument(
        "--ppd", type=_positive_float, default=None, help="FLIP pixels per degree (default 67.02)"
    )
    p.add_argument(
        "--fail-above",
        action="append",
        default=[],
        metavar="METRIC=VALUE",
        help="exit 1 when METRIC exceeds VALUE (repeatable)",
    )
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--no-cache", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--out", type=_path, default=Path("out/score"), help="output folder")

    p = sub.add_parser("report", help="combine score folders (or a sweep) into one HTML report")
    p.add_argument("folders", nargs="*", type=Path, metavar="DIR")
    p.add_argument("--out", type=_path, required=True, help="the report.html to write")
    p.add_argument("--title", default="raster-oracle report")
    from .sweeps import add_parsers, report_sweep_args

    report_sweep_args(p)
    add_parsers(sub)

    p = sub.add_parser("main", help="the main job: the default sweep, claims, extremes, report")
    p.add_argument("--out", type=_path, default=Path("out"), help="output folder")
    p.add_argument("--spp", type=_spp, default=None, help="reference spp (default: the spec's 64)")
    p.add_argument("--scenes", default=None, help="comma-separated scenes (default: all)")
    p.add_argument(
        "--workers",
        type=_nonneg_int,
        default=None,
        help="Dask workers (default: one per core; 0: run in this process)",
    )
    p.add_argument("--width", type=_positive_int, default=None, help="film width (default 640)")
    p.add_argument("--height", type=_positive_int, default=None, help="film height (default 360)")
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--quiet", action="store_true")

    p = sub.add_parser("bench", help="benchmarks that print JSON figures")
    p.add_argument("what", choices=["oracle", "models"], help="what to benchmark")
    p.add_argument("--width", type=_positive_int, default=1920)
    p.add_argument("--height", type=_positive_int, default=1080)
    p.add_argument("--spp", type=_positive_int, default=32)
    p.add_argument(
        "--only",
        default="",
        help="models: comma-separated techniques to time (default: every row)",
    )
    p.add_argument("--quiet", action="store_true")

    p = sub.add_parser(
        "aa-memory", help="AA framebuffer memory (models' accounting) vs the quoted figures"
    )
    p.add_argument("--out", type=_path, default=Path("out/aa-memory"), help="output folder")

    p = sub.add_parser("converge", help="oracle true error against spp (and adaptive)")
    p.add_argument("scene", metavar="SCENE", help="built-in scene name or Mitsuba XML file")
    p.add_argument("--width", type=_positive_int, help="film width in pixels")
    p.add_argument("--height", type=_positive_int, help="film height in pixels")
    p.add_argument("--max-spp", type=_spp, default=4096, help="largest spp (default 4096)")
    p.add_argument("--truth-spp", type=_spp, default=None, help="truth spp (default 4x max)")
    p.add_argument(
        "--target",
        type=_positive_float,
        action="append",
        default=None,
        help="true RMS visibility error to find the spp for (repeatable; default 0.01)",
    )
    p.add_argument("--seed", type=_nonneg_int, default=0)
    p.add_argument("--no-adaptive", action="store_true", help="skip the adaptive rendering")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--out", type=_path, default=Path("out/converge"), help="output folder")

    p = sub.add_parser("extremes", help="every model x every numerical extreme vs the oracle")
    p.add_argument("--quick", action="store_true", help="the main job's size (64x36, 4096^2)")
    p.add_argument("--huge", type=_positive_int, default=None, help="huge map size (default 16384)")
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--no-cache", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--out", type=_path, default=Path("out/extremes"), help="output folder")

    p = sub.add_parser("claims", help="measure the seed documents' headline claims")
    p.add_argument("--quick", action="store_true", help="the main job's size (160x90, 16 spp)")
    p.add_argument("--only", default=None, help="comma-separated claim ids (default: all)")
    p.add_argument("--cache-dir", type=_path, default=None)
    p.add_argument("--no-cache", action="store_true")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--out", type=_path, default=Path("out/claims"), help="output folder")
    return parser


def _load_scene(args):
    import scenes

    light_path = getattr(args, "light_path", None)
    if (
        args.frame
        and args.camera_path is None
        and light_path is None
        and not getattr(args, "frames", None)
    ):
        raise CliError(
            f"--frame {args.frame} needs --camera-path or --light-path (frame 0 is the "
            "scene's own camera and light)"
        )

    return scenes.load(
        args.scene,
        width=args.width,
        height=args.height,
        light=args.light,
        camera_path=args.camera_path,
        frame=args.frame,
        n_frames=args.frames or 8,
        light_path=light_path,
    )


def _settings(args, channels=None):
    from ..reference.render import ALL_CHANNELS, ReferenceSettings

    if channels is None:
        channels = ALL_CHANNELS
    return ReferenceSettings(
        spp=args.spp,
        seed=args.seed,
        channels=tuple(channels),
        adaptive=args.adaptive,
        target_stderr=args.target_stderr,
        max_spp=args.max_spp,
    ).validate()


def _cache(args):
    from ..reference.cache import ReferenceCache, default_cache_dir

    if getattr(args, "no_cache", False):
        return None
    root = args.cache_dir if args.cache_dir is not None else default_cache_dir()
    _check_dir(root, label="--cache-dir" if args.cache_dir is not None else "cache folder")
    return ReferenceCache(root)


def _check_dir(path: Path, *, label: str) -> None:
    """``path`` is a writable folder, or can be created: its nearest existing ancestor is one."""
    text = os.fspath(path)
    if not text:
        raise CliError(f"{label}: expected a path, got ''")
    if os.path.exists(text) or os.path.islink(text):
        if not os.path.isdir(text):
            raise CliError(f"{label} {path} exists and is not a folder")
        if not os.access(text, os.W_OK | os.X_OK):
            raise CliError(f"{label} {path} is not writable")
        return
    parent = os.path.dirname(os.path.abspath(text))
    while not os.path.exists(parent):
        if os.path.islink(parent):  # a dangling link: nothing can be created under it
            raise CliError(f"{label} {path}: {parent} is a broken link")
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise CliError(f"{label} {path}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise CliError(f"{label} {path}: {parent} is not writable")


def _check_out(out: Path) -> None:
    _check_dir(out, label="--out")


def cmd_doctor(args) -> int:
    from scenes import backend

    from ..reference.store import package_versions

    info = {"cores": os.cpu_count(), "versions": package_versions()}
    try:
        b = backend.select(args.backend)
        info.update(variant=b.variant, libllvm=b.libllvm, reason=b.reason)
    except backend.BackendError as exc:
        info.update(variant=None, error=str(exc))
    info["libllvm_found"] = backend.find_libllvm()
    info["cuda_device"] = backend.cuda_works()
    print(json.dumps(info, indent=2))
    if not (info["libllvm_found"] or info["cuda_device"]):
        print(
            "raster-oracle: no vectorized backend works (no CUDA device, no libLLVM >= 16); "
            f"install one with: {backend.INSTALL_HINT}",
            file=sys.stderr,
        )
        return 2
    return 0


def cmd_scenes(args) -> int:
    from scenes import BUILTIN_SCENES, CAMERA_PATHS

    width = max(len(n) for n in BUILTIN_SCENES)
    for name, spec in BUILTIN_SCENES.items():
        print(f"{name:<{width}}  {spec.width}x{spec.height}  {spec.description}")
    print("\ncamera paths (--camera-path NAME --frame K --frames N):")
    for name, text in CAMERA_PATHS.items():
        print(f"  {name:<13} {text}")
    from scenes.light_paths import LIGHT_PATHS

    print("\nlight paths (--light-path NAME --frame K --frames N):")
    for name, text in LIGHT_PATHS.items():
        print(f"  {name:<13} {text}")
    return 0


def cmd_reference(args) -> int:
    from ..reference.store import get_reference, publish

    groups = None
    if args.channels is not None:
        groups = [c.strip() for c in args.channels.split(",") if c.strip()]
    settings = _settings(args, groups)
    _check_out(args.out)
    loaded = _load_scene(args)
    ref = get_reference(loaded, settings, cache=_cache(args), quiet=args.quiet)
    if ref.cache_status == "corrupted":
        print("raster-oracle: warning: corrupted cache entry replaced", file=sys.stderr)
    publish(ref, args.out)
    print(f"reference ({ref.cache_status}): {args.out / 'reference.exr'}")
    return 0


def cmd_export(args) -> int:
    from scenes.export import export

    _check_out(args.out)
    loaded = _load_scene(args)
    summary = export(loaded, args.out)
    tris = sum(s["triangles"] for s in summary["shapes"].values())
    print(f"exported {len(summary['shapes'])} shapes ({tris} triangles) to {args.out}")
    return 0


def cmd_main(args) -> int:
    import scenes

    from ..sweeps.mainjob import run_main

    names = None
    if args.scenes:
        names = tuple(n.strip() for n in args.scenes.split(",") if n.strip())
        unknown = [n for n in names if n not in scenes.BUILTIN_SCENES]
        if unknown:
            raise CliError(
                f"unknown scene(s) {', '.join(unknown)}; choose from "
                f"{', '.join(scenes.BUILTIN_SCENES)}"
            )
    if (args.width is None) != (args.height is None):
        raise CliError("main: give both --width and --height, or neither")
    _check_out(args.out)
    report, failed = run_main(
        names,
        args.out,
        spp=args.spp,
        cache=_cache(args),
        quiet=args.quiet,
        workers=args.workers,
        size=(args.width, args.height) if args.width else None,
    )
    print(f"report: {report.resolve()}")
    if failed:
        print(f"raster-oracle: main job: failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def cmd_bench(args) -> int:
    from ..studies.bench import bench_models, bench_oracle

    kwargs = dict(width=args.width, height=args.height, spp=args.spp, quiet=args.quiet)
    if args.what == "models":
        only = tuple(t.strip() for t in args.only.split(",") if t.strip())
        try:
            figures = bench_models(only=only, **kwargs)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    elif args.only:
        raise CliError("bench oracle: --only applies to 'bench models' only")
    else:
        figures = bench_oracle(**kwargs)
    print(json.dumps(figures, indent=2))
    return 0


def cmd_techniques(args) -> int:
    import raster_models

    for tech in raster_models.list_techniques():
        print(f"{tech['name']}: {tech['description']}")
        for prm in tech["params"]:
            choices = f" {{{', '.join(map(str, prm['choices']))}}}" if prm.get("choices") else ""
            print(f"  {prm['name']} = {prm['default']!r}{choices}  [{prm['source']}]")
        print()
    return 0


def cmd_model(args) -> int:
    from ..scoring.models import run_model_to_folder

    _check_out(args.out)
    loaded = _load_scene(args)
    run_model_to_folder(args.technique, loaded, args.params, args.out)
    print(f"model {args.technique}: {args.out / 'output.exr'}")
    return 0


def _check_frame_pattern(pattern: str | None) -> None:
    """A ``--candidate`` pattern with a ``{frame}`` field is a ``str.format`` pattern: it may
    hold ``{frame}`` fields only, with an integer format (a name without one is literal)."""
    import re

    if pattern is None or not re.search(r"\{frame(?::[^}]*)?\}", pattern):
        return
    try:
        for k in (0, 1):
            pattern.format(frame=k)
    except (KeyError, IndexError, ValueError, AttributeError) as exc:
        raise CliError(
            f"--candidate pattern {pattern!r} is not valid ({type(exc).__name__}: {exc}); "
            "use {frame} or e.g. {frame:03d} (write a literal brace as {{ or }})"
        ) from None


def cmd_score(args) -> int:
    from ..scoring.score import parse_thresholds
    from .score import score_command

    parse_thresholds(args.fail_above)
    _check_frame_pattern(args.candidate)
    _check_out(args.out)
    failed = score_command(args, _load_scene(args), _cache(args))
    print(f"score: {args.out / 'metrics.json'} and {args.out / 'report.html'}")
    if failed:
        print(f"raster-oracle: above threshold: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def cmd_report(args) -> int:
    from .score import combine_reports

    if not args.title.strip():
        raise CliError("--title must not be empty")
    if (args.sweep is None) == (not args.folders):
        raise CliError("report: give score folders or --sweep DB (one of them)")
    out = args.out
    if out.suffix.lower() == ".json":
        raise CliError(f"--out must name the HTML file (its JSON goes beside it), got {out}")
    if out.is_dir():
        raise CliError(f"--out {out} is a folder; give the report file to write")
    _check_dir(out.parent, label=f"--out {out}: folder")
    if args.sweep is not None:
        from .sweeps import sweep_report

        title = None if args.title == "raster-oracle report" else args.title
        sweep_report(args.sweep, out, title=title, costs=args.cost, metrics=args.metric)
        print(f"sweep report: {out}")
        return 0
    try:
        n = combine_reports(args.folders, out, title=args.title)
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        # Score folders are user data: a wrong schema, missing keys or unsafe links.
        if isinstance(exc, _known_errors()):
            raise
        detail = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc)
        raise CliError(f"report: bad score folder data: {detail}") from None
    print(f"report of {n} case(s): {args.out}")
    return 0


def cmd_converge(args) -> int:
    from ..studies.converge import run_converge

    if args.truth_spp is not None and args.truth_spp <= args.max_spp:
        raise CliError(f"--truth-spp ({args.truth_spp}) must be larger than --max-spp")
    _check_out(args.out)
    data = run_converge(
        args.scene,
        out=args.out,
        max_spp=args.max_spp,
        truth_spp=args.truth_spp,
        targets=tuple(args.target or (0.01,)),
        adaptive=not args.no_adaptive,
        width=args.width,
        height=args.height,
        seed=args.seed,
        quiet=args.quiet,
        echo=None if args.quiet else print,
    )
    for t in data["targets"]:
        print(f"target RMS {t['target_rms']:g}: {t['spp_measured']} spp (fit {t['spp_fitted']})")
    print(f"converge: {args.out / 'converge.json'} and {args.out / 'converge.html'}")
    return 0


def cmd_extremes(args) -> int:
    from ..studies.extremes.run import run_extremes

    if args.huge is not None and not 8 <= args.huge <= 16384:
        raise CliError(f"--huge must be in [8, 16384], got {args.huge}")
    _check_out(args.out)
    data = run_extremes(
        args.out,
        cache=_cache(args),
        quiet=args.quiet,
        echo=None if args.quiet else print,
        quick=args.quick,
        huge=args.huge,
    )
    cells = data["cells"]
    print(
        f"extremes: {len(cells)} cells, {len(data['unexpected'])} not as documented"
        + (f" ({', '.join(data['unexpected'])})" if data["unexpected"] else "")
    )
    print(f"extremes: {args.out / 'extremes.json'} and {args.out / 'extremes.html'}")
    return 0


def cmd_claims(args) -> int:
    from ..studies.claims.run import CLAIMS, run_claims

    only = None
    if args.only is not None:
        only = [c.strip() for c in args.only.split(",") if c.strip()]
        known = [c.id for c in CLAIMS]
        unknown = [c for c in only if c not in known]
        if unknown or not only:
            raise CliError(
                f"--only: unknown claim(s) {', '.join(unknown) or '(none given)'}; choose from "
                f"{', '.join(known)}"
            )
    _check_out(args.out)
    data = run_claims(
        args.out,
        cache=_cache(args),
        quiet=args.quiet,
        echo=None if args.quiet else print,
        quick=args.quick,
        only=only,
    )
    print("claims: " + ", ".join(f"{k} {v}" for k, v in data["counts"].items()))
    print(f"claims: {args.out / 'claims.json'} and {args.out / 'claims.html'}")
    return 0


COMMANDS = {
    "doctor": cmd_doctor,
    "scenes": cmd_scenes,
    "reference": cmd_reference,
    "export": cmd_export,
    "main": cmd_main,
    "bench": cmd_bench,
    "techniques": cmd_techniques,
    "model": cmd_model,
    "score": cmd_score,
    "report": cmd_report,
    "sweep": lambda args: _sweep_cli().cmd_sweep(args),
    "tune": lambda args: _sweep_cli().cmd_tune(args),
    "converge": cmd_converge,
    "extremes": cmd_extremes,
    "claims": cmd_claims,
    "aa-memory": lambda args: _aa_memory(args),
}


def _aa_memory(args) -> int:
    from ..studies.aa_memory import cmd_aa_memory

    _check_out(args.out)
    return cmd_aa_memory(out=args.out)


def _sweep_cli():
    from . import sweeps as sweepcli

    return sweepcli


def _known_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that mean bad input: reported in one line with exit code 2."""
    from metrics import MetricError
    from scenes import SceneError
    from scenes.backend import BackendError

    from ..reference.exr import ExrError
    from ..reference.render import ReferenceError_
    from ..scoring.candidates import CandidateError
    from ..scoring.score import ScoreError
    from ..studies.converge import ConvergeError

    errors = [
        CliError,
        *_sweep_cli().known_errors(),
        SceneError,
        BackendError,
        ExrError,
        ReferenceError_,
        ScoreError,
        CandidateError,
        MetricError,
        ConvergeError,
    ]
    try:
        from raster_models import ModelError

        errors.append(ModelError)
    except ImportError:  # the models package is optional for the reference commands
        pass
    return tuple(errors)


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line: newlines (e.g. in file names) are escaped."""
    text = str(exc)
    return "".join(c if c >= " " or c == "\t" else repr(c)[1:-1] for c in text)


def _terminate(signum, frame):  # SIGTERM: unwind so that `finally` blocks clean up
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> int:
    import signal
    import warnings

    from ..reference.cache import remove_scratch, scratch_mark, sweep_stale_scratch

    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except CliError as exc:
        print(f"raster-oracle: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help
        return int(exc.code or 0)
    previous = None
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread
        pass
    mark = scratch_mark()
    try:
        sweep_stale_scratch()
        with warnings.catch_warnings():
            # NumPy's RuntimeWarnings (0/0 on empty masks, ...) are not the user's business;
            # results are checked for NaN/inf where they are made.
            warnings.simplefilter("ignore", RuntimeWarning)
            if args.command != "doctor":
                from scenes import backend

                backend.select(args.backend)
            return COMMANDS[args.command](args)
    except _known_errors() as exc:
        print(f"raster-oracle: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head`: not an error
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("raster-oracle: interrupted", file=sys.stderr)
        return 130
    finally:
        remove_scratch(mark)
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
