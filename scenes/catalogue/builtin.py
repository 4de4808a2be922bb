"""The catalogue of built-in scenes: each a factory returning a Mitsuba scene dictionary.

Every factory takes the film size and returns a plain dictionary for ``mitsuba.load_dict``;
custom triangle meshes appear as ``{"type": "ro_mesh", "vertices": (V, 3), "faces": (F, 3)}``
entries that :mod:`scenes.loader` turns into Mitsuba meshes. World up is +Y. All materials are
two-sided diffuse (see :mod:`scenes.shading.phong`); a top-level ``"ro_specular"`` entry (used by
:mod:`scenes.catalogue.aa_scenes`' glossy scene) switches on the shared Blinn-Phong lobe.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import aa_scenes, moving_scenes, pbr_scenes, shadow_scenes, soft_scenes

__all__ = ["BUILTIN_SCENES", "BuiltinScene", "DEFAULT_SCENES"]


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

#: The scenes the main job runs by default.
DEFAULT_SCENES = ("plate", "city", "thin", "star", "curved", "spot", "point", "pbr-spheres")
