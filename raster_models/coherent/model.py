"""Coherent shadow maps: many precomputed orthographic depth maps over the bounding sphere,
numbered along a Hilbert curve, with the paper's lossless visibility compression.

The scene is treated as the paper's one rigid object: ``directions`` orthographic maps of it
are rendered (once, a precomputation) from directions spread over the sphere of directions,
each map a square of side ``2R`` (``R`` the radius of the scene's bounding sphere) looking
along its direction, depth normalized to ``[0, 1]`` across the sphere's diameter.

- Directions: a ``g x g`` grid (``g = sqrt(directions)``) over ``[0, 1]^2``, ``u = phi / 2pi``,
  ``v = (1 - cos(theta)) / 2`` (equal-area: every cell covers ``4 pi / N`` steradians; theta
  from +Y), each cell's centre giving the map's travel direction. Map ids run along the
  Hilbert curve over the grid (:mod:`_hilbert`): consecutive ids, neighbouring directions.
- Lookup per receiver (the paper's shader): its light travel direction (the directional
  light's direction; from a point light to the receiver) -> ``(u, v)`` -> the id texture
  (``g x g``) -> that map's matrix (a ``4 g x 4 g`` matrix texture in the paper) -> a point
  depth test ``z - bias <= stored``. Receivers outside the map's square are lit (the sphere
  holds every caster). Point lights: a stored depth nearer than the light's own depth in the
  map does not shadow (the light is inside the sphere); a caster hidden behind such a
  surface is then missed (the paper's objects lie outside the light).
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
run in Dr.Jit kernels (:mod:`._coherent_dr`, ray descriptions from :mod:`._coherent_maps`),
asynchronously while NumPy looks the receivers up; :func:`visibility_intervals` and
:func:`compress_runs` are their NumPy references (same bytes, pinned by tests).

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

from scenes.records import jsonable, provenance

from .. import params as _params
from ..errors import ModelError
from ..gbuffer import trace_gbuffer
from ..light_frame import Projection, make_frame
from ..params import param
from ..result import ModelResult
from . import kernels as _coherent_dr
from . import rays as _coherent_maps
from .hilbert import hilbert_cell, hilbert_index

__all__ = [
    "CoherentParams",
    "compress_runs",
    "map_directions",
    "run",
]

NAME = "coherent-shadow-map"

#: Relative margin on the bounding sphere's radius (geometry on the sphere stays inside).
SPHERE_MARGIN = 1e-4

#: Texture lookups per receiver: one id texel, four float4 texels of the matrix, one depth.
LOOKUPS_PER_RECEIVER = 6

#: Bytes per id texel (16-bit ids: at most 65536 maps).
ID_TEXEL_BYTES = 2

#: Bytes of a stored run in the compressed maps: a float32 depth and a 16-bit map index
#: where the run ends.
RUN_BYTES = 6

ORDERINGS = ("hilbert", "row_major", "column_major", "random")

#: Texels per Dr.Jit launch of the map kernel of :func:`_render_intervals`. The kernel
#: keeps no per-texel arrays of its own (the surface interactions stay in registers) and
#: writes two float32 bounds per texel: peak memory does not grow with the launch
#: (measured at the defaults), while every launch costs its tracing and a synchronisation
#: (a quarter of the render time at 1 << 20).
SURFACE_CHUNK = 1 << 24

#: Texels per launch of :func:`_surfaces`, whose NumPy records hold 32 bytes a texel
#: (128 MiB a launch).
RECORD_CHUNK = 1 << 22

#: Safety factor on the depth spreads of :func:`visibility_intervals`: curved surfaces bend
#: away from their tangent plane within a texel (1.01 left one mismatching receiver on
#: ``curved`` at 1024 maps of 64^2; 1.5 none on the built-in scenes).
SPREAD_GUARD = 1.5

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


# ---------------------------------------------------------------------------- directions
def map_directions(n_maps: int) -> tuple[np.ndarray, np.ndarray]:
    """Travel directions of the maps, by map id, and the id texture.

    Returns ``(directions, id_texture)``: ``(N, 3)`` unit vectors (map ``m`` looks along
    ``directions[m]``) and the ``(g, g)`` int64 id texture (row = v cell, column = u cell).
    """
    g = math.isqrt(n_maps)
    cx, cy = hilbert_cell(g, np.arange(n_maps))
    u = (cx + 0.5) / g
    v = (cy + 0.5) / g
    ids = hilbert_index(g, *np.meshgrid(np.arange(g), np.arange(g)))
    return _direction(u, v), ids


def _direction(u, v) -> np.ndarray:
    """Unit vectors of ``(u, v)`` in ``[0, 1]^2`` (see module docstring)."""
    phi = 2.0 * math.pi * np.asarray(u, dtype=np.float64)
    cos_t = 1.0 - 2.0 * np.asarray(v, dtype=np.float64)
    sin_t = np.sqrt(np.clip(1.0 - cos_t * cos_t, 0.0, 1.0))
    return np.stack([sin_t * np.cos(phi), cos_t, sin_t * np.sin(phi)], axis=-1)


def _uv(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u, v)`` of unit vectors ``(M, 3)`` (inverse of :func:`_direction`)."""
    u = np.mod(np.arctan2(w[:, 2], w[:, 0]) / (2.0 * math.pi), 1.0)
    v = 0.5 * (1.0 - np.clip(w[:, 1], -1.0, 1.0))
    return u, v


