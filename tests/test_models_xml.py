"""Small Mitsuba XML scenes for the shadow-model tests (helpers + a check of the helpers).

Scenes are data: :func:`write_scene` writes an XML file (and OBJ meshes) into a folder and
returns its path for :func:`scenes.load`. World up is +Y; every surface is diffuse.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from raster_oracle import scenes


def _vec(v) -> str:
    return ",".join(f"{float(c):.17g}" for c in v)


def _matrix(m: np.ndarray) -> str:
    return " ".join(f"{float(c):.17g}" for c in np.asarray(m, dtype=np.float64).ravel())


def quad(center, u_half, v_half) -> dict:
    """A rectangle with half-axes ``u_half``, ``v_half`` (normal along ``u x v``)."""
    u = np.asarray(u_half, float)
    v = np.asarray(v_half, float)
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u, v, n, center
    return {"type": "rectangle", "matrix": m}


def ground(size: float, y: float = 0.0, center=(0.0, 0.0)) -> dict:
    h = size / 2
    return quad((center[0], y, center[1]), (h, 0, 0), (0, 0, -h))


def box(lo, hi) -> dict:
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    m = np.diag([*((hi - lo) / 2), 1.0])
    m[:3, 3] = (hi + lo) / 2
    return {"type": "cube", "matrix": m}


def write_scene(
    folder: Path,
    *,
    origin,
    target,
    shapes,
    sun=(0.3, -1.0, 0.2),
    fov: float = 60.0,
    near: float = 0.1,
    far: float = 200.0,
    width: int = 96,
    height: int = 64,
    up=(0.0, 1.0, 0.0),
    name: str = "scene",
    meshes: dict | None = None,
) -> Path:
    """Write ``folder/name.xml``: a perspective camera, a directional light, the shapes.

    ``meshes``: extra OBJ meshes ``{file name: (vertices (V, 3), faces (F, 3) 0-based)}``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    parts = [
        '<scene version="3.0.0">',
        '  <sensor type="perspective">',
        f'    <float name="fov" value="{fov:.17g}"/>',
        '    <string name="fov_axis" value="x"/>',
        f'    <float name="near_clip" value="{near:.17g}"/>',
        f'    <float name="far_clip" value="{far:.17g}"/>',
        '    <transform name="to_world">',
        f'      <lookat origin="{_vec(origin)}" target="{_vec(target)}" up="{_vec(up)}"/>',
        "    </transform>",
        '    <film type="hdrfilm">',
        f'      <integer name="width" value="{width}"/>',
        f'      <integer name="height" value="{height}"/>',
        '      <rfilter type="box"/>',
        "    </film>",
        "  </sensor>",
        '  <emitter type="directional">',
        f'    <vector name="direction" value="{_vec(sun)}"/>',
        '    <rgb name="irradiance" value="3"/>',
        "  </emitter>",
    ]
    for i, shape in enumerate(shapes):
        parts += [
            f'  <shape type="{shape["type"]}" id="shape_{i}">',
            f'    <transform name="to_world"><matrix value="{_matrix(shape["matrix"])}"/>'
            "</transform>",
            '    <bsdf type="diffuse"/>',
            "  </shape>",
        ]
    for fname, (verts, faces) in (meshes or {}).items():
        lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in np.asarray(verts, float)]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces, int)]
        (folder / fname).write_text("\n".join(lines) + "\n")
        parts += [
            f'  <shape type="obj" id="{Path(fname).stem}">',
            f'    <string name="filename" value="{fname}"/>',
            '    <boolean name="face_normals" value="true"/>',
            '    <bsdf type="diffuse"/>',
            "  </shape>",
        ]
    parts.append("</scene>")
    path = folder / f"{name}.xml"
    path.write_text("\n".join(parts) + "\n")
    return path


def test_write_scene_round_trip(tmp_path):
    path = write_scene(
        tmp_path,
        origin=(0, 3, -6),
        target=(0, 0, 0),
        shapes=[ground(20.0), box((-1, 0, -1), (1, 2, 1))],
        width=40,
        height=30,
    )
    s = scenes.load(str(path))
    assert (s.width, s.height) == (40, 30)
    assert s.light.kind == "directional"
    lo, hi = s.bounds()
    np.testing.assert_allclose(lo, [-10, 0, -10], atol=1e-5)
    np.testing.assert_allclose(hi, [10, 2, 10], atol=1e-5)
