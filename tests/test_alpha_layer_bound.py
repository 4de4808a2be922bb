"""reference.json counts the rays that stopped at the alpha layer bound (64 cut-out surfaces a
ray): none through a few cut-out cards, every camera ray through more than 64."""

from __future__ import annotations

import numpy as np
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
from raster_oracle.scenes.backend.alpha_hit import MAX_ALPHA_LAYERS
from raster_oracle.scenes.formats import gltf_write as gw

from raster_oracle import scenes

RES, SPP = 8, 4


def _stack_glb(path, cards: int) -> str:
    """``cards`` horizontal 4 x 4 m cards 0.1 m apart, each cut out everywhere (MASK,
    baseColorFactor alpha 0), seen from straight above over a 2 m wide view; the sun is
    overhead."""
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
    meshes = []
    for k in range(cards):
        y = 0.1 * k
        quad = np.array([[-2, y, -2], [2, y, -2], [2, y, 2], [-2, y, 2]], np.float32)
        meshes.append(gw.GltfMesh(f"card{k}", quad, faces, 0, np.tile([0, 1, 0], (4, 1))))
    card = {"name": "leaf", "alphaMode": "MASK", "doubleSided": True}
    card["pbrMetallicRoughness"] = {"baseColorFactor": [1, 1, 1, 0]}
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = (1, 0, 0), (0, 0, -1), (0, 1, 0)
    m[:3, 3] = (0, 0.1 * cards + 5, 0)
    camera = gw.GltfCamera(m, 0.1, 100.0, ymag=1.0, aspect=1.0, film=(RES, RES))
    data = gw.glb_bytes(
        camera=camera,
        lights=[gw.GltfLight("sun", "directional", gw.light_matrix((0, -1, 0.1)), intensity=3.0)],
        meshes=meshes,
        materials=[card],
    )
    path.write_bytes(data)
    return str(path)


def _bound_rays(path) -> tuple[int, dict]:
    loaded = scenes.load(path)
    settings = ReferenceSettings(spp=SPP, channels=("coverage", "visibility"))
    ch, stats = render_reference(loaded, settings, quiet=True)
    return stats["alpha_tested"]["rays_at_layer_bound"], ch


def test_rays_at_the_layer_bound_are_counted(tmp_path, mi):
    few, ch = _bound_rays(_stack_glb(tmp_path / "few.glb", 10))
    assert few == 0 and not np.any(ch["coverage"])  # every card cut out: the sky
    many, ch = _bound_rays(_stack_glb(tmp_path / "many.glb", MAX_ALPHA_LAYERS + 6))
    # every camera ray passes 64 cut-out cards and stops on the 65th (then seen as covered);
    # its shadow ray starts there with 5 cards above it: not at the bound
    assert many == RES * RES * SPP
    assert np.all(ch["coverage"] == 1.0)
