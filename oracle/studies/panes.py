"""The stacked panes (issue 45): content the exact-coverage estimate once under-counted.

``n`` camera-facing rectangles, each about 90 % of a square film across, 1 cm apart in depth,
each turned a little about the view axis (up to 4 degrees) and tilted by less than 0.1
degree (never enough to cross a neighbour 1 cm away), and shifted by up to 3 % of its size:
every pane overlaps every other over most of the film, so the exact coverage's tile pieces
pair up about ``256 n^2 / 2`` times (two triangles a pane: ``256 (2n)^2 / 2``).

Not a built-in scene (its exact coverage takes minutes at 256 x 256: the catalogue's tests
would pay it): :func:`stacked_panes` is a scene factory (the built-in scenes' dict form,
loadable with :func:`scenes.load` through a
:class:`scenes.catalogue.builtin.BuiltinScene`), :func:`stacked_panes_xml` writes the same
scene as a Mitsuba XML file for the command line (``raster-oracle bench exact --panes-xml
FILE``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PANES_N", "panes_scene", "stacked_panes", "stacked_panes_xml"]

#: Panes of the issue's content.
PANES_N = 80
#: Camera distance to the front pane and horizontal field of view (degrees).
_DISTANCE, _FOV = 5.0, 40.0
#: Pane half-size as a fraction of the film's half-width at the front pane.
_SIZE = 0.9
#: Spacing of the panes in depth (world units: metres).
_SPACING = 0.01


def _panes(n: int, seed: int) -> list[dict]:
    """Per pane: centre, half-size, turn about the view axis and tilts (degrees)."""
    rng = np.random.default_rng([int(seed), 45])
    half = _SIZE * _DISTANCE * math.tan(math.radians(_FOV / 2))
    turn = rng.uniform(-4.0, 4.0, n)
    tilt = rng.uniform(-0.08, 0.08, (n, 2))
    shift = rng.uniform(-0.03, 0.03, (n, 2)) * 2 * half
    return [
        {
            "centre": (float(shift[i, 0]), float(shift[i, 1]), -_SPACING * i),
            "half": half,
            "turn": float(turn[i]),
            "tilt": (float(tilt[i, 0]), float(tilt[i, 1])),
        }
        for i in range(n)
    ]


def _to_world(p: dict) -> np.ndarray:
    """4x4 matrix of a pane: Mitsuba's rectangle ([-1, 1]^2 at z = 0, normal +z) scaled,
    turned about z, tilted about x then y, moved to its centre."""

    def rot(axis: int, deg: float) -> np.ndarray:
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        m = np.eye(4)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    m = np.diag([p["half"], p["half"], 1.0, 1.0])
    m = rot(1, p["tilt"][1]) @ rot(0, p["tilt"][0]) @ rot(2, p["turn"]) @ m
    m[:3, 3] = p["centre"]
    return m


def stacked_panes(width: int, height: int, *, n: int = PANES_N, seed: int = 1) -> dict:
    """The stacked panes as a built-in scene's dict (Mitsuba's ``load_dict`` form): ``n``
    panes, a sun from behind the camera's right shoulder, the camera ``5`` in front of the
    first pane with a 40-degree horizontal field of view."""
    from ...scenes.catalogue.factories import diffuse, sensor, sun

    scene = {
        "type": "scene",
        "camera": sensor(
            width, height, origin=(0, 0, _DISTANCE), target=(0, 0, 0), fov=_FOV, near=0.1, far=100
        ),
        "sun": sun((-0.3, -0.4, -1.0)),
    }
    for i, p in enumerate(_panes(int(n), int(seed))):
        scene[f"pane{i:03d}"] = {
            "type": "rectangle",
            "to_world": _to_world(p),
            "bsdf": diffuse((0.3 + 0.5 * (i % 2), 0.5, 0.7 - 0.4 * (i % 2))),
        }
    return scene


def panes_scene(n: int = PANES_N, seed: int = 1):
    """The stacked panes as a :class:`scenes.catalogue.builtin.BuiltinScene` (loadable with
    :func:`scenes.load` at any film size, square by default)."""
    from ...scenes.catalogue.builtin import BuiltinScene

    def factory(width, height):
        return stacked_panes(width, height, n=n, seed=seed)

    return BuiltinScene(f"panes{int(n)}", factory, "the stacked panes (issue 45)", 256, 256)


def stacked_panes_xml(width: int = 256, height: int = 256, *, n: int = PANES_N, seed: int = 1):
    """The stacked panes as a Mitsuba 3 XML scene (text): the same panes as
    :func:`stacked_panes`."""
    lines = [
        '<scene version="3.0.0">',
        '  <sensor type="perspective">',
        f'    <float name="fov" value="{_FOV:g}"/>',
        '    <string name="fov_axis" value="x"/>',
        '    <float name="near_clip" value="0.1"/>',
        '    <float name="far_clip" value="100"/>',
        '    <transform name="to_world">',
        f'      <lookat origin="0, 0, {_DISTANCE:g}" target="0, 0, 0" up="0, 1, 0"/>',
        "    </transform>",
        '    <film type="hdrfilm">',
        f'      <integer name="width" value="{int(width)}"/>',
        f'      <integer name="height" value="{int(height)}"/>',
        '      <rfilter type="box"/>',
        '      <string name="component_format" value="float32"/>',
        "    </film>",
        "  </sensor>",
        '  <emitter type="directional">',
        '    <vector name="direction" value="-0.3, -0.4, -1"/>',
        '    <rgb name="irradiance" value="3"/>',
        "  </emitter>",
    ]
    for i, p in enumerate(_panes(int(n), int(seed))):
        m = _to_world(p)
        rgb = (0.3 + 0.5 * (i % 2), 0.5, 0.7 - 0.4 * (i % 2))
        lines += [
            f'  <shape type="rectangle" id="pane{i:03d}">',
            '    <transform name="to_world">',
            f'      <matrix value="{" ".join(f"{v:.17g}" for v in m.ravel())}"/>',
            "    </transform>",
            '    <bsdf type="twosided"><bsdf type="diffuse">',
            f'      <rgb name="reflectance" value="{rgb[0]:g}, {rgb[1]:g}, {rgb[2]:g}"/>',
            "    </bsdf></bsdf>",
            "  </shape>",
        ]
    return "\n".join([*lines, "</scene>", ""])
