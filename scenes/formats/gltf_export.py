"""``export`` of a glTF scene: its materials record and a GLB an engine (or the oracle) reads.

:func:`scene_glb` writes the loaded scene back as one GLB: world-space meshes (with their
normals, ``TEXCOORD_0`` and tangents), the camera of the export (the frame's view, the
film's aspect, glTF axes: ``node = to_world @ diag(-1, 1, -1, 1)``), every light as a
KHR_lights_punctual light on a node whose -Z is the light's direction (colour already
multiplied by the intensity, so ``intensity`` is 1), and the metallic-roughness materials with
their textures (8-bit PNG; colour textures encoded back to sRGB). Alpha-tested materials
(``loaded.alpha``) are written ``MASK`` with their ``alphaCutoff`` and ``baseColorFactor``
alpha, their base colour texture as RGBA with the alpha the truth tests (linear). Loading the
GLB gives the same colour truth as the scene it came from.
"""

from __future__ import annotations

import math

import numpy as np

from .. import backend
from ..base.display import srgb_encode
from . import gltf_write
from .gltf_write import GltfCamera, GltfLight, GltfMesh, glb_bytes, light_matrix, png_bytes

__all__ = ["light_records", "materials_record", "scene_glb"]


def materials_record(loaded, shapes: dict) -> dict:
    """``materials.json`` of a glTF scene: the shading model and, per shape, its material
    (factors and texture indices of :class:`scenes.shading.materials.PbrMaterial`)."""
    from ..shading.pbr import SHADING_MODEL

    pbr = loaded.pbr
    table = loaded.alpha
    out = {}
    for name, rec in shapes.items():
        mat = pbr.materials[int(pbr.shape_material[rec["id"]])]
        out[name] = {**rec, "albedo": list(mat.base_color), "pbr": mat.to_json()}
        m = -1 if table is None else int(table.shape_mask[rec["id"]])
        if m >= 0:  # glTF MASK: the alpha test the truth applies
            out[name]["alpha"] = table.masks[m].to_json()
    return {
        "model": SHADING_MODEL,
        "brdf": "glTF 2.0 Appendix B: GGX D (alpha = roughness^2), height-correlated Smith V, "
        "Schlick Fresnel, Lambert diffuse, dielectric F0 0.04; radiance = f E max(0, n.l) "
        "+ emissive",
        "textures": pbr.to_json()["textures"],
        "shapes": out,
    }


def _light(lt) -> GltfLight:
    if lt.kind == "directional":
        m = light_matrix(lt.direction)
    elif lt.kind == "point":
        m = light_matrix(None, lt.position)
    else:
        m = light_matrix(lt.direction, lt.position)
    rng = lt.range if lt.model == "gltf" and lt.range > 0 else None
    return GltfLight(
        lt.name or lt.kind,
        lt.kind,
        m,
        color=tuple(float(c) for c in lt.color),
        intensity=1.0,
        range=rng,
        inner=math.radians(min(lt.beam_width, lt.cutoff_angle)),
        outer=math.radians(lt.cutoff_angle),
    )


def light_records(loaded) -> list[dict]:
    """``lights.json``'s records of a glTF scene: each light's record with ``to_world_gltf``,
    the world matrix of its node in ``scene.glb`` (column vectors; the light travels along
    its -Z column, a point or spot light sits at its translation)."""
    out = []
    for lt in loaded.lights:
        rec = lt.to_json()
        rec["to_world_gltf"] = np.asarray(_light(lt).matrix, dtype=np.float64).tolist()
        out.append(rec)
    return out


def _camera(cam) -> GltfCamera:
    m = np.asarray(cam.to_world, dtype=np.float64)
    if cam.kind == "perspective":
        yfov = math.radians(cam.fov_y)
        return GltfCamera(
            m @ gltf_write.GL_TO_MI,
            cam.near,
            cam.far,
            yfov=yfov,
            aspect=cam.aspect,
            film=(cam.width, cam.height),
        )
    hw, hh = cam.half_extent()
    frame = m.copy()
    frame[:3, 0] /= np.linalg.norm(frame[:3, 0])
    frame[:3, 1] /= np.linalg.norm(frame[:3, 1])
    return GltfCamera(
        frame @ gltf_write.GL_TO_MI,
        cam.near,
        cam.far,
        ymag=hh,
        aspect=hw / hh,
        film=(cam.width, cam.height),
    )


