"""Coherent shadow maps: many precomputed orthographic depth maps over the bounding sphere,
numbered along a Hilbert curve, with the paper's lossless visibility compression.

The scene is treated as the paper's one rigid object: ``directions`` orthographic maps of it
are rendered (once, a precomputation) from directions spread over the sphere of directions,
each map a square of side ``2R`` (``R`` the radius of the scene's bounding sphere) looking
along its direction, depth normalized to ``[0, 1]`` across the sphere's diameter.

- Directions: a ``g x g`` grid (``g = sqrt(directions)``) over ``[0, 1]^2``, ``u = phi / 2pi``,
  ``v = (1 - cos(theta)) / 2`` (equal-area: every cell covers ``4 pi / N`` steradians; theta
  from +Y), each cell's centre giving the map's travel direction. Map ids run along the
  Hilbert curve over the grid (:mod:`.directions`, :mod:`.hilbert`): consecutive ids,
  neighbouring directions.
- Lookup per receiver (the paper's shader): its light travel direction (the directional
  light's direction; from a point light to the receiver) -> ``(u, v)`` -> the id texture
  (``g x g``) -> that map's matrix (a ``4 g x 4 g`` matrix texture in the paper) -> a point
  depth test ``z - bias <= stored``. Receivers outside the map's square are lit (the sphere
  holds every caster). Point lights: a stored depth nearer than the light's own depth in the
  map does not shadow (the light is inside the sphere); a caster hidden behind such a
  surface is then missed (the paper's objects lie outside the light) (:mod:`.shading`).
- Compression (the paper's lossless scheme): a texel's depth test gives the same answer for
  any stored value ``c`` in ``[s1, h)``, ``s1`` the stored first depth and ``h`` the smallest
  compare reference (``z - bias``) above ``s1`` of a receiver the texel answers for: those
  on the first surface stay lit (or acned), those on or behind the second stay shadowed.
  ``lossless="texel_centre"`` (the paper's criterion) takes the surfaces at the texel
  centre; ``"footprint"`` every point of the first and second surfaces' planes over the
  whole texel (their depth spread to the texel corners, from the hit normals): then a map
  that acnes a surface anywhere in a texel cannot share that texel, and receivers in the
  image get exactly the uncompressed answer. Consecutive maps, in a given order, whose
  intervals intersect share one value (greedy runs, optimal for interval runs); the stored
  value is the run's largest ``s1``. The ratio ``N R^2 / runs`` is reported for the Hilbert
  order, row-major (rows of constant theta, periodic in phi) and column-major order of the
  direction grid, and a seeded random order; the Hilbert-decompressed maps are shaded again
  and the receivers whose visibility differs counted (``decompressed_mismatches``).

Error sources: direction quantization (spacing about ``sqrt(4 pi / N)``), map resolution
(texel ``2R / r``) and bias.

Implementation: the maps' rays, their intervals and the run compression of every ordering
run in Dr.Jit kernels (:mod:`.surfaces`, :mod:`.kernels`, ray descriptions from
:mod:`.rays`), asynchronously while NumPy looks the receivers up; ``tests/
_coherent_reference.py`` holds their NumPy references (the tests compare the bytes).

References
----------
.. [1] T. Ritschel, T. Grosch, J. Kautz, S. Mueller, "Interactive Illumination with Coherent
   Shadow Maps", EGSR 2007. DOI: 10.2312/EGWR/EGSR07/061-072
.. [2] X. Tijsen (xaviert.be), "Coherent Shadow Maps: Uncompressed Algorithm", 2010 (lookup:
   direction -> id texture -> matrix texture -> depth test).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ...scenes.base.records import jsonable
from .. import params as _params
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..params import param
from ..result import ModelResult, model_result
from .directions import Projections, map_directions
from .kernels import launch_compression, launch_rows
from .shading import DIRECTIONAL_ROWS, direction_error, lookup, project, shade
from .surfaces import first_surface, render_intervals, stored_depth

__all__ = ["ORDERINGS", "CoherentParams", "run"]

NAME = "coherent-shadow-map"

#: Texture lookups per receiver: one id texel, four float4 texels of the matrix, one depth.
LOOKUPS_PER_RECEIVER = 6

#: Bytes per id texel (16-bit ids: at most 65536 maps).
ID_TEXEL_BYTES = 2

#: Bytes of a stored run in the compressed maps: a float32 depth and a 16-bit map index
#: where the run ends.
RUN_BYTES = 6

#: The map orderings whose compression is reported.
ORDERINGS = ("hilbert", "row_major", "column_major", "random")

#: Most texels (directions x resolution^2) held for compression: about 0.6 GB of work
#: arrays (float32 bounds, run values, decoded maps, run starts).
MAX_COMPRESSED_TEXELS = 1 << 25


def _power_of_four(n: int) -> bool:
    return n >= 1 and (n & (n - 1)) == 0 and (n.bit_length() - 1) % 2 == 0


@dataclass(frozen=True)
class CoherentParams:
    """Parameters of ``coherent-shadow-map``."""

    directions: int = param(
        1024,
        source="1024 maps: the CSM re-implementation of the seed blog (xaviert.be, 'Stanford "
        "Bunny, 1024 shadow maps'); Ritschel et al. use about a thousand (count unverified)",
        help="number of maps N, a power of 4 (the id texture is sqrt(N) x sqrt(N) and the "
        "Hilbert curve needs a power-of-two side); direction spacing about sqrt(4 pi / N)",
        lo=4,
        hi=65536,
    )
    resolution: int = param(
        128,
        source="raster-oracle default (the paper's map size is not verified here; "
        "N x r^2 two-surface rays bound the precomputation)",
        help="texels per side r of every map (texel = 2R / r, R the bounding sphere radius)",
        lo=8,
        hi=4096,
    )
    bias: float = param(
        0.005,
        source="TheRealMJP/Shadows Bias 0.005 (the paper gives none)",
        help="constant bias subtracted from the receiver's normalized depth (fraction of the "
        "bounding sphere's diameter) before the depth test",
        lo=0.0,
        hi=1.0,
    )
    normal_offset: float = param(
        0.0,
        source="TheRealMJP/Shadows OffsetScale 0",
        help="normal offset in texels: the lookup moves by normal_offset * texel * "
        "saturate(1 - N.L) * N",
        lo=0.0,
        hi=1e3,
    )
    compression: bool = param(
        True,
        source="Ritschel et al. 2007 (lossless compression)",
        help="render every map with its first and second surfaces and report the lossless "
        "compression ratio per ordering (off: only the maps receivers look up, first surface)",
    )
    lossless: str = param(
        "footprint",
        source="raster-oracle default (issue 10: decompressed visibility equals uncompressed); "
        "texel_centre is the paper's criterion",
        help="what compression keeps exact: footprint = every receiver on the planes of a "
        "texel's first and second surfaces anywhere in the texel (acne included), "
        "texel_centre = surfaces at texel centres only (far higher ratios; image receivers "
        "may differ: decompressed_mismatches)",
        choices=("footprint", "texel_centre"),
    )
    seed: int = param(
        0,
        source="raster-oracle default",
        help="seed of the random map ordering compared against the Hilbert ordering",
        lo=0,
        hi=2**31 - 1,
    )

    def check(self, technique: str) -> None:
        """Cross-field validation (raises :class:`ModelError`)."""
        if not _power_of_four(int(self.directions)):
            raise ModelError(
                f"{technique}: parameter directions must be a power of 4 (4, 16, 64, 256, "
                f"1024, 4096, 16384, 65536), got {self.directions}"
            )


def run(scene, params: CoherentParams | None = None, **kwargs) -> ModelResult:
    """Run ``coherent-shadow-map`` on a loaded scene; see :func:`raster_models.run`.

    Outputs (``(H, W)`` float32): ``visibility`` (1 = lit), ``map_id`` (the map a receiver
    looks up, -1 elsewhere), ``direction_error_deg`` (angle between the receiver's light
    direction and its map's direction), ``uncovered`` (receivers outside their map).
    """
    t0 = time.perf_counter()
    p = params or _params.make(NAME, CoherentParams, kwargs)
    n, r = int(p.directions), int(p.resolution)
    if p.compression and n * r * r > MAX_COMPRESSED_TEXELS:
        raise ModelError(
            f"{NAME}: compression needs every map in memory: directions x resolution^2 = "
            f"{n * r * r} texels is above {MAX_COMPRESSED_TEXELS}; lower them or set "
            "compression=false"
        )
    gbuf = trace_gbuffer(scene)
    dirs, id_tex = map_directions(n)
    projs = Projections(scene, dirs, r)
    bounds = None
    if p.compression:
        # The map kernels run asynchronously while NumPy looks the receivers up and
        # projects them into their maps below.
        footprint = p.lossless == "footprint"
        bounds = render_intervals(scene, projs, np.arange(n), p.bias, footprint=footprint)
    rec = np.nonzero(gbuf.receiver)[0]
    pos = gbuf.position[rec]
    # Which maps the receivers look up (sorted distinct ids).
    w, sel, shared = lookup(scene, pos, id_tex)
    used = sel[:1].copy() if shared else np.nonzero(np.bincount(sel, minlength=n))[0]
    pending = _schedule_maps(scene, projs, used, id_tex, bounds, seed=p.seed)
    images, records, err_rec = _look_up(scene, gbuf, projs, p, rec, pos, (w, sel, shared), used)
    maps, compression = pending()
    vis, mismatches = _visibility(gbuf, rec, records, maps)
    outputs = {"visibility": gbuf.image(vis)}  # 0 or 1 only
    outputs.update({k: gbuf.image(v) for k, v in images.items()})
    cost = _cost(p, compression, mismatches, n_receivers=len(rec))
    diagnostics = {
        "light": scene.light.to_json(),
        "sphere": {"centre": projs.centre.tolist(), "radius": projs.radius},
        "texel_world_size": 2.0 * projs.radius / r,
        "direction_spacing_deg": math.degrees(math.sqrt(4.0 * math.pi / n)),
        "maps_looked_up": int(len(used)),
        "direction_error_deg_mean": float(err_rec.mean()) if len(rec) else 0.0,
        "direction_error_deg_max": float(err_rec.max()) if len(rec) else 0.0,
        "receivers": int(len(rec)),
        "uncovered_receivers": int(np.count_nonzero(images["uncovered"])),
    }
    return model_result(
        NAME,
        scene,
        outputs=outputs,
        cost=jsonable(cost),
        diagnostics=diagnostics,
        params=_params.as_dict(p),
        t0=t0,
    )


def _map_orders(id_tex: np.ndarray, *, seed: int) -> dict:
    """The storage orders of :data:`ORDERINGS`: permutations of the map ids."""
    n = id_tex.size
    rng = np.random.default_rng(seed)
    return {
        "hilbert": np.arange(n),
        # Row-major over the direction grid (row v, then column u): the ids of the id
        # texture read row by row.
        "row_major": id_tex.ravel(),
        # Column-major (column u, then row v): rows along theta, a pole-to-pole jump at
        # every column.
        "column_major": id_tex.T.ravel(),
        "random": rng.permutation(n),
    }


def _schedule_maps(scene, projs, used: np.ndarray, id_tex: np.ndarray, bounds, *, seed: int):
    """The maps the receivers read: with ``bounds`` (the visibility intervals of every map,
    compression on) the compression kernels of every ordering are scheduled and the function
    returned waits for them; without, the first surfaces of the maps ``used`` are rendered.

    The function returns ``(maps, compression)``: ``maps`` the stored depths of each used
    map id, ``{"uncompressed": {m: (R^2,) float32}}`` and with compression
    ``"decompressed"`` (the Hilbert-decoded maps); ``compression`` the runs per ordering
    (``None`` without)."""
    if bounds is None:
        stored = stored_depth(first_surface(scene, projs, used))
        maps = {"uncompressed": {int(m): stored[i] for i, m in enumerate(used)}}
        return lambda: (maps, None)
    lo, hi = bounds
    n = id_tex.size
    orders = _map_orders(id_tex, seed=seed)
    compressed = launch_compression(
        lo, hi, n, list(orders.values()), decode=list(orders).index("hilbert"), rows=used
    )
    # Only the maps the receivers look up leave the Dr.Jit side.
    uncompressed = launch_rows(lo, used, n)

    def finish():
        counts, decoded = compressed()
        stored = uncompressed()
        maps = {
            "uncompressed": {int(m): stored[i] for i, m in enumerate(used)},
            "decompressed": {int(m): decoded[i] for i, m in enumerate(used)},
        }
        return maps, dict(zip(orders, counts, strict=True))

    return finish


def _look_up(scene, gbuf, projs, p: CoherentParams, rec, pos, looked, used):
    """The lookup images (``map_id``, ``direction_error_deg``, ``uncovered``; float32 from
    the start: values are cast on assignment, as the final conversion would), the receivers'
    records of :func:`~raster_models.coherent.shading.project` and their direction errors.
    ``looked``: ``(w, sel, shared)`` of :func:`~raster_models.coherent.shading.lookup`."""
    w, sel, shared = looked
    map_id = np.full(gbuf.size, -1.0, dtype=np.float32)
    err = np.zeros(gbuf.size, dtype=np.float32)
    uncovered = np.zeros(gbuf.size, dtype=np.float32)
    err_rec = np.zeros(0)
    records: list = []
    if len(rec):
        map_id[rec] = sel
        if shared:
            part = slice(0, DIRECTIONAL_ROWS)
            one = direction_error(
                np.ascontiguousarray(w[part]), projs.directions, np.ascontiguousarray(sel[part])
            )
            err_rec = np.full(len(rec), one[0])
        else:
            err_rec = direction_error(w, projs.directions, sel)
        err[rec] = err_rec
        records, outside = project(
            scene, gbuf, projs, rec, pos, sel, used, bias=p.bias, normal_offset=p.normal_offset
        )
        uncovered[rec] = outside
    images = {"map_id": map_id, "direction_error_deg": err, "uncovered": uncovered}
    return images, records, err_rec


def _visibility(gbuf, rec: np.ndarray, records: list, maps: dict):
    """The visibility image (float32: receivers shaded with the uncompressed maps, other
    valid pixels 0, sky 1) and the receivers whose decompressed answer differs (``None``
    without compression)."""
    vis_all = np.ones(gbuf.size, dtype=np.float32)
    vis_all[gbuf.valid] = 0.0
    mismatches = 0 if "decompressed" in maps else None
    if len(rec):
        vis = shade(records, maps, len(rec))
        vis_all[rec] = vis["uncompressed"]
        if "decompressed" in vis:
            mismatches = int(np.sum(vis["decompressed"] != vis["uncompressed"]))
    vis_all[~gbuf.valid] = 1.0
    return vis_all, mismatches


def _cost(p: CoherentParams, compression: dict | None, mismatches, *, n_receivers: int) -> dict:
    """The cost record: the compressed runs per ordering, the maps' and textures' memory,
    texels rendered, lookups per pixel."""
    n, r = int(p.directions), int(p.resolution)
    cost: dict = {}
    if compression is not None:
        cost["compression"] = {
            name: {
                "stored_values": runs,
                "ratio": float(n * r * r) / runs,
                "bytes": runs * RUN_BYTES,
            }
            for name, runs in compression.items()
        }
    cost.update(
        {
            "maps": n,
            "map_resolution": r,
            "shadow_map_bytes": int(n * r * r * 4),
            "id_texture_bytes": int(n * ID_TEXEL_BYTES),
            "matrix_texture_bytes": int(n * 16 * 4),
            "texels_rendered": int(n * r * r),
            "render_passes": n,
            "texture_lookups_per_pixel": float(LOOKUPS_PER_RECEIVER if n_receivers else 0),
            "precomputed": True,
        }
    )
    if compression is not None:
        cost["decompressed_mismatches"] = mismatches
    return cost