class _Projections:
    """The orthographic projection of each map over the bounding sphere, built on demand
    (a map's matrix, the paper's matrix texture entry)."""

    def __init__(self, scene, dirs: np.ndarray, resolution: int):
        lo, hi = scene.bounds()
        self.centre = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo)) * (1.0 + SPHERE_MARGIN)
        self.radius = max(radius, 1e-9)
        self.resolution = int(resolution)
        self._dirs = dirs
        self._cache: dict[int, Projection] = {}

    @property
    def directions(self) -> np.ndarray:
        """``(N, 3)`` travel directions by map id."""
        return self._dirs

    def __getitem__(self, m) -> Projection:
        m = int(m)
        if m not in self._cache:
            frame = make_frame(self._dirs[m], [("world_y", (0.0, 1.0, 0.0))])
            c = frame.to_light(self.centre[None, :])[0]
            rad = self.radius
            extent = (c[0] - rad, c[0] + rad, c[1] - rad, c[1] + rad, c[2] - rad, c[2] + rad)
            self._cache[m] = Projection("ortho", frame, extent, self.resolution)
        return self._cache[m]


# ---------------------------------------------------------------------------- rendering
def _surface_chunks(scene, projs, ids, *, second: bool, chunk: int = SURFACE_CHUNK):
    """The Dr.Jit side of :func:`_surfaces`: yields ``(start, stop, record)`` per chunk with
    ``record`` holding unevaluated Dr.Jit Float64 arrays."""
    from scenes import backend

    mi = backend.mitsuba()
    import drjit as dr

    r = projs.resolution
    rr = r * r
    k = len(ids)
    params = _coherent_maps.ray_table(projs, ids)
    f64 = mi.Float64
    cols = [f64(np.ascontiguousarray(params[:, c])) for c in range(13)]
    total = k * rr
    # Literal divisors: the compiler turns the per-texel divisions into multiplications
    # and shifts (one kernel per map resolution).
    r_u, rr_u = r, rr
    inv_r = dr.opaque(f64, 1.0 / r)
    half_inv_r = dr.opaque(f64, 0.5 / r)

    def spread(n, g, span):
        nf = [f64(n[i]) for i in range(3)]
        nu = dr.abs(nf[0] * g[3] + nf[1] * g[4] + nf[2] * g[5])
        nv = dr.abs(nf[0] * g[6] + nf[1] * g[7] + nf[2] * g[8])
        nd = dr.abs(nf[0] * g[9] + nf[1] * g[10] + nf[2] * g[11])
        return dr.select(nd > 1e-12, (nu + nv) * half_inv_r / (nd * span), dr.inf)

    for start in range(0, total, chunk):
        stop = min(total, start + chunk)
        # The chunk offset is a kernel parameter: one compiled kernel serves every chunk.
        idx = dr.arange(mi.UInt32, stop - start) + dr.opaque(mi.UInt32, start)
        mid = idx // rr_u
        tex = idx - mid * rr_u
        row = tex // r_u
        s = (f64(tex - row * r_u) + 0.5) * inv_r
        t = (f64(row) + 0.5) * inv_r
        g = [dr.gather(f64, c, mid) for c in cols]
        o = [g[i] + s * g[3 + i] + t * g[6 + i] for i in range(3)]
        span = g[12]
        ray = mi.Ray3f(
            mi.Point3f(mi.Float(o[0]), mi.Float(o[1]), mi.Float(o[2])),
            mi.Vector3f(mi.Float(g[9]), mi.Float(g[10]), mi.Float(g[11])),
        )
        ray.maxt = mi.Float(span)
        if second:
            si = scene.mi_scene.ray_intersect(ray, mi.RayFlags.Minimal, coherent=True)
            valid = si.is_valid()
            t1 = f64(si.t)
            ray2 = si.spawn_ray(ray.d)
            ray2.maxt = dr.maximum(mi.Float(span - t1), 0.0)
            si2 = scene.mi_scene.ray_intersect(
                ray2, mi.RayFlags.Minimal, coherent=False, active=valid
            )
            valid2 = valid & si2.is_valid()
            out = {
                "z1": dr.select(valid, t1 / span, dr.inf),
                "z2": dr.select(valid2, (t1 + f64(si2.t)) / span, dr.inf),
                "dz1": dr.select(valid, spread(si.n, g, span), 0.0),
                "dz2": dr.select(valid2, spread(si2.n, g, span), 0.0),
            }
        else:
            pi = scene.mi_scene.ray_intersect_preliminary(ray, coherent=True)
            out = {"z1": dr.select(pi.is_valid(), f64(pi.t) / span, dr.inf)}
        yield start, stop, out


