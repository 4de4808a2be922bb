"""Commands about the world and its ground truth: ``doctor``, ``scenes``, ``reference``,
``export``."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ...scenes.base.files import staged_folder
from . import args as A

__all__ = ["COMMANDS", "add_parsers"]


def add_parsers(sub) -> None:
    """Add ``doctor``, ``scenes``, ``reference`` and ``export`` to the subparsers ``sub``."""
    p = sub.add_parser("doctor", help="print the backend, libLLVM, versions and cores")
    p.add_argument(
        "--check",
        action="store_true",
        help="run the backend's self-check (closed-form checks, < 30 s): one line a check, "
        "exit 1 if any fails; the verdict is cached for --backend auto",
    )
    sub.add_parser("scenes", help="list the built-in scenes and camera paths")

    p = sub.add_parser("reference", help="render (or fetch from the cache) a reference")
    A.add_scene_args(p)
    A.add_reference_args(p)
    p.add_argument(
        "--channels",
        default=None,
        help="comma-separated channel groups (default: all but the optional ones): "
        "visibility, coverage, coverage_exact, color, edge, id, depth, position, normal, "
        "albedo; optional: tangent32, motion",
    )
    p.add_argument("--out", type=A.path, default=Path("out/reference"), help="output folder")

    p = sub.add_parser("export", help="write meshes (PLY), camera.json and lights.json")
    A.add_scene_args(p)
    p.add_argument("--out", type=A.path, required=True, help="output folder")


def cmd_doctor(args) -> int:
    from ...scenes import backend
    from ...scenes.base.records import package_versions

    if args.check:
        return _doctor_check(args)
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


def _doctor_check(args) -> int:
    """``doctor --check``: the battery on the selected backend, one line a check."""
    from ...scenes import backend
    from ..certify import run_check

    info = backend.select(args.backend)
    device = backend.device_info()
    print(f"backend {info.variant} on {device.get('name', 'an unknown device')}")
    verdict = run_check(on_check=lambda c: print(c.line(), flush=True))
    if verdict["passed"]:
        print(f"self-check passed ({len(verdict['checks'])} checks, {verdict['seconds']} s)")
        return 0
    print(f"self-check FAILED: {', '.join(verdict['failed'])}")
    return 1


def cmd_scenes(args) -> int:
    from ...scenes import BUILTIN_SCENES, CAMERA_PATHS
    from ...scenes.light_paths import LIGHT_PATHS

    width = max(len(n) for n in BUILTIN_SCENES)
    for name, spec in BUILTIN_SCENES.items():
        print(f"{name:<{width}}  {spec.width}x{spec.height}  {spec.description}")
        for param in spec.params:  # meadow:n=100000
            print(f"{'':<{width}}    {name}:{param.key}=N  {param.doc}")
    print("\ncamera paths (--camera-path NAME --frame K --frames N):")
    for name, text in CAMERA_PATHS.items():
        print(f"  {name:<13} {text}")
    print("\nlight paths (--light-path NAME --frame K --frames N):")
    for name, text in LIGHT_PATHS.items():
        print(f"  {name:<13} {text}")
    return 0


def cmd_reference(args) -> int:
    from ..reference.render import ALL_CHANNELS, ReferenceSettings
    from ..reference.store import get_reference, publish

    groups = ALL_CHANNELS if args.channels is None else A.names(args.channels)
    settings = ReferenceSettings(
        spp=args.spp,
        seed=args.seed,
        channels=tuple(groups),
        adaptive=args.adaptive,
        target_stderr=args.target_stderr,
        max_spp=args.max_spp,
        exact_budget=A.exact_budget(args),
    ).validate()
    A.check_out(args.out)
    loaded = A.load_scene(args)
    ref = get_reference(loaded, settings, cache=A.reference_cache(args), quiet=args.quiet)
    if ref.cache_status == "corrupted":
        print("raster-oracle: warning: corrupted cache entry replaced", file=sys.stderr)
    with staged_folder(args.out) as out:
        publish(ref, out)
    print(f"reference ({ref.cache_status}): {args.out / 'reference.exr'}")
    return 0


def cmd_export(args) -> int:
    from ...scenes.formats.export import export

    A.check_out(args.out)
    loaded = A.load_scene(args)
    with staged_folder(args.out) as out:
        summary = export(loaded, out)
    tris = sum(s["triangles"] for s in summary["shapes"].values())
    print(f"exported {len(summary['shapes'])} shapes ({tris} triangles) to {args.out}")
    return 0


COMMANDS = {
    "doctor": cmd_doctor,
    "scenes": cmd_scenes,
    "reference": cmd_reference,
    "export": cmd_export,
}
