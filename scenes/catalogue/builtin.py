"""The catalogue of built-in scenes: each a factory returning a Mitsuba scene dictionary.

Every factory takes the film size and returns a plain dictionary for ``mitsuba.load_dict``;
custom triangle meshes appear as ``{"type": "ro_mesh", "vertices": (V, 3), "faces": (F, 3)}``
entries that :mod:`scenes.loader` turns into Mitsuba meshes. World up is +Y. All materials are
two-sided diffuse (see :mod:`scenes.shading.phong`); a top-level ``"ro_specular"`` entry (used by
:mod:`scenes.catalogue.aa_scenes`' glossy scene) switches on the shared Blinn-Phong lobe.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace

from ..base.memory import available_memory, gib
from ..base.numbers import parse_int
from . import (
    aa_scenes,
    alpha_foliage,
    event_scenes,
    moving_scenes,
    pbr_scenes,
    scale_scenes,
    shadow_scenes,
    soft_scenes,
)

__all__ = [
    "BUILTIN_SCENES",
    "BuiltinScene",
    "DEFAULT_SCENES",
    "SceneParam",
    "SceneParamError",
    "builtin_scene",
]


class SceneParamError(ValueError):
    """A built-in scene name with a parameter that is unknown or out of range."""


@dataclass(frozen=True)
class SceneParam:
    """An integer parameter of a built-in scene (``name:key=value``), passed to its factory
    as a keyword: its default and inclusive bounds."""

    key: str
    default: int
    lo: int
    hi: int
    doc: str
    #: Bytes each unit of the parameter costs a command at its peak (measured: peak RSS of
    #: ``reference`` at n=0 and n=1,000,000, 8x8, visibility, with a margin for the models
    #: and scoring), checked against the memory free before the scene is built.
    bytes_each: int = 0


@dataclass(frozen=True)
class BuiltinScene:
    """A built-in scene: its factory, one-line description and default (test) resolution."""

    name: str
    factory: Callable[[int, int], dict]
    description: str
    width: int = 160
    height: int = 90
    #: ``"mitsuba"``: the factory returns a Mitsuba dictionary; ``"gltf"``: GLB bytes
    #: (read by :mod:`scenes.formats.gltf`, shaded with the glTF BRDF).
    kind: str = "mitsuba"
    #: Parameters the factory takes as keywords (``meadow:n=100000``); see
    #: :func:`builtin_scene`.
    params: tuple[SceneParam, ...] = ()


BUILTIN_SCENES: dict[str, BuiltinScene] = {
    s.name: s
    for s in [
        BuiltinScene(
            "plate", shadow_scenes.plate, "a square plate casting a hard shadow on a ground plane"
        ),
        BuiltinScene(
            "city",
            shadow_scenes.city,
            "196 boxes on a 4 km ground plane, far/near = 2e4 (the cascade workload)",
        ),
        BuiltinScene(
            "thin",
            shadow_scenes.thin,
            "fence slats, wires 0.05-3 px wide at five depths and "
            "3000 grass blades (several surfaces per pixel)",
            320,
            180,
        ),
        BuiltinScene(
            "star",
            shadow_scenes.star,
            "a 36-spoke Siemens star and near-axis edges against the sky (coverage aliasing)",
        ),
        BuiltinScene(
            "curved",
            shadow_scenes.curved,
            "a sphere and a cylinder casting onto a large curved receiver",
        ),
        BuiltinScene("spot", shadow_scenes.spot, "boxes on a ground plane lit by a spot light"),
        BuiltinScene("point", shadow_scenes.point, "boxes and a sphere around a point light"),
    ]
}

# The anti-aliasing scenes (decal, stripes, glossy, foliage, hdr-edge): see .aa_scenes.
BUILTIN_SCENES.update(
    {n: BuiltinScene(n, f, d, w, h) for n, (f, d, w, h) in aa_scenes.AA_SCENES.items()}
)

# The glTF scenes (pbr-spheres, pbr-foliage): GLB bytes, see scenes.catalogue.pbr_scenes.
BUILTIN_SCENES.update(
    {
        n: BuiltinScene(n, f, d, w, h, kind="gltf")
        for n, (f, d, w, h) in pbr_scenes.PBR_SCENES.items()
    }
)

# Scenes with moving objects (slide, spin): see scenes.catalogue.moving_scenes.
BUILTIN_SCENES.update(
    {n: BuiltinScene(n, f, d, w, h) for n, (f, d, w, h) in moving_scenes.MOVING_SCENES.items()}
)

# Soft-shadow scenes (soft-contact: an area light; stacked-casters): see .soft_scenes.
BUILTIN_SCENES.update(
    {n: BuiltinScene(n, f, d, w, h) for n, (f, d, w, h) in soft_scenes.SOFT_SCENES.items()}
)

# Event scenes for temporal shadow denoisers (flicker-, occluder-, pan- x sun, rect): see
# scenes.catalogue.event_scenes.
BUILTIN_SCENES.update(
    {n: BuiltinScene(n, f, d, w, h) for n, (f, d, w, h) in event_scenes.EVENT_SCENES.items()}
)

# Scenes of real size, their size a parameter (meadow:n=1000000): see scenes.catalogue.scale_scenes.
_SIZE = "number of {}; default {}"
BUILTIN_SCENES.update(
    {
        "meadow": BuiltinScene(
            "meadow",
            scale_scenes.meadow,
            "a 24 x 24 ground and n one-triangle grass blades 0.3-0.6 tall (content of real "
            "size: meadow:n=1000000)",
            320,
            180,
            params=(
                SceneParam("n", scale_scenes.MEADOW_N, 0, 10**8, _SIZE.format("blades", 5000), 600),
                SceneParam("seed", 1, 0, 2**31 - 1, "random seed of the blades; default 1"),
            ),
        ),
        "city-foliage": BuiltinScene(
            "city-foliage",
            scale_scenes.city_foliage,
            "twelve buildings and sixteen trees whose crowns hold n leaves (large casters among "
            "small ones: city-foliage:n=200000)",
            320,
            180,
            params=(
                SceneParam(
                    "n", scale_scenes.CITY_FOLIAGE_N, 0, 10**8, _SIZE.format("leaves", 5000), 600
                ),
                SceneParam("seed", 1, 0, 2**31 - 1, "random seed of the block; default 1"),
            ),
        ),
        "alpha-foliage": BuiltinScene(
            "alpha-foliage",
            alpha_foliage.alpha_foliage,
            "glTF: n alpha-tested (MASK) leaf cards in five distance bands 2-200 m, one column "
            "each, under a sun (alpha-foliage:n=100000; alpha=0: the same cards opaque)",
            320,
            180,
            kind="gltf",
            params=(
                SceneParam(
                    "n",
                    alpha_foliage.ALPHA_FOLIAGE_N,
                    1,
                    10**7,
                    _SIZE.format("cards", alpha_foliage.ALPHA_FOLIAGE_N),
                    2000,
                ),
                SceneParam("seed", 1, 0, 2**31 - 1, "random seed of the cards; default 1"),
                SceneParam("alpha", 1, 0, 1, "1: MASK (alpha-tested); 0: OPAQUE; default 1"),
            ),
        ),
    }
)


def builtin_scene(name) -> BuiltinScene | None:
    """The built-in scene ``name`` stands for, or None when it names none.

    ``name`` is a catalogue name, or one followed by parameters ``:key=value`` (integers;
    ``meadow:n=100000:seed=3``): the scene's factory then receives them as keywords and the
    returned scene's name lists them in the catalogue's order (the name the reference cache,
    the records and the reports carry). A :class:`BuiltinScene` is returned as it is.

    Raises
    ------
    SceneParamError
        A parameter the scene does not take, a repeated one, or a value that is not an
        integer within the parameter's bounds.
    """
    if isinstance(name, BuiltinScene):
        return name
    if not isinstance(name, str):
        return None
    base, _, rest = name.partition(":")
    spec = BUILTIN_SCENES.get(base)
    if spec is None or not rest:
        return spec if not rest else None
    known = {p.key: p for p in spec.params}
    if not known:
        raise SceneParamError(f"built-in scene {base!r} takes no parameters (got {name!r})")
    given: dict[str, int] = {}
    for item in rest.split(":"):
        key, eq, text = (part.strip() for part in item.partition("="))
        if key not in known or not eq:
            raise SceneParamError(
                f"scene {name!r}: {key or item!r} is not a parameter of {base!r} "
                f"(it takes {', '.join(f'{p.key}=' for p in spec.params)}; e.g. {base}:n=1000)"
            )
        if key in given:
            raise SceneParamError(f"scene {name!r}: parameter {key!r} given twice")
        p = known[key]
        what = f"scene {name[:80]!r}: {key}"
        given[key] = parse_int(text, what=what, lo=p.lo, hi=p.hi, error=SceneParamError)
    _check_memory(name, spec, given)
    canonical = base + "".join(f":{p.key}={given[p.key]}" for p in spec.params if p.key in given)
    return replace(spec, name=canonical, factory=functools.partial(spec.factory, **given))


def _check_memory(name: str, spec: BuiltinScene, given: dict[str, int]) -> None:
    """Refuse parameters whose estimated memory (:attr:`SceneParam.bytes_each` per unit)
    exceeds what this machine has free, before anything is allocated."""
    need = sum(p.bytes_each * given.get(p.key, p.default) for p in spec.params)
    if not need:
        return
    free = available_memory()
    if need > free:
        raise SceneParamError(
            f"scene {name[:80]!r} needs about {gib(need)} of memory, more than the {gib(free)} "
            "free here; choose a smaller size"
        )


#: The scenes the main job runs by default.
DEFAULT_SCENES = ("plate", "city", "thin", "star", "curved", "spot", "point", "pbr-spheres")