def _surfaces(scene, projs, ids, *, second: bool):
    """First (and second) surfaces of every texel of maps ``ids``, batched over maps.

    Rays are those of :meth:`Projection.grid_rays` (texel centres, from the sphere's near
    plane along the map's direction). Yields ``(start, stop, record)`` per chunk of the
    flattened ``(len(ids), R^2)`` texels; ``record`` holds ``z1`` (and ``z2``): depth
    normalized over the sphere's diameter (``inf``: no surface), and with ``second`` the
    half-footprint depth spreads ``dz1``, ``dz2``: how far the depth of the hit surface's
    plane moves from the texel centre to a texel corner, ``(|n.U| + |n.V|) / (2 r |n.D|)``
    in normalized depth (``inf`` for a surface seen edge-on). The second surface is found by
    continuing from the first hit with Mitsuba's ``spawn_ray`` (its self-intersection
    offset).
    """
    import drjit as dr

    for start, stop, out in _surface_chunks(scene, projs, ids, second=second, chunk=RECORD_CHUNK):
        dr.eval(*out.values())
        yield start, stop, {key: val.numpy() for key, val in out.items()}


def _render(scene, projs, ids) -> np.ndarray:
    """First-surface depth ``(len(ids), R^2)`` (see :func:`_surfaces`)."""
    rr = projs.resolution**2
    z1 = np.empty(len(ids) * rr, dtype=np.float64)
    for start, stop, rec in _surfaces(scene, projs, ids, second=False):
        z1[start:stop] = rec["z1"]
    return z1.reshape(len(ids), rr)


