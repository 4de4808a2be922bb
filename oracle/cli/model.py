"""Commands about the technique models: ``techniques`` and ``model``."""

from __future__ import annotations

from pathlib import Path

from ...scenes.base.files import staged_folder
from . import args as A

__all__ = ["COMMANDS", "add_parsers"]


def add_parsers(sub) -> None:
    """Add ``techniques`` and ``model`` to the subparsers ``sub``."""
    sub.add_parser("techniques", help="list the technique models with their parameters")

    p = sub.add_parser("model", help="run a technique model: output.exr + model.json")
    p.add_argument("technique", metavar="TECHNIQUE")
    A.add_scene_args(p)
    A.add_set_arg(p)
    p.add_argument("--out", type=A.path, default=Path("out/model"), help="output folder")


def cmd_techniques(args) -> int:
    from ... import raster_models

    for tech in raster_models.list_techniques():
        seq = ", over frame sequences" if tech["temporal"] else ""
        print(f"{tech['name']}: {tech['description']}")
        print(f"  (family {tech['family']}: scored on {', '.join(tech['scored_on'])}{seq})")
        for prm in tech["params"]:
            choices = f" {{{', '.join(map(str, prm['choices']))}}}" if prm.get("choices") else ""
            print(f"  {prm['name']} = {prm['default']!r}{choices}  [{prm['source']}]")
        print()
    return 0


def cmd_model(args) -> int:
    from ... import raster_models
    from ..scoring.models import run_model_to_folder

    A.check_out(args.out)
    loaded = A.load_scene(args)
    params = raster_models.parse_params(args.technique, args.params)
    with staged_folder(args.out) as out:
        run_model_to_folder(args.technique, loaded, params=params, out=out)
    print(f"model {args.technique}: {args.out / 'output.exr'}")
    return 0


COMMANDS = {"techniques": cmd_techniques, "model": cmd_model}
