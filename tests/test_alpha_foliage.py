"""The alpha-foliage scene family (scenes.catalogue.alpha_foliage): alpha-tested leaf cards in
distance bands, its leaf texture and its glTF MASK material."""

from __future__ import annotations

import io
import math

import numpy as np
import pygltflib
import pytest
from raster_oracle.scenes.catalogue.alpha_foliage import (
    BANDS,
    CUTOFF,
    EYE,
    LAYERS,
    alpha_foliage,
    band_edges,
    leaf_cards,
    leaf_texture,
)
from raster_oracle.scenes.shading.alpha_mips import box_mips, nvtt_alpha_test_coverage


def _doc(glb: bytes):
    return pygltflib.GLTF2.load_from_bytes(glb)


def test_bands_span_2_to_200_m():
    edges = band_edges()
    assert edges[0] == 2.0 and edges[-1] == pytest.approx(200.0)
    assert np.allclose(edges[1:] / edges[:-1], 100 ** (1 / BANDS))
    v, f, nrm, uv, band = leaf_cards(np.random.default_rng(3), 1000, aspect=16 / 9)
    assert v.shape == (4000, 3) and f.shape == (2000, 3) and uv.shape == (4000, 2)
    centre = v.reshape(-1, 4, 3).mean(1)
    depth = centre[:, 2] - EYE[2]
    for k in range(BANDS):  # an equal share in each band, within its edges
        mine = depth[band == k]
        assert len(mine) == 200
        assert np.all((mine >= edges[k] - 1e-9) & (mine <= edges[k + 1] + 1e-9))
    assert depth.min() < 2.2 and depth.max() > 180.0
    # unit normals, facing the eye (the winding's side)
    assert np.allclose(np.linalg.norm(nrm, axis=1), 1.0)
    assert np.all(np.sum(nrm * (EYE - np.repeat(centre, 4, 0)), 1) > 0)


@pytest.mark.parametrize("n", [1000, 50000])
def test_depth_complexity_does_not_depend_on_n(n):
    # a card's half size is kappa x its distance: the cards' angular area in a band's column
    # adds up to LAYERS columns whatever n
    v, _, _, _, band = leaf_cards(np.random.default_rng(5), n, aspect=16 / 9)
    q = v.reshape(-1, 4, 3)
    half = np.linalg.norm(q[:, 1] - q[:, 0], axis=1) / 2
    depth = q.mean(1)[:, 2] - EYE[2]
    ang = (2 * half / depth) ** 2
    v_ang = math.radians(18.0)
    h_ang = math.atan(math.tan(v_ang) * 16 / 9) * 1.05
    column = (2 * h_ang / BANDS) * (2 * v_ang)
    for k in range(BANDS):
        assert ang[band == k].sum() / column == pytest.approx(LAYERS, rel=1e-9)


def test_texture_alpha_has_thin_features_and_tiles():
    rgba = leaf_texture()
    a = rgba[..., 3]
    assert rgba.shape == (256, 256, 4) and a.min() == 0.0 and a.max() == 1.0
    base = nvtt_alpha_test_coverage(a, CUTOFF)
    assert 0.25 < base < 0.5
    # box mips average the stems, petioles and serrations away: at 32 texels a texel
    # (level 5) less than two thirds of the foliage passes the test, at level 6 none
    box = box_mips(a)
    assert nvtt_alpha_test_coverage(box[5], CUTOFF) < 2 / 3 * base
    assert nvtt_alpha_test_coverage(box[6], CUTOFF) == 0.0
    # seamless: the step across the wrap is no larger than steps inside the tile
    inner = np.abs(np.diff(a, axis=1)).max(axis=0).max()
    assert np.abs(a[:, 0] - a[:, -1]).max() <= inner
    assert np.abs(a[0, :] - a[-1, :]).max() <= np.abs(np.diff(a, axis=0)).max()


def test_scene_is_glb_with_a_mask_material():
    glb = alpha_foliage(160, 90, n=200)
    doc = _doc(glb)
    mat = doc.materials[0]
    assert mat.alphaMode == "MASK" and mat.alphaCutoff == 0.5 and mat.doubleSided
    assert doc.samplers[0].wrapS == 10497 and doc.samplers[0].minFilter == 9987
    prim = doc.meshes[0].primitives[0]
    assert doc.accessors[prim.attributes.POSITION].count == 800
    assert doc.accessors[prim.indices].count == 3 * 400
    from PIL import Image

    view = doc.bufferViews[doc.images[0].bufferView]
    blob = doc.binary_blob()
    png = blob[view.byteOffset : view.byteOffset + view.byteLength]
    with Image.open(io.BytesIO(png)) as im:
        assert im.mode == "RGBA" and im.size == (256, 256)
        alpha = np.asarray(im)[..., 3] / 255.0
    assert np.abs(alpha - leaf_texture()[..., 3]).max() <= 0.5 / 255 + 1e-12
    # the same cards without the alpha test; same inputs, same bytes; the seed matters
    opaque = _doc(alpha_foliage(160, 90, n=200, alpha=0)).materials[0]
    assert opaque.alphaMode in (None, "OPAQUE")
    assert alpha_foliage(160, 90, n=200) == glb
    assert alpha_foliage(160, 90, n=200, seed=2) != glb
    empty = _doc(alpha_foliage(160, 90, n=0))
    assert not empty.meshes