def _render_intervals(scene, projs, ids, bias: float, *, footprint: bool = True):
    """Visibility intervals ``(lo, hi)`` of every texel of maps ``ids``: flat Dr.Jit Float32
    arrays of ``len(ids) * R^2`` values (map-major), computed inside the rendering kernel
    chunk by chunk (the Dr.Jit twin of :func:`visibility_intervals`; ``footprint=False``:
    texel centres only, spreads 0)."""
    from scenes import backend

    mi = backend.mitsuba()
    import drjit as dr

    total = len(ids) * projs.resolution**2
    lo = hi = None
    for start, stop, rec in _surface_chunks(scene, projs, ids, second=True):
        spreads = {"dz1": rec["dz1"], "dz2": rec["dz2"]} if footprint else {}
        c_lo, c_hi = _coherent_dr.intervals(rec["z1"], rec["z2"], bias, SPREAD_GUARD, **spreads)
        if stop - start == total:  # one launch: the kernel's outputs are the arrays
            lo, hi = c_lo, c_hi
        else:
            if lo is None:
                lo, hi = dr.empty(mi.Float, total), dr.empty(mi.Float, total)
            idx = dr.arange(mi.UInt32, start, stop)
            dr.scatter(lo, c_lo, idx)
            dr.scatter(hi, c_hi, idx)
        dr.eval(lo, hi)
    return lo, hi


def _stored(z1: np.ndarray) -> np.ndarray:
    """Stored depth: float32 of the first surface, 1 (cleared) where no surface."""
    return np.where(np.isfinite(z1), z1, 1.0).astype(np.float32)


def _below(x: np.ndarray) -> np.ndarray:
    """Largest float32 strictly below each float64 ``x`` (``inf`` stays ``inf``)."""
    f = x.astype(np.float32)
    f = np.where(f.astype(np.float64) >= x, np.nextafter(f, np.float32(-np.inf)), f)
    return np.where(np.isinf(x), np.float32(np.inf), f).astype(np.float32)


def visibility_intervals(z1, z2, bias: float, *, dz1=None, dz2=None):
    """Per texel, the stored values ``[lo, hi]`` (float32, inclusive) that give the
    uncompressed map's answer to every receiver on the texel's first or second surface.

    ``lo`` is the stored first depth ``s1``. A receiver is compared as ``z - bias <=
    stored``; on a surface of depth ``z`` at the texel centre and depth spread ``dz`` to the
    texel's corners (its plane), its reference lies in ``[z - dz - bias, z + dz - bias]``.
    First surface: if any of its references exceeds ``s1`` (acne: the uncompressed map
    shadows it there) no other value is safe, ``hi = s1``. Second surface: its references
    must stay above the stored value, ``hi`` = the largest float32 below
    ``z2 - dz2 - bias`` (``s1`` when that is not above ``s1``). Without ``dz`` (texel
    centres only) the spreads are 0. No first surface: the map is cleared to 1, every
    receiver inside the sphere is lit by any value >= 1 (``hi = inf``).
    """
    z1 = np.asarray(z1, dtype=np.float64)
    z2 = np.asarray(z2, dtype=np.float64)
    dz1 = np.zeros_like(z1) if dz1 is None else np.asarray(dz1, dtype=np.float64)
    dz2 = np.zeros_like(z2) if dz2 is None else np.asarray(dz2, dtype=np.float64)
    lo = _stored(z1)
    s1 = lo.astype(np.float64)
    guard = SPREAD_GUARD
    with np.errstate(invalid="ignore"):
        acne = np.isfinite(z1) & (z1 + dz1 * guard - bias > s1)
        h2 = z2 - dz2 * guard - bias
    h2 = np.where(np.isfinite(z2), h2, np.inf)
    hi = np.where(h2 > s1, _below(h2), lo)
    hi = np.where(acne, lo, hi)
    return lo, np.maximum(hi, lo).astype(np.float32)


