"""Where receivers fall in a shadow map: shadow-texture coordinates (with the normal offset),
the Jacobian ``J = d(u, v, z) / d(pixel)`` of the map with respect to screen pixels, and the
texel density it implies, as one Dr.Jit kernel per chunk of pixels.

- ``texels_per_pixel``: the smallest singular value of the ``(u, v)`` rows of ``J`` in
  texels: shadow-map texels per screen pixel along the worst-sampled screen direction.
- ``resolution_error``: the Intel SDSM sample's ``max(0, -log2(sqrt(fw_u fw_v)))`` with
  ``fw = max(|J dx|, |J dy|)`` per texel axis.
"""

from __future__ import annotations

import numpy as np

from ...scenes import backend

__all__ = [
    "DRJIT_CHUNK",
    "DrjitColumns",
    "normal_offset_in_world_units",
    "normal_offset_texels",
    "partition_geometry",
]


def normal_offset_texels(params, proj) -> float:
    """Normal offset of a map: ``perspective_normal_offset`` (texels) on spot/point maps of
    techniques that have it, else ``normal_offset`` (texels, or world units with
    ``normal_offset_units="world"``)."""
    if proj is not None and proj.kind == "persp":
        persp = getattr(params, "perspective_normal_offset", None)
        if persp is not None:
            return float(persp)
    return float(params.normal_offset)


def normal_offset_in_world_units(params, proj) -> bool:
    """Whether :func:`normal_offset_texels` is in world units: ``normal_offset`` with
    ``normal_offset_units="world"`` (never ``perspective_normal_offset``)."""
    if getattr(params, "normal_offset_units", "texels") != "world":
        return False
    return not (
        proj is not None and proj.kind == "persp" and hasattr(params, "perspective_normal_offset")
    )


#: Pixels per Dr.Jit launch of :func:`_geometry_drjit` (bounded memory).
DRJIT_CHUNK = 1 << 21


class DrjitColumns:
    """Flat Dr.Jit ``Float64`` copies of a G-buffer's fields (``(N, 3)`` fields row-major),
    uploaded on first use and shared by every partition (and blend band) one :func:`shade`
    call looks up; pass a new one after changing the G-buffer."""

    def __init__(self, gbuf):
        self.gbuf = gbuf
        self._columns: dict = {}

    def __getitem__(self, name: str):
        col = self._columns.get(name)
        if col is None:
            flat = np.ascontiguousarray(getattr(self.gbuf, name), dtype=np.float64).reshape(-1)
            col = self._columns[name] = backend.mitsuba().Float64(flat)
        return col


def partition_geometry(params, part, gbuf, pix, columns: DrjitColumns | None = None) -> dict:
    """Shadow coordinates (with the normal offset), Jacobian, texel density and resolution
    error for pixels ``pix`` of ``gbuf`` in the map of ``part``.

    One fused Dr.Jit kernel per chunk of pixels, reading the G-buffer through ``columns``
    (a new :class:`DrjitColumns` when ``None``). The projection to ``(u, v, z, w)`` runs in
    the projection's precision (float32 for ``matrix_precision="float32"``, with its float32
    matrix, as :meth:`Projection.project`); the normal offset, the Jacobian
    ``J = d(u, v, z)/d(pixel)`` and the texel density in float64.

    ``lookup_offset`` ``(du, dv)`` texels moves every lookup after the projection (an
    engine off the texel-centre convention).

    Returns a dict: ``u``, ``v``, ``z`` (float64; non-finite values replaced by 0, 0, 1),
    ``inside`` (bool: within the map's texture and in front of the light), ``tpp`` (smallest
    singular value of the ``(u, v)`` rows of ``J`` in texels per pixel), ``err`` (Intel's
    resolution error) and, with ``receiver_plane_bias``, ``j3`` ``(N, 3, 2)``, ``ju``,
    ``jv``; ``proj``.
    """
    proj = part.projection
    geo = _geometry_drjit(params, proj, columns or DrjitColumns(gbuf), pix)
    geo["proj"] = proj
    return geo


def _projector(mi, proj):
    """``project(p) -> (u, v, z, w)`` (Dr.Jit ``Float64``) of points ``p`` (three
    ``Float64``), evaluated in the projection's precision."""
    import drjit as dr

    persp = proj.kind != "ortho"
    f64 = mi.Float64
    ftype = mi.Float if proj.precision == "float32" else f64
    # Kernel parameters, not literals: one compiled kernel serves every projection.
    m = [[dr.opaque(ftype, float(c)) for c in row] for row in np.asarray(proj.matrix_used)]

    def project(p):
        q = [ftype(c) for c in p]
        rows = [m[i][0] * q[0] + m[i][1] * q[1] + m[i][2] * q[2] + m[i][3] for i in range(4)]
        if not persp:
            return f64(rows[0]), f64(rows[1]), f64(rows[2]), f64(1.0)
        w = rows[3]
        return f64(rows[0] / w), f64(rows[1] / w), f64(rows[2] / w), f64(w)

    return project


