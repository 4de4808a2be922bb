"""Commands that measure the oracle and the models: ``bench``, ``aa-memory``, ``converge``,
``extremes``, ``claims`` and ``soft-shadows``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ...scenes.base.files import staged_folder
from . import args as A

__all__ = ["COMMANDS", "add_parsers"]


def add_parsers(sub) -> None:
    """Add ``bench``, ``aa-memory``, ``converge``, ``extremes``, ``claims`` and
    ``soft-shadows`` to ``sub``."""
    p = sub.add_parser("bench", help="benchmarks that print JSON figures")
    p.add_argument(
        "what",
        choices=["oracle", "models", "scale", "exact", "detection"],
        help="what to benchmark",
    )
    p.add_argument("--width", type=A.positive_int, default=None, help="default 1920 (scale 640)")
    p.add_argument("--height", type=A.positive_int, default=None, help="default 1080 (scale 360)")
    p.add_argument("--spp", type=A.positive_int, default=None, help="default 32 (scale 16)")
    p.add_argument(
        "--only",
        default="",
        help="models, scale: comma-separated techniques to time (default: every row; scale: "
        "fxaa, shadow-map, smaa, sdsm, izb, agaa, msaa)",
    )
    p.add_argument(
        "--sizes",
        default=None,
        help="scale: comma-separated blade counts of meadow:n=N (default 10000,100000,1000000)",
    )
    A.add_exact_budget_arg(p)
    p.add_argument(
        "--rows",
        default=None,
        help="exact: comma-separated rows scene@WxH (panes:n=N is the stacked panes; default "
        "meadow, city-foliage, the panes at 16:9, 4:3, 1:1, then every built-in scene)",
    )
    p.add_argument(
        "--panes-xml",
        type=A.path,
        default=None,
        metavar="FILE",
        help="exact: write the stacked panes (80, or --rows panes:n=N) as a Mitsuba XML scene "
        "at --width x --height (default 256x256) and stop",
    )
    p.add_argument(
        "--quiet", action="store_true", help="no progress bar, no profile tables on stderr"
    )
    for flag, text in (
        ("--scenes", "detection: comma-separated scenes (default plate,city,meadow:n=100000)"),
        ("--screens", "detection: comma-separated WxH (default 320x180,1280x720,1920x1080)"),
        ("--maps", "detection: comma-separated map sizes (default 1024,2048,4096)"),
        ("--faults", "detection: comma-separated faults (default every one)"),
    ):
        p.add_argument(flag, default=None, help=text)
    p.add_argument(
        "--out", type=A.path, default=None, help="detection: folder for detection.json and .md"
    )

    p = sub.add_parser(
        "aa-memory", help="AA framebuffer memory (models' accounting) vs the quoted figures"
    )
    p.add_argument("--out", type=A.path, default=Path("out/aa-memory"), help="output folder")

    p = sub.add_parser("converge", help="oracle true error against spp (and adaptive)")
    p.add_argument("scene", metavar="SCENE", help="built-in scene name or Mitsuba XML file")
    p.add_argument("--width", type=A.positive_int, help="film width in pixels")
    p.add_argument("--height", type=A.positive_int, help="film height in pixels")
    p.add_argument("--max-spp", type=A.spp, default=4096, help="largest spp (default 4096)")
    p.add_argument("--truth-spp", type=A.spp, default=None, help="truth spp (default 4x max)")
    p.add_argument(
        "--target",
        type=A.positive_float,
        action="append",
        default=None,
        help="true RMS visibility error to find the spp for (repeatable; default 0.01)",
    )
    p.add_argument("--seed", type=A.nonneg_int, default=0)
    p.add_argument("--no-adaptive", action="store_true", help="skip the adaptive rendering")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--out", type=A.path, default=Path("out/converge"), help="output folder")

    p = sub.add_parser("extremes", help="every model x every numerical extreme vs the oracle")
    p.add_argument("--quick", action="store_true", help="the main job's size (64x36, 4096^2)")
    p.add_argument(
        "--huge", type=A.positive_int, default=None, help="huge map size (default 16384)"
    )
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/extremes"), help="output folder")

    p = sub.add_parser("claims", help="measure the seed documents' headline claims")
    p.add_argument("--quick", action="store_true", help="the main job's size (160x90, 16 spp)")
    p.add_argument("--only", default=None, help="comma-separated claim ids (default: all)")
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/claims"), help="output folder")

    p = sub.add_parser(
        "soft-shadows",
        help="PCSS vs fixed-width PCF on the area-light truth, contact hardening, MSM bleeding",
    )
    p.add_argument("--quick", action="store_true", help="the main job's size (160x90, 16 spp)")
    A.add_cache_args(p)
    p.add_argument("--out", type=A.path, default=Path("out/soft-shadows"), help="output folder")


def cmd_bench(args) -> int:
    from ..studies.bench import bench_oracle, oracle_profile_lines
    from ..studies.bench_models import bench_models, models_profile_lines

    if args.what == "detection":
        return _bench_detection(args)
    given = [f for f in ("scenes", "screens", "maps", "faults", "out") if getattr(args, f)]
    if given:
        raise A.CliError(f"bench {args.what}: --{given[0]} applies to 'bench detection' only")
    if args.what == "scale":
        return _bench_scale(args)
    if args.what == "exact":
        return _bench_exact(args)
    if args.rows is not None or args.panes_xml is not None:
        raise A.CliError(f"bench {args.what}: --rows and --panes-xml apply to 'bench exact' only")
    if args.sizes is not None:
        raise A.CliError(f"bench {args.what}: --sizes applies to 'bench scale' only")
    kwargs = dict(
        width=args.width or 1920, height=args.height or 1080, spp=args.spp or 32, quiet=args.quiet
    )
    if args.what == "models":
        try:
            figures = bench_models(only=tuple(A.names(args.only)), **kwargs)
        except ValueError as exc:
            raise A.CliError(str(exc)) from None
    elif args.only:
        raise A.CliError("bench oracle: --only applies to 'bench models' only")
    else:
        figures = bench_oracle(**kwargs)
    print(json.dumps(figures, indent=2))
    if not args.quiet:  # where the time goes, for a reader (the JSON holds it all)
        lines = models_profile_lines if args.what == "models" else oracle_profile_lines
        print("\n".join(lines(figures)), file=sys.stderr)
    return 0


def _bench_exact(args) -> int:
    """``bench exact``: the estimate against the exact pass per row (JSON on stdout), or
    the stacked panes written as XML (``--panes-xml``)."""
    from ..studies.bench_exact import EXACT_ROWS, bench_exact, exact_lines
    from ..studies.panes import PANES_N, stacked_panes_xml

    rows = A.names(args.rows) if args.rows else None
    if args.panes_xml is not None:
        spec = (rows or ["panes"])[0]
        n = int(spec.partition("n=")[2].partition("@")[0] or PANES_N)
        xml = stacked_panes_xml(args.width or 256, args.height or 256, n=n)
        args.panes_xml.parent.mkdir(parents=True, exist_ok=True)
        args.panes_xml.write_text(xml)
        print(f"bench exact: the stacked panes ({n}) written to {args.panes_xml}")
        return 0
    log = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    figures = bench_exact(rows or EXACT_ROWS, builtins=rows is None, log=log)
    print(json.dumps(figures, indent=2))
    if not args.quiet:
        print("\n".join(exact_lines(figures)), file=sys.stderr)
    return 0


def _detection_grid(args) -> dict:
    """The ``bench detection`` grid from its options (defaults: the published table's)."""
    from ..studies import detection as D

    screens = D.DEFAULT_SIZES
    if args.screens is not None:
        screens = []
        for text in A.names(args.screens):
            w, x, h = text.partition("x")
            if not (x and w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
                raise A.CliError(f"bench detection: --screens expects WxH, got {text!r}")
            screens.append((int(w), int(h)))
    maps = D.DEFAULT_MAPS
    if args.maps is not None:
        if not all(t.isdigit() and 8 <= int(t) <= 16384 for t in A.names(args.maps)):
            raise A.CliError(f"bench detection: --maps expects sizes 8..16384, got {args.maps!r}")
        maps = tuple(int(t) for t in A.names(args.maps))
    faults = None
    if args.faults is not None:
        faults = A.names(args.faults)
        unknown = [f for f in faults if f not in D.FAULTS]
        if unknown:
            raise A.CliError(
                f"bench detection: unknown fault(s) {', '.join(unknown)}; choose from "
                f"{', '.join(D.FAULTS)}"
            )
    names = tuple(A.names(args.scenes)) if args.scenes is not None else D.DEFAULT_SCENES
    if not (names and screens and maps):
        raise A.CliError("bench detection: --scenes, --screens and --maps need a value each")
    return {"scene_names": names, "sizes": tuple(screens), "maps": maps, "faults": faults}


def _bench_detection(args) -> int:
    """``bench detection``: the detection-power table (JSON summary on stdout, the rows and
    a Markdown table in ``--out``)."""
    from ...scenes import SceneError
    from ...scenes.base.files import atomic_write_bytes, atomic_write_json
    from ..studies import detection as D

    grid = _detection_grid(args)
    log = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        record = D.run_detection(**grid, log=log)
    except SceneError as exc:
        raise A.CliError(f"bench detection: {exc}") from None
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(args.out / "detection.json", record)
        text = D.markdown_summary(record) + "\n" + D.markdown_table(record)
        atomic_write_bytes(args.out / "detection.md", text.encode())
    print(json.dumps({"gate": record["gate"], "summary": record["summary"]}, indent=2))
    return 0


def _bench_scale(args) -> int:
    """``bench scale``: per size and phase, seconds and peak memory (JSON on stdout)."""
    from ...scenes.catalogue.builtin import builtin_scene
    from ..studies.bench_scale import (
        SCALE_MODELS,
        SCALE_SIZES,
        bench_scale,
        failed_sizes,
        scale_lines,
    )

    texts = A.names(args.sizes) if args.sizes else [str(n) for n in SCALE_SIZES]
    if not texts:
        raise A.CliError(f"bench scale: --sizes must be blade counts >= 0, got {args.sizes!r}")
    # each size is a scene name: the strict number rule, its bounds, its memory estimate
    sizes = [int(builtin_scene(f"meadow:n={text}").name.partition("=")[2] or 0) for text in texts]
    models = tuple(A.names(args.only)) or SCALE_MODELS
    from ... import raster_models

    known = {t["name"] for t in raster_models.list_techniques()}
    unknown = [m for m in models if m not in known]
    if unknown:
        raise A.CliError(f"bench scale: unknown technique(s) {', '.join(unknown)}")
    figures = bench_scale(
        sizes=sizes,
        width=args.width or 640,
        height=args.height or 360,
        spp=args.spp or 16,
        models=models,
        budget=args.exact_budget,
        quiet=args.quiet,
    )
    print(json.dumps(figures, indent=2))
    if not args.quiet:
        print("\n".join(scale_lines(figures)), file=sys.stderr)
    failed = failed_sizes(figures)
    if failed:
        print(f"raster-oracle: bench scale: size(s) {', '.join(failed)} failed", file=sys.stderr)
        return 1
    return 0


def cmd_aa_memory(args) -> int:
    from ..studies.aa_memory import summary_lines, write_memory_report

    A.check_out(args.out)
    with staged_folder(args.out) as out:
        data = write_memory_report(out)
    print("\n".join(summary_lines(data)))
    print(f"aa-memory: {args.out / 'aa_memory.json'} and {args.out / 'aa_memory.html'}")
    return 0


def cmd_converge(args) -> int:
    from ..studies.converge import run_converge

    if args.truth_spp is not None and args.truth_spp <= args.max_spp:
        raise A.CliError(f"--truth-spp ({args.truth_spp}) must be larger than --max-spp")
    A.check_out(args.out)
    with staged_folder(args.out) as out:
        data = run_converge(
            args.scene,
            out=out,
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
        raise A.CliError(f"--huge must be in [8, 16384], got {args.huge}")
    A.check_out(args.out)
    with staged_folder(args.out) as out:
        data = run_extremes(
            out,
            cache=A.reference_cache(args),
            quiet=args.quiet,
            echo=None if args.quiet else print,
            quick=args.quick,
            huge=args.huge,
        )
    cells, unexpected = data["cells"], data["unexpected"]
    print(
        f"extremes: {len(cells)} cells, {len(unexpected)} not as documented"
        + (f" ({', '.join(unexpected)})" if unexpected else "")
    )
    print(f"extremes: {args.out / 'extremes.json'} and {args.out / 'extremes.html'}")
    return 0


def cmd_claims(args) -> int:
    from ..studies.claims.run import CLAIMS, run_claims

    only = None
    if args.only is not None:
        only = A.names(args.only)
        known = [c.id for c in CLAIMS]
        unknown = [c for c in only if c not in known]
        if unknown or not only:
            raise A.CliError(
                f"--only: unknown claim(s) {', '.join(unknown) or '(none given)'}; choose from "
                f"{', '.join(known)}"
            )
    A.check_out(args.out)
    with staged_folder(args.out) as out:
        data = run_claims(
            out,
            cache=A.reference_cache(args),
            quiet=args.quiet,
            echo=None if args.quiet else print,
            quick=args.quick,
            only=only,
        )
    print("claims: " + ", ".join(f"{k} {v}" for k, v in data["counts"].items()))
    print(f"claims: {args.out / 'claims.json'} and {args.out / 'claims.html'}")
    return 0


def cmd_soft_shadows(args) -> int:
    from ..studies.soft_shadows import run_soft_shadows

    A.check_out(args.out)
    with staged_folder(args.out) as out:
        data = run_soft_shadows(
            out, cache=A.reference_cache(args), quiet=args.quiet, quick=args.quick
        )
    best = data["ranking"]["rows"][0]
    print(f"soft-shadows: best on {data['ranking']['scene']}: {best['label']}")
    print(f"soft-shadows: {args.out / 'soft_shadows.json'} and {args.out / 'soft_shadows.html'}")
    return 0


COMMANDS = {
    "bench": cmd_bench,
    "aa-memory": cmd_aa_memory,
    "converge": cmd_converge,
    "extremes": cmd_extremes,
    "claims": cmd_claims,
    "soft-shadows": cmd_soft_shadows,
}
