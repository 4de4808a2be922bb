"""The alpha of glTF ``MASK`` materials (:mod:`scenes.shading.alpha`), read from a checked
:class:`.gltf_document.GltfDocument`.

A ``MASK`` material's alpha is ``baseColorFactor[3]`` times the alpha channel of its base
colour texture (linear: glTF's sRGB transfer applies to RGB only), sampled with the texture's
sampler: its magnification filter and its wrap modes in ``s`` and ``t``, each on its own
axis. ``alphaCutoff`` defaults to 0.5. The vertex colour's alpha (``COLOR_0``,
:func:`.gltf_parts.vertex_alpha`) multiplies it: the loader marks a mask read with
``COLOR_0`` as ``vertex_alpha`` and gives its meshes without one an alpha of 1. ``OPAQUE``
materials have no mask; ``BLEND`` is refused by :func:`.gltf_parts.read_material`.
"""

from __future__ import annotations

import numpy as np

from ..shading.alpha import WRAP_CODES, AlphaMask, AlphaTable, AlphaTexture, gltf_alpha_mode
from .gltf_document import GltfDocument, as_index, as_numbers
from .gltf_parts import _image

__all__ = ["alpha_table", "read_alpha"]

#: glTF ``magFilter`` NEAREST.
_NEAREST = 9728


def _alpha_texture(d: GltfDocument, info, label: str) -> AlphaTexture:
    tex = d.doc.textures[as_index(d, info.index, d.doc.textures, f"{label} base colour")]
    wrap_s = wrap_t = "repeat"
    nearest = False
    if tex.sampler is not None:
        smp = d.doc.samplers[as_index(d, tex.sampler, d.doc.samplers, "sampler")]
        ws, wt = smp.wrapS or 10497, smp.wrapT or 10497
        for axis, code in (("wrapS", ws), ("wrapT", wt)):
            if code not in WRAP_CODES:
                d.fail(f"sampler {tex.sampler} has {axis} {code}; expected 10497, 33071, 33648")
        wrap_s, wrap_t, nearest = WRAP_CODES[ws], WRAP_CODES[wt], smp.magFilter == _NEAREST
    rgba = _image(d, tex.source, mode="RGBA")
    return AlphaTexture(rgba[..., 3].astype(np.float32), wrap_s, wrap_t, nearest)


def read_alpha(d: GltfDocument, index: int | None) -> AlphaMask | None:
    """The :class:`~scenes.shading.alpha.AlphaMask` of material ``index``, or None for an
    ``OPAQUE`` material (and for the default material)."""
    if index is None:
        return None
    mat = d.doc.materials[as_index(d, index, d.doc.materials, "material")]
    label = f"material {index} ({mat.name or 'unnamed'})"
    mode, cutoff = gltf_alpha_mode(
        {"alphaMode": mat.alphaMode, "alphaCutoff": mat.alphaCutoff}, label=label
    )
    if mode != "MASK":
        return None
    pbr = mat.pbrMetallicRoughness
    base = pbr.baseColorFactor if pbr and pbr.baseColorFactor is not None else [1.0] * 4
    factor = as_numbers(d, base, 4, f"{label} baseColorFactor", 1.0, lo=0.0)[3]
    info = pbr.baseColorTexture if pbr else None
    texture = None if info is None else _alpha_texture(d, info, label)
    return AlphaMask(factor=float(factor), texture=texture, cutoff=cutoff, name=label)


def alpha_table(masks: list, shape_materials: dict, shape_names: list[str]) -> AlphaTable | None:
    """The :class:`~scenes.shading.alpha.AlphaTable` of shapes ``shape_names`` (loaded order)
    whose materials (``shape_materials``: shape -> material slot) have ``masks`` (per slot,
    None for opaque), or None when no shape is alpha-tested."""
    used = sorted({i for i, m in enumerate(masks) if m is not None})
    if not used:
        return None
    slot = {m: k for k, m in enumerate(used)}
    table = [slot.get(shape_materials.get(n, -1), -1) for n in shape_names]
    if all(t < 0 for t in table):
        return None
    return AlphaTable([masks[i] for i in used], np.asarray(table, np.int32))