def _masks_by_material(loaded) -> dict:
    """Material index -> its :class:`scenes.shading.alpha.AlphaMask` (alpha-tested
    materials of ``loaded``, through the shapes that use them)."""
    table, pbr = loaded.alpha, loaded.pbr
    if table is None:
        return {}
    return {
        int(pbr.shape_material[idx]): table.masks[m]
        for idx, m in enumerate(table.shape_mask)
        if m >= 0
    }


def _texture_dicts(pbr, masks: dict):
    images, textures, samplers = [], [], []
    wrap = {"repeat": 10497, "clamp": 33071, "mirror": 33648}
    # a MASK material's base colour texture carries the alpha the truth tests
    alpha = {
        pbr.materials[k].base_color_texture: m.texture.alpha
        for k, m in masks.items()
        if m.texture is not None and pbr.materials[k].base_color_texture >= 0
    }
    for k, tex in enumerate(pbr.textures):
        img = tex.image[..., :3] if tex.image.shape[-1] >= 3 else np.repeat(tex.image, 3, -1)
        img = srgb_encode(np.clip(img.astype(np.float64), 0.0, 1.0)) if tex.srgb else img
        if k in alpha and alpha[k].shape == img.shape[:2]:
            img = np.concatenate([img, alpha[k][..., None]], -1)
        images.append(png_bytes(img))
        samplers.append(
            {
                "magFilter": 9728 if tex.nearest else 9729,
                "wrapS": wrap[tex.wrap],
                "wrapT": wrap[tex.wrap],
            }
        )
        textures.append({"source": len(images) - 1, "sampler": len(samplers) - 1})
    return images, textures, samplers


def _material_dict(mat, mask=None) -> dict:
    pbr = {
        "baseColorFactor": [*mat.base_color, 1.0 if mask is None else float(mask.factor)],
        "metallicFactor": mat.metallic,
        "roughnessFactor": mat.roughness,
    }
    if mat.base_color_texture >= 0:
        pbr["baseColorTexture"] = {"index": mat.base_color_texture}
    if mat.metallic_roughness_texture >= 0:
        pbr["metallicRoughnessTexture"] = {"index": mat.metallic_roughness_texture}
    out = {"name": mat.name, "pbrMetallicRoughness": pbr, "doubleSided": mat.double_sided}
    if any(mat.emissive):
        out["emissiveFactor"] = list(mat.emissive)
    if mat.emissive_texture >= 0:
        out["emissiveTexture"] = {"index": mat.emissive_texture}
    if mat.normal_texture >= 0:
        out["normalTexture"] = {"index": mat.normal_texture, "scale": mat.normal_scale}
    if mask is not None:
        out.update(alphaMode="MASK", alphaCutoff=float(mask.cutoff))
    return out


def scene_glb(loaded) -> bytes:
    """The GLB of a loaded glTF scene (see the module text)."""
    mi = backend.mitsuba()
    pbr = loaded.pbr
    meshes = []
    for idx, sh in enumerate(loaded.mi_scene.shapes()):
        p = mi.traverse(sh)
        keys = set(p.keys())
        v = np.array(p["vertex_positions"], dtype=np.float32).reshape(-1, 3)
        f = np.array(p["faces"], dtype=np.uint32).reshape(-1, 3)
        mesh = GltfMesh(loaded.shape_names[idx], v, f, int(pbr.shape_material[idx]))
        if "vertex_normals" in keys:
            mesh.normals = np.array(p["vertex_normals"], dtype=np.float32).reshape(-1, 3)
        if "vertex_texcoords" in keys:
            mesh.texcoords = np.array(p["vertex_texcoords"], dtype=np.float32).reshape(-1, 2)
        if "vertex_tangent" in keys:
            t3 = np.array(p["vertex_tangent"], dtype=np.float32).reshape(-1, 3)
            tw = np.array(p["vertex_tangent_w"], dtype=np.float32).reshape(-1, 1)
            if np.any(t3):
                mesh.tangents = np.concatenate([t3, tw], axis=1)
        meshes.append(mesh)
    masks = _masks_by_material(loaded)
    images, textures, samplers = _texture_dicts(pbr, masks)
    return glb_bytes(
        camera=_camera(loaded.camera),
        lights=[_light(lt) for lt in loaded.lights],
        meshes=meshes,
        materials=[_material_dict(m, masks.get(k)) for k, m in enumerate(pbr.materials)],
        images=images,
        textures=textures,
        samplers=samplers,
    )