def compress_runs(lo: np.ndarray, hi: np.ndarray, order: np.ndarray):
    """Greedy runs of consecutive maps (in ``order``) whose intervals intersect.

    Parameters
    ----------
    lo, hi : ``(N, T)`` float32 interval bounds per map id and texel.
    order : the map ids in storage order (a permutation of ``range(N)``).

    Returns
    -------
    runs : total number of stored values (runs summed over texels).
    decoded : ``(N, T)`` float32 value each map id reads after decompression (the run's
        largest ``lo``), by map id.
    """
    n, t = lo.shape
    starts = np.zeros((n, t), dtype=bool)  # a run starts at this position
    prefix = np.empty((n, t), dtype=np.float32)  # largest lo of the run so far
    cur_lo = lo[order[0]].copy()
    cur_hi = hi[order[0]].copy()
    starts[0] = True
    prefix[0] = cur_lo
    for pos in range(1, n):
        m = order[pos]
        new_lo = np.maximum(cur_lo, lo[m])
        new_hi = np.minimum(cur_hi, hi[m])
        brk = new_lo > new_hi
        cur_lo = np.where(brk, lo[m], new_lo)
        cur_hi = np.where(brk, hi[m], new_hi)
        starts[pos], prefix[pos] = brk, cur_lo
    runs = int(starts.sum())
    # Backward: every member of a run reads the run's final (largest) lo.
    value = prefix
    for pos in range(n - 2, -1, -1):
        value[pos] = np.where(starts[pos + 1], prefix[pos], value[pos + 1])
    decoded = np.empty_like(value)
    decoded[order] = value
    return runs, decoded


# ---------------------------------------------------------------------------- shading
def _travel(scene, pos: np.ndarray) -> np.ndarray:
    light = scene.light
    if light.kind == "directional":
        d = np.asarray(light.direction, dtype=np.float64)
        return np.broadcast_to(d / np.linalg.norm(d), pos.shape).copy()
    w = pos - np.asarray(light.position, dtype=np.float64)
    return w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)


#: Receivers a directional light's lookup is evaluated on (every receiver has the same
#: travel direction): a strided slice of the same layout as the full arrays, so NumPy
#: takes the same loops and the values are the full evaluation's.
DIRECTIONAL_ROWS = 64


def _lookup(scene, pos: np.ndarray, id_tex: np.ndarray):
    """Light travel directions ``w`` of receivers at ``pos``, the map ids ``sel`` they look
    up in the id texture, and whether all receivers share them (a directional light: then
    ``w`` and ``sel`` are read-only broadcasts of the first receiver's)."""
    g = id_tex.shape[0]
    shared = scene.light.kind == "directional" and len(pos) > 0
    part = pos[:DIRECTIONAL_ROWS] if shared else pos
    w = _travel(scene, part) if len(part) else np.zeros((0, 3))
    u, v = _uv(w)
    ci = np.minimum((u * g).astype(np.int64), g - 1)
    cj = np.minimum((v * g).astype(np.int64), g - 1)
    sel = id_tex[cj, ci]
    if shared:
        return np.broadcast_to(w[:1], pos.shape), np.broadcast_to(sel[:1], len(pos)), True
    return w, sel, False


