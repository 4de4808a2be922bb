"""Export a scene for an external engine: meshes as PLY, exact camera and light matrices.

``export(loaded, out_dir)`` writes

- ``meshes/<shape>.ply``: world-space triangles (binary little-endian PLY; analytic spheres
  and cylinders are tessellated finely: 512 x 256 and 512 segments),
- ``camera.json``: world-to-view and projection matrices in the OpenGL and Direct3D
  conventions, fov, resolution, near/far and the pixel-centre convention, and ``sequence``:
  the path, frame and object transforms this export was made for, and ``previous``: the
  camera of the frame before (frame -1 for frame 0), for the engine's motion vectors,
- ``lights.json``: every usable light with its radiometric quantity (an area light with its
  shape, size, orientation and radiance: :meth:`scenes.lights.Light.area_json`),
- ``materials.json``: the diffuse albedo of every shape and the scene-wide specular lobe,
- ``scene.xml``: a Mitsuba scene built from the files above, so the export can be loaded back
  (``raster-oracle reference out/scene.xml``) and compared with the original,
- ``export.json``: what it was exported for: the scene, size and light, and a pointer to the
  sequence in ``camera.json`` (``scenes.inputs`` reads both back: scoring an export
  uses them),
- ``cameras/frame_NNN.json``: with a camera path, every frame's ``camera.json`` (what an
  engine renders the path's frames from).

A glTF scene (``loaded.pbr``) writes ``scene.glb`` instead of ``scene.xml`` (its meshes,
camera, KHR lights and metallic-roughness materials: :mod:`scenes.formats.gltf_export`), and its
``materials.json`` records the glTF material of every shape.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .. import backend
from ..geometry.tessellation import shape_mesh
from ..lights import AREA_SHAPES

__all__ = ["EXPORT_SCENE_FILES", "export", "export_scene_file"]

#: The scene file of an export folder: Mitsuba XML, or GLB for a glTF scene.
EXPORT_SCENE_FILES = ("scene.xml", "scene.glb")


def export_scene_file(folder) -> Path | None:
    """The scene file (``scene.xml`` or ``scene.glb``) of an export folder, or None."""
    for name in EXPORT_SCENE_FILES:
        if (Path(folder) / name).is_file():
            return Path(folder) / name
    return None


def _albedo(mi, shape) -> list[float]:
    params = mi.traverse(shape.bsdf())
    for key in params.keys():
        if key.endswith("reflectance.value") or key.endswith("base_color.value"):
            val = np.array(params[key], dtype=np.float64).ravel()
            return [float(c) for c in np.broadcast_to(val, (3,))]
    return [0.5, 0.5, 0.5]


def _write_ply(path: Path, verts: np.ndarray, faces: np.ndarray) -> None:
    from plyfile import PlyData, PlyElement

    vert = np.empty(len(verts), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    vert["x"], vert["y"], vert["z"] = verts.astype(np.float32).T
    face = np.empty(len(faces), dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = faces.astype(np.int32)
    PlyData(
        [PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")], byte_order="<"
    ).write(str(path))


def _floats(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _area_light_xml(lt, i: int, albedo) -> str:
    """A Mitsuba shape with an ``area`` emitter for area light ``lt`` (:mod:`scenes.lights`):
    a rectangle or disk whose ``to_world`` columns are its half axes, unit normal and centre,
    or a sphere."""
    bsdf = f'<bsdf type="diffuse"><rgb name="reflectance" value="{_floats(albedo)}"/></bsdf>'
    radiance = _floats(lt.radiance)
    emitter = f'<emitter type="area"><rgb name="radiance" value="{radiance}"/></emitter>'
    if lt.area == "sphere":
        geometry = (
            f'<point name="center" value="{_floats(lt.position)}"/>'
            f'<float name="radius" value="{float(lt.radius)!r}"/>'
        )
    else:
        m = np.eye(4)
        m[:3, 0], m[:3, 1] = lt.axes
        m[:3, 2], m[:3, 3] = lt.direction, lt.position
        geometry = f'<transform name="to_world"><matrix value="{_floats(m)}"/></transform>'
    return f'  <shape type="{lt.area}" id="light_{i}">{geometry}{bsdf}{emitter}</shape>'


def _scene_xml(loaded, shapes: list[tuple[str, str, list[float]]], area_shapes=()) -> str:
    """The export's ``scene.xml``; ``area_shapes``: names of the shapes that carry an area
    light, written with their emitter instead of as PLY meshes."""
    cam = loaded.camera
    lines = ['<scene version="3.0.0">']
    kind = cam.kind
    lines.append(f'  <sensor type="{kind}">')
    if kind == "perspective":
        lines.append(f'    <float name="fov" value="{cam.fov_x!r}"/>')
        lines.append('    <string name="fov_axis" value="x"/>')
    lines.append(f'    <float name="near_clip" value="{cam.near!r}"/>')
    lines.append(f'    <float name="far_clip" value="{cam.far!r}"/>')
    lines.append(
        f'    <transform name="to_world"><matrix value="{_floats(cam.to_world)}"/></transform>'
    )
    lines.append('    <film type="hdrfilm">')
    lines.append(f'      <integer name="width" value="{cam.width}"/>')
    lines.append(f'      <integer name="height" value="{cam.height}"/>')
    lines.append('      <rfilter type="box"/>')
    lines.append('      <string name="component_format" value="float32"/>')
    lines.append("    </film>\n  </sensor>")
    albedos = {name: albedo for name, _, albedo in shapes}
    for i, lt in enumerate(loaded.lights):
        rgb = _floats(lt.color)
        if lt.is_area:
            lines.append(_area_light_xml(lt, i, albedos.get(lt.name, [0.0, 0.0, 0.0])))
        elif lt.kind == "directional":
            lines.append(
                f'  <emitter type="directional" id="light_{i}">'
                f'<vector name="direction" value="{_floats(lt.direction)}"/>'
                f'<rgb name="irradiance" value="{rgb}"/></emitter>'
            )
        elif lt.kind == "point":
            lines.append(
                f'  <emitter type="point" id="light_{i}">'
                f'<point name="position" value="{_floats(lt.position)}"/>'
                f'<rgb name="intensity" value="{rgb}"/></emitter>'
            )
        else:
            d = np.asarray(lt.direction)
            up = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
            target = np.asarray(lt.position) + d
            lines.append(
                f'  <emitter type="spot" id="light_{i}"><transform name="to_world">'
                f'<lookat origin="{_floats(lt.position)}" target="{_floats(target)}" '
                f'up="{_floats(up)}"/></transform>'
                f'<rgb name="intensity" value="{rgb}"/>'
                f'<float name="cutoff_angle" value="{lt.cutoff_angle!r}"/>'
                f'<float name="beam_width" value="{lt.beam_width!r}"/></emitter>'
            )
    for name, rel, albedo in shapes:
        if name in area_shapes:
            continue
        lines.append(
            f'  <shape type="ply" id={quoteattr(name)}>'
            f'<string name="filename" value={quoteattr(rel)}/>'
            '<boolean name="face_normals" value="true"/>'
            '<bsdf type="twosided"><bsdf type="diffuse">'
            f'<rgb name="reflectance" value="{_floats(albedo)}"/></bsdf></bsdf>'
            "</shape>"
        )
    lines.append("</scene>\n")
    return "\n".join(lines)


def _write_export_record(tmp: Path, loaded) -> None:
    """``export.json`` (see the module docstring) and, along a camera path, every frame's
    camera. The sequence is recorded once, in ``camera.json``'s ``sequence``; ``export.json``
    points at it (``scenes.inputs.read_export_record`` reads both)."""
    record = {
        "schema": "raster-oracle/export/2",
        "scene": loaded.name,
        "width": loaded.width,
        "height": loaded.height,
        "light": loaded.light_index,
        "sequence": "camera.json#/sequence",
    }
    (tmp / "export.json").write_text(json.dumps(record, indent=2))
    if loaded.camera_path is None:
        return
    (tmp / "cameras").mkdir()
    for k in range(loaded.n_frames):
        at = loaded.with_frame(k, path=loaded.camera_path, n_frames=loaded.n_frames)
        cam = {**at.camera.to_json(), "sequence": _sequence(at)}
        cam["previous"] = _previous_camera(at)
        (tmp / "cameras" / f"frame_{k:03d}.json").write_text(json.dumps(cam, indent=2))


def _previous_camera(loaded) -> dict:
    """The camera of the frame before ``loaded``'s (frame -1 for frame 0: the paths are
    defined there, and the reference's motion of frame 0 is against it), what an engine's
    velocity buffer of this frame is computed with."""
    return loaded.previous().camera.to_json()


def _sequence(loaded) -> dict:
    """The frame of the sequence a camera record was made for (engines render the same
    frame): its camera and light paths or camera file, and the moving objects' transforms."""
    return {
        "camera_path": loaded.camera_path,
        "light_path": loaded.light_path,
        "camera_file": loaded.camera_file,
        "frame": loaded.frame,
        "n_frames": loaded.n_frames,
        "object_paths": {k: dict(v) for k, v in loaded.object_motion.items()} or None,
        "object_transforms": {k: loaded.shape_transform(k).tolist() for k in loaded.object_motion}
        or None,
    }


