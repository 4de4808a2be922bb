"""Argument types, shared options and argument checks of the command line.

Every command module adds its parser with the helpers here and turns its parsed arguments
into keyword calls of the library; nothing here is called by the library.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from ...scenes.base.numbers import MAX_FRAMES, NumberError, parse_float, parse_int
from ...scenes.base.untrusted import check_path, path_problem
from ..errors import InputError

__all__ = [
    "MAX_SPP",
    "CliError",
    "Parser",
    "add_cache_args",
    "add_exact_budget_arg",
    "exact_budget",
    "add_reference_args",
    "add_scene_args",
    "add_set_arg",
    "check_db",
    "check_distinct",
    "check_dir",
    "check_out",
    "input_errors",
    "load_scene",
    "names",
    "nonneg_float",
    "nonneg_int",
    "path",
    "positive_float",
    "depth_buffer",
    "positive_int",
    "reference_cache",
    "spp",
]


class CliError(InputError):
    """Bad command-line input."""


def input_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that mean bad input: reported in one line with exit code 2.

    The oracle's own derive from :class:`oracle.errors.InputError`; the other packages' are
    named here (an untrusted file refused by :mod:`scenes.base.untrusted` included).
    """
    from ...metrics import MetricError
    from ...raster_models import ModelError
    from ...scenes import SceneError, SceneParamError
    from ...scenes.backend import BackendError
    from ...scenes.base.untrusted import UntrustedError

    return (
        InputError,
        SceneError,
        SceneParamError,
        BackendError,
        MetricError,
        ModelError,
        UntrustedError,
        NumberError,
    )


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (raised, not printed with the usage)."""

    def error(self, message):
        where = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        raise CliError(f"{where}{message}")


def _number(kind: type, *, minimum: float, strict: bool):
    """An argparse type: ``kind`` parsed from text by the one strict rule
    (:mod:`scenes.base.numbers`: decimal digits, bounded length; ``inf`` for numbers),
    bounded below by ``minimum``."""
    noun = "an integer" if kind is int else "a number"
    relation = ">" if strict else ">="

    def parse(text: str):
        try:
            if kind is int:
                value = parse_int(text, what="value", signed=True)
            elif text.lower() in ("inf", "+inf", "infinity", "+infinity"):
                value = math.inf
            else:
                value = parse_float(text, what="value")
        except NumberError:
            shown = text if len(text) <= 40 else text[:40] + "..."
            raise argparse.ArgumentTypeError(f"expected {noun}, got {shown!r}") from None
        if not (value > minimum if strict else value >= minimum):
            raise argparse.ArgumentTypeError(f"must be {relation} {minimum:g}, got {value}")
        return value

    return parse


#: argparse types: an integer > 0, an integer >= 0, a number > 0.
positive_int = _number(int, minimum=0, strict=True)
nonneg_int = _number(int, minimum=0, strict=False)
positive_float = _number(float, minimum=0.0, strict=True)
nonneg_float = _number(float, minimum=0.0, strict=False)

#: Largest ``--spp`` / ``--max-spp``: 2^20 samples per pixel (a 1-pixel reference then takes
#: seconds; beyond it the standard error, 0.0005 at worst, stops mattering).
MAX_SPP = 2**20


def spp(text: str) -> int:
    """An argparse type: samples per pixel, an integer in [1, MAX_SPP]."""
    value = positive_int(text)
    if value > MAX_SPP:
        raise argparse.ArgumentTypeError(f"must be <= {MAX_SPP} (2^20), got {value}")
    return value


def frames(text: str) -> int:
    """An argparse type: a frame count, an integer in [1, MAX_FRAMES] (as in a manifest)."""
    value = positive_int(text)
    if value > MAX_FRAMES:
        raise argparse.ArgumentTypeError(f"must be <= {MAX_FRAMES}, got {value}")
    return value


def depth_buffer(text: str) -> tuple[float, float, int]:
    """An argparse type: ``NEAR,FAR,BITS``, an engine's hyperbolic depth buffer
    (``0 < NEAR < FAR``, ``BITS`` 16, 24 or 32)."""
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"must be NEAR,FAR,BITS (e.g. 0.1,1000,24), got {text!r}")
    near, far, bits = positive_float(parts[0]), positive_float(parts[1]), positive_int(parts[2])
    if not near < far:
        raise argparse.ArgumentTypeError(f"needs NEAR < FAR, got near {near:g}, far {far:g}")
    if bits not in (16, 24, 32):
        raise argparse.ArgumentTypeError(f"BITS must be 16, 24 or 32, got {bits}")
    return near, far, bits


def path(text: str) -> Path:
    """An argparse type: a non-empty path without control characters."""
    if not text:
        raise argparse.ArgumentTypeError("expected a path, got ''")
    if any(ord(c) < 32 for c in text):
        raise argparse.ArgumentTypeError(f"path contains control characters: {text!r}")
    problem = path_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{text[:60]!r}...: {problem}")
    return Path(text)


def names(text: str) -> list[str]:
    """The non-empty items of a comma-separated option value, stripped."""
    return [item.strip() for item in text.split(",") if item.strip()]


def add_scene_args(p: argparse.ArgumentParser) -> None:
    """``SCENE --camera --light --width --height --camera-path --light-path --frame --frames``."""
    p.add_argument(
        "scene",
        metavar="SCENE",
        help="built-in scene name, Mitsuba XML file, glTF 2.0 file (.gltf, .glb), or an "
        "`export` folder (its scene.xml or scene.glb, at its exported size and light)",
    )
    p.add_argument(
        "--camera",
        type=nonneg_int,
        default=None,
        help="glTF scenes: index of the file's camera to view through (default: the scene's "
        "first camera node)",
    )
    p.add_argument(
        "--light",
        type=nonneg_int,
        default=None,
        help="index of the light (default 0; an export's own light)",
    )
    p.add_argument("--width", type=positive_int, help="film width in pixels")
    p.add_argument("--height", type=positive_int, help="film height in pixels")
    p.add_argument(
        "--camera-path",
        default=None,
        help="camera path for temporal work: subpixel-pan, subtexel-pan, rotate, dolly, "
        "static (default of scenes whose objects move)",
    )
    p.add_argument(
        "--camera-file",
        type=path,
        default=None,
        metavar="JSON",
        help="camera sequence file: per-frame camera matrices and field of view "
        "(docs/cli.md); frames follow it",
    )
    p.add_argument(
        "--light-path",
        default=None,
        help="light path for moving-light work: orbit-sun (directional), moving-point "
        "(point/spot); --frame K picks its frame",
    )
    p.add_argument(
        "--frame", type=nonneg_int, default=0, help="frame of the camera and/or light path"
    )
    p.add_argument(
        "--frames",
        type=frames,
        default=None,
        help="frames in the camera path (default 8); for `score`: score that many frames of "
        "the path (--camera-path, or the one an export records: required) and add the "
        "temporal metrics",
    )


def add_set_arg(p: argparse.ArgumentParser, *, help: str = "technique parameter") -> None:
    """``--set KEY=VALUE`` (repeatable), into ``args.params``."""
    p.add_argument(
        "--set",
        dest="params",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"{help} (repeatable)",
    )


def add_cache_args(p: argparse.ArgumentParser, *, no_cache: bool = True) -> None:
    """``--cache-dir DIR`` (and ``--no-cache``) and ``--quiet``."""
    p.add_argument(
        "--cache-dir",
        type=path,
        default=None,
        help="reference cache (default ~/.cache/raster-oracle)",
    )
    if no_cache:
        p.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def add_reference_args(p: argparse.ArgumentParser, *, default_spp: int = 64) -> None:
    """Reference sampling options: ``--spp --seed --adaptive --target-stderr --max-spp`` and
    the cache options."""
    p.add_argument(
        "--spp",
        type=spp,
        default=default_spp,
        help=f"sub-pixel samples per pixel (default {default_spp})",
    )
    p.add_argument("--seed", type=nonneg_int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--adaptive",
        action="store_true",
        help="adaptive sampling: more samples only where pixels are not uniform",
    )
    p.add_argument(
        "--target-stderr",
        type=positive_float,
        default=0.01,
        help="adaptive: target standard error (default 0.01)",
    )
    p.add_argument(
        "--max-spp",
        type=spp,
        default=4096,
        help="adaptive: most samples a pixel gets (default 4096)",
    )
    add_exact_budget_arg(p)
    add_cache_args(p)


def exact_budget(args):
    """The command's one exact-coverage budget (``--exact-budget``, default
    :data:`oracle.reference.settings.EXACT_BUDGET_S`): every reference the command renders
    holds this object, so their exact work adds up against it, and it is the command's
    deadline (counted from now, when the command starts)."""
    import time

    from ..reference.settings import EXACT_BUDGET_S, ExactBudget

    seconds = getattr(args, "exact_budget", None)
    return ExactBudget(EXACT_BUDGET_S if seconds is None else seconds, since=time.perf_counter())


def add_exact_budget_arg(p: argparse.ArgumentParser) -> None:
    """``--exact-budget SECONDS``: the references' ``exact_budget`` setting
    (:class:`oracle.reference.settings.ReferenceSettings`), handed to them by the command."""
    p.add_argument(
        "--exact-budget",
        type=nonneg_float,
        default=None,
        metavar="SECONDS",
        help="seconds of coverage_exact work the whole command may spend, all views and "
        "frames together (default 60): a view whose estimate exceeds what is left is "
        "skipped, and the exact pass stops when the time runs out; either way with one "
        "line on stderr, the decision in the record, and coverage scored against the "
        "Monte Carlo truth",
    )


def load_scene(args):
    """The scene of ``add_scene_args`` options (its frame of a camera or light path), as
    :func:`scenes.inputs.load_input` resolves it: an ``export`` folder (or its
    ``scene.xml``) is loaded at its exported size with its light, named after its folder."""
    from ...scenes.inputs import load_input

    loaded = load_input(
        args.scene,
        width=args.width,
        height=args.height,
        light=args.light,
        camera_path=args.camera_path,
        frame=args.frame,
        n_frames=args.frames or 8,
        light_path=args.light_path,
        camera_file=getattr(args, "camera_file", None),
        camera=getattr(args, "camera", None),
    )
    # a frame needs a sequence: a camera or light path, a camera file or objects that move
    if args.frame and loaded.camera_path is None and args.light_path is None and not args.frames:
        raise CliError(
            f"--frame {args.frame} needs --camera-path or --light-path (frame 0 is the "
            "scene's own camera and light)"
        )
    return loaded


def reference_cache(args):
    """The reference cache of ``--cache-dir`` (checked), or None with ``--no-cache``."""
    from ..reference.cache import ReferenceCache, default_cache_dir

    if getattr(args, "no_cache", False):
        return None
    root = args.cache_dir if args.cache_dir is not None else default_cache_dir()
    check_dir(root, label="--cache-dir" if args.cache_dir is not None else "cache folder")
    return ReferenceCache(root)


def check_dir(folder: Path, *, label: str) -> None:
    """``folder`` is a writable folder, or can be created: its nearest existing ancestor is
    one. ``label`` names the option in the message."""
    text = os.fspath(folder)
    if not text:
        raise CliError(f"{label}: expected a path, got ''")
    check_path(text, what=label, error=CliError)
    if os.path.exists(text) or os.path.islink(text):
        if not os.path.isdir(text):
            raise CliError(f"{label} {folder} exists and is not a folder")
        if not os.access(text, os.W_OK | os.X_OK):
            raise CliError(f"{label} {folder} is not writable")
        return
    parent = os.path.dirname(os.path.abspath(text))
    while not os.path.exists(parent):
        if os.path.islink(parent):  # a dangling link: nothing can be created under it
            raise CliError(f"{label} {folder}: {parent} is a broken link")
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise CliError(f"{label} {folder}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise CliError(f"{label} {folder}: {parent} is not writable")


def check_out(out: Path) -> None:
    """``--out`` is a folder that can be written (or created)."""
    check_dir(out, label="--out")


def _same_file(a: Path, b: Path) -> bool:
    """``a`` and ``b`` name one file: the same resolved path, or (both existing) one inode."""
    if Path(a).resolve() == Path(b).resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_distinct(*, writes: dict[str, Path], reads: dict[str, Path]) -> None:
    """No file this command writes is one it reads: an output path that is an input (or is
    the same file through a link) would destroy the input, so it is refused before anything
    is written.

    Parameters
    ----------
    writes, reads : a label for the message ("--out", "the report's JSON twin", "--db",
        "--sweep") -> the file's path.
    """
    for wlabel, w in writes.items():
        for rlabel, r in reads.items():
            if w is not None and r is not None and _same_file(w, r):
                raise CliError(
                    f"{wlabel} {w} is {rlabel} {r}: writing it would destroy it; "
                    "choose another output path"
                )


def check_not_inputs(*, writes: dict, reads: dict, folders: dict | None = None) -> None:
    """Every output file of ``writes`` is none of the input files of ``reads``
    (:func:`check_distinct`, links followed) and no existing file inside an input folder of
    ``folders`` (a folder whose every file may be read, a folder of candidate images).
    ``None`` values are skipped; files that do not exist are no inputs."""
    reads = {k: v for k, v in reads.items() if v is not None and os.path.isfile(v)}
    check_distinct(writes=writes, reads=reads)
    for wlabel, w in writes.items():
        if w is None or not os.path.lexists(w):
            continue
        inside = Path(w).resolve()
        for flabel, folder in (folders or {}).items():
            if (
                folder is not None
                and os.path.isdir(folder)
                and Path(folder).resolve() in inside.parents
            ):
                raise CliError(
                    f"{wlabel} {w} is a file of {flabel} {folder}: writing it would destroy "
                    "it; choose another output path"
                )


def check_db(db: Path) -> None:
    """``--db`` is a file (or can be created) in a writable folder."""
    if db.exists() and not db.is_file():
        raise CliError(f"--db {db} exists and is not a file")
    check_dir(db.parent if str(db.parent) else Path("."), label=f"--db {db}: folder")