def _direction_error(w: np.ndarray, dirs: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """Angle in degrees between travel directions ``w`` and their maps' directions."""
    cosang = np.clip(np.sum(w * dirs[sel], axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(cosang))


def _project(scene, gbuf, p, projs, rec: np.ndarray, pos, sel, used):
    """Where the receivers ``rec`` (at ``pos``, looking up maps ``sel``; ``used`` the sorted
    distinct ``sel``) fall in their maps: per map ``(m, mask, texel, ref, zl, inside)``
    (receivers, texel index, compare reference ``z - bias``, the light's own depth,
    inside the map's square), and which receivers lie outside their map."""
    n_dot_l = np.clip(gbuf.cos_l[rec], 0.0, 1.0) if p.normal_offset > 0.0 else None
    outside = np.zeros(len(rec), dtype=bool)
    r = projs.resolution
    records = []
    for m in used:
        # One map for every receiver (a directional light): no masking copies.
        mask = slice(None) if len(used) == 1 else sel == m
        proj = projs[int(m)]
        q = pos[mask]
        if p.normal_offset > 0.0:
            scale = p.normal_offset * proj.texel_world_size() * (1.0 - n_dot_l[mask])
            q = q + gbuf.normal[rec[mask]] * scale[:, None]
        tu, tv, tz, _ = proj.project(q)
        inside = (tu >= 0) & (tu < 1) & (tv >= 0) & (tv < 1)
        outside[mask] = ~inside
        texel = np.clip((tv * r).astype(np.int64), 0, r - 1) * r + np.clip(
            (tu * r).astype(np.int64), 0, r - 1
        )
        ref = tz - p.bias
        zl = -np.inf
        if scene.light.kind != "directional":
            zl = float(proj.project(np.asarray(scene.light.position, dtype=np.float64)[None])[2][0])
        records.append((int(m), mask, texel, ref, zl, inside))
    return records, outside


def _shade(records: list, maps: dict, n_rec: int) -> dict:
    """Visibility of the receivers of :func:`_project` per set of maps: the depth test
    ``z - bias <= stored`` (a stored depth nearer than a point light's own does not
    shadow; outside the map: lit)."""
    vis = {k: np.ones(n_rec) for k in maps}
    for m, mask, texel, ref, zl, inside in records:
        for key, depth in maps.items():
            stored = depth[m][texel].astype(np.float64)
            shadow = (ref > stored) & (stored > zl) & inside
            vis[key][mask] = np.where(shadow, 0.0, 1.0)
    return vis


def run(scene, params: CoherentParams | None = None, **kwargs) -> ModelResult:
    """Run ``coherent-shadow-map`` on a loaded scene; see :func:`raster_models.run`.

    Outputs (``(H, W)`` float32): ``visibility`` (1 = lit), ``map_id`` (the map a receiver
    looks up, -1 elsewhere), ``direction_error_deg`` (angle between the receiver's light
    direction and its map's direction), ``uncovered`` (receivers outside their map).
    """
    t0 = time.perf_counter()
    p = params or _params.make(NAME, CoherentParams, kwargs)
    n = int(p.directions)
    r = int(p.resolution)
    gbuf = trace_gbuffer(scene)
    dirs, id_tex = map_directions(n)
    projs = _Projections(scene, dirs, r)
    centre, radius = projs.centre, projs.radius
    if p.compression and n * r * r > MAX_COMPRESSED_TEXELS:
        raise ModelError(
            f"{NAME}: compression needs every map in memory: directions x resolution^2 = "
            f"{n * r * r} texels is above {MAX_COMPRESSED_TEXELS}; lower them or set "
            "compression=false"
        )
    if p.compression:
        # The map kernels run asynchronously while NumPy looks the receivers up and
        # projects them into their maps below.
        lo, hi = _render_intervals(
            scene, projs, np.arange(n), p.bias, footprint=p.lossless == "footprint"
        )
    rec = np.nonzero(gbuf.receiver)[0]
    pos = gbuf.position[rec]
    # Which maps the receivers look up (sorted distinct ids).
    w, sel, shared = _lookup(scene, pos, id_tex)
    used = sel[:1].copy() if shared else np.nonzero(np.bincount(sel, minlength=n))[0]
    cost: dict = {}
    if p.compression:
        rng = np.random.default_rng(p.seed)
        orders = {
            "hilbert": np.arange(n),
            # Row-major over the direction grid (row v, then column u): the ids of the id
            # texture read row by row.
            "row_major": id_tex.ravel(),
            # Column-major (column u, then row v): rows along theta, a pole-to-pole jump
            # at every column.
            "column_major": id_tex.T.ravel(),
            "random": rng.permutation(n),
        }
        compressed = _coherent_dr.launch_compression(
            lo, hi, n, list(orders.values()), decode=list(orders).index("hilbert"), rows=used
        )
        # Only the maps the receivers look up leave the Dr.Jit side.
        uncompressed = _coherent_dr.launch_rows(lo, used, n)
    else:
        z1 = _render(scene, projs, used)
        stored = _stored(z1)
        maps = {"uncompressed": {int(m): stored[i] for i, m in enumerate(used)}}
    # The output images are float32 from the start (values are cast on assignment, as
    # the final conversion would).
    vis_all = np.ones(gbuf.size, dtype=np.float32)
    vis_all[gbuf.valid] = 0.0
    map_id = np.full(gbuf.size, -1.0, dtype=np.float32)
    err = np.zeros(gbuf.size, dtype=np.float32)
    err_rec = np.zeros(0)
    uncovered = np.zeros(gbuf.size, dtype=np.float32)
    n_uncovered = 0
    mismatches = 0
    if len(rec):
        map_id[rec] = sel
        if shared:
            part = slice(0, DIRECTIONAL_ROWS)
            err_rec = np.full(
                len(rec),
                _direction_error(
                    np.ascontiguousarray(w[part]), dirs, np.ascontiguousarray(sel[part])
                )[0],
            )
        else:
            err_rec = _direction_error(w, dirs, sel)
        err[rec] = err_rec
        records, outside = _project(scene, gbuf, p, projs, rec, pos, sel, used)
        uncovered[rec] = outside
        n_uncovered = int(np.count_nonzero(outside))
    if p.compression:
        counts, decoded = compressed()
        stored = uncompressed()
        maps = {
            "uncompressed": {int(m): stored[i] for i, m in enumerate(used)},
            "decompressed": {int(m): decoded[i] for i, m in enumerate(used)},
        }
        comp = {
            name: {
                "stored_values": runs,
                "ratio": float(n * r * r) / runs,
                "bytes": runs * RUN_BYTES,
            }
            for name, runs in zip(orders, counts, strict=True)
        }
        cost["compression"] = comp
    if len(rec):
        vis = _shade(records, maps, len(rec))
        vis_all[rec] = vis["uncompressed"]
        if "decompressed" in vis:
            mismatches = int(np.sum(vis["decompressed"] != vis["uncompressed"]))
    vis_all[~gbuf.valid] = 1.0
    cost.update(
        {
            "maps": n,
            "map_resolution": r,
            "shadow_map_bytes": int(n * r * r * 4),
            "id_texture_bytes": int(n * ID_TEXEL_BYTES),
            "matrix_texture_bytes": int(n * 16 * 4),
            "texels_rendered": int(n * r * r),
            "render_passes": n,
            "texture_lookups_per_pixel": float(LOOKUPS_PER_RECEIVER if len(rec) else 0),
            "precomputed": True,
        }
    )
    if p.compression:
        cost["decompressed_mismatches"] = mismatches
    spacing = math.degrees(math.sqrt(4.0 * math.pi / n))
    diagnostics = {
        "light": scene.light.to_json(),
        "sphere": {"centre": centre.tolist(), "radius": radius},
        "texel_world_size": 2.0 * radius / r,
        "direction_spacing_deg": spacing,
        "maps_looked_up": int(len(used)),
        "direction_error_deg_mean": float(err_rec.mean()) if len(rec) else 0.0,
        "direction_error_deg_max": float(err_rec.max()) if len(rec) else 0.0,
        "receivers": int(len(rec)),
        "uncovered_receivers": n_uncovered,
        "scene": scene.provenance(),
        "provenance": provenance(),
    }
    outputs = {
        "visibility": gbuf.image(vis_all),  # 0 or 1 only
        "map_id": gbuf.image(map_id),
        "direction_error_deg": gbuf.image(err),
        "uncovered": gbuf.image(uncovered),
    }
    return ModelResult(
        technique=NAME,
        outputs=outputs,
        cost=jsonable(cost),
        diagnostics=jsonable(diagnostics),
        params=_params.as_dict(p),
        wall_seconds=time.perf_counter() - t0,
    )