def export(loaded, out_dir: str | Path) -> dict:
    """Write the export files to ``out_dir`` (created if needed; each file renamed into place).

    Returns a summary record (files written, triangle counts).
    """
    mi = backend.mitsuba()
    out_dir = Path(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        (tmp / "meshes").mkdir()
        shapes, summary, area_shapes = [], {"shapes": {}}, set()
        for idx, sh in enumerate(loaded.mi_scene.shapes()):
            name = loaded.shape_names[idx] or f"shape_{idx}"
            safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)[:100]
            rel = f"meshes/{idx:04d}_{safe}.ply"
            verts, faces = shape_mesh(mi, sh)
            _write_ply(tmp / rel, verts, faces)
            albedo = _albedo(mi, sh)
            shapes.append((name, rel, albedo))
            summary["shapes"][name] = {
                "file": rel,
                "triangles": int(len(faces)),
                "albedo": albedo,
                "id": idx,
                "source_type": sh.class_name(),
            }
            if sh.is_emitter() and sh.class_name().lower() in AREA_SHAPES:
                summary["shapes"][name]["area_light"] = True  # lights.json describes it
                area_shapes.add(name)
        camera = loaded.camera.to_json()
        # the frame of the sequence this export was made for (engines render the same frame)
        camera["sequence"] = _sequence(loaded)
        camera["previous"] = _previous_camera(loaded)
        (tmp / "camera.json").write_text(json.dumps(camera, indent=2))
        lights = {"chosen": loaded.light_index, "lights": [lt.to_json() for lt in loaded.lights]}
        if loaded.pbr is not None:  # with each light's glTF node matrix
            from .gltf_export import light_records

            lights["lights"] = light_records(loaded)
        (tmp / "lights.json").write_text(json.dumps(lights, indent=2))
        materials = {
            "model": "two-sided diffuse (see scenes.shading.phong)",
            # the scene-wide Blinn-Phong lobe (ks 0: none; the glossy scene has one)
            "specular": loaded.specular.to_json(),
            "shapes": summary["shapes"],
        }
        if (
            loaded.pbr is not None
        ):  # a glTF scene: its materials and a GLB (scenes.formats.gltf_export)
            from .gltf_export import materials_record, scene_glb

            materials = materials_record(loaded, summary["shapes"])
            (tmp / "scene.glb").write_bytes(scene_glb(loaded))
        else:
            (tmp / "scene.xml").write_text(_scene_xml(loaded, shapes, area_shapes))
        (tmp / "materials.json").write_text(json.dumps(materials, indent=2))
        _write_export_record(tmp, loaded)
        summary["scene"] = loaded.provenance()
        out_dir.mkdir(exist_ok=True)
        (out_dir / "meshes").mkdir(exist_ok=True)
        if (tmp / "cameras").is_dir():
            (out_dir / "cameras").mkdir(exist_ok=True)
        for f in sorted(tmp.rglob("*")):
            if f.is_file():
                os.replace(f, out_dir / f.relative_to(tmp))
        shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return summary