def _texel_density(dr, a, b, c, d):
    """Smallest singular value of ``[[a, b], [c, d]]`` (texels per pixel; 0 where
    undefined) and Intel's resolution error ``max(0, -log2(sqrt(fw_u fw_v)))``."""
    fro = a * a + b * b + c * c + d * d
    det = dr.abs(a * d - b * c)
    smax = dr.sqrt(0.5 * (fro + dr.sqrt(dr.maximum(fro * fro - 4.0 * det * det, 0.0))))
    smin = dr.select(smax > 0, det / smax, 0.0)
    fw_u = dr.maximum(dr.abs(a), dr.abs(b))
    fw_v = dr.maximum(dr.abs(c), dr.abs(d))
    lod = dr.log2(dr.sqrt(fw_u * fw_v))
    err = dr.select(dr.isfinite(lod), dr.maximum(-lod, 0.0), 0.0)
    return dr.select(dr.isfinite(smin), smin, 0.0), err


def _geometry_drjit(params, proj, cols: DrjitColumns, pix):
    """:func:`partition_geometry`'s kernel, launched per chunk of :data:`DRJIT_CHUNK`
    pixels (one launch: its evaluated arrays are the outputs)."""
    mi = backend.mitsuba()
    import drjit as dr

    f64 = mi.Float64

    def const(x):
        # Kernel parameters, not literals: one compiled kernel serves every projection.
        return dr.opaque(f64, float(x))

    m = [[const(c) for c in row] for row in np.asarray(proj.matrix, dtype=np.float64)]
    res = float(proj.resolution)
    res_k = const(res)
    persp = proj.kind != "ortho"
    offset = normal_offset_texels(params, proj)
    n = len(pix)
    need_j = bool(params.receiver_plane_bias)
    keys = ("u", "v", "z", "tpp", "err")
    if need_j:
        keys += ("jux", "juy", "jvx", "jvy", "jzx", "jzy")
    single = 0 < n <= DRJIT_CHUNK
    out = {} if single else {k: np.empty(n) for k in keys}
    inside_out = None if single else np.empty(n, dtype=bool)
    tan2 = const(2.0 * float(proj.extent[0]) / res if persp else 0.0)
    texel_ortho = const(0.0 if persp else float(proj.texel_world_size()))
    offset_k = const(offset)
    world_units = normal_offset_in_world_units(params, proj)
    du, dv = getattr(params, "lookup_offset", (0.0, 0.0))
    shift_uv = bool(du or dv)
    shift_u, shift_v = const(float(du) / res), const(float(dv) / res)

    project = _projector(mi, proj)

    def gather(name, base, k):
        # The pixels' float64 G-buffer values, read inside the kernel (no NumPy gathers).
        return dr.gather(f64, cols[name], base + k)

    for start in range(0, n, DRJIT_CHUNK):
        sl = slice(start, min(n, start + DRJIT_CHUNK))
        idx = mi.UInt32(np.asarray(pix[sl], dtype=np.uint32))
        base = idx * 3
        p = [gather("position", base, k) for k in range(3)]
        u, v, z, w = project(p)
        if offset > 0.0:
            if world_units:
                scale = offset_k
            else:
                texel = tan2 * w if persp else texel_ortho
                n_dot_l = dr.clip(dr.gather(f64, cols["cos_l"], idx), 0.0, 1.0)
                scale = offset_k * texel * (1.0 - n_dot_l)
            p = [p[k] + gather("normal", base, k) * scale for k in range(3)]
            u, v, z, w = project(p)
        if shift_uv:
            u, v = u + shift_u, v + shift_v
        jac = []
        for name in ("dpdx", "dpdy"):
            dp = [gather(name, base, k) for k in range(3)]
            dq = [m[i][0] * dp[0] + m[i][1] * dp[1] + m[i][2] * dp[2] for i in range(3)]
            if persp:
                dw = m[3][0] * dp[0] + m[3][1] * dp[1] + m[3][2] * dp[2]
                dq = [(dq[i] - t * dw) / w for i, t in enumerate((u, v, z))]
            jac.append(dq)
        (ux, vx, zx), (uy, vy, zy) = jac
        tpp, err = _texel_density(dr, ux * res_k, uy * res_k, vx * res_k, vy * res_k)
        inside = (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1) & (w > 0) & dr.isfinite(u + v)
        vals = {
            "u": dr.select(dr.isfinite(u), u, 0.0),
            "v": dr.select(dr.isfinite(v), v, 0.0),
            "z": dr.select(dr.isfinite(z), z, 1.0),
            "tpp": tpp,
            "err": err,
        }
        if need_j:
            vals.update(jux=ux, juy=uy, jvx=vx, jvy=vy, jzx=zx, jzy=zy)
        dr.eval(inside, *vals.values())
        if single:
            # One launch: its evaluated arrays are the outputs (views, no copies).
            out = {k: val.numpy() for k, val in vals.items()}
            inside_out = inside.numpy()
            continue
        for k, val in vals.items():
            out[k][sl] = val.numpy()
        inside_out[sl] = inside.numpy()
    geo = {
        "u": out["u"],
        "v": out["v"],
        "z": out["z"],
        "inside": inside_out,
        "tpp": out["tpp"],
        "err": out["err"],
    }
    if need_j:
        # The Jacobian itself only feeds the receiver-plane bias (tpp, err are done above).
        j_u = np.stack([out["jux"], out["juy"]], axis=-1)
        j_v = np.stack([out["jvx"], out["jvy"]], axis=-1)
        jz = np.stack([out["jzx"], out["jzy"]], axis=-1)
        geo.update(ju=j_u * res, jv=j_v * res, j3=np.stack([j_u, j_v, jz], axis=1))
    return geo
