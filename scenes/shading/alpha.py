"""Alpha-tested materials (glTF ``alphaMode: MASK``): the alpha a surface point has and
whether the alpha test keeps it.

glTF 2.0 (specification, section 3.9.6 "Alpha Coverage") defines, for a ``MASK`` material,
the alpha of a surface point as ``baseColorFactor.a`` times the base colour texture's alpha
times the vertex colour's alpha (``COLOR_0``; 1 without one), and the point as opaque where
``alpha >= alphaCutoff`` (default 0.5) and absent elsewhere. The texture is the continuous
function the sampler defines on its base level: its magnification filter (``NEAREST`` or
``LINEAR``) and its wrap modes in ``s`` and ``t`` (OpenGL 4.6 core, section 8.14.2
"Coordinate Wrapping and Texel Selection", table 8.20), no mipmaps: the oracle integrates a
pixel with its own sub-pixel samples, so the truth is the texture itself.

:class:`AlphaMask` holds one material's alpha (factor, texture, cutoff, whether vertex colours
take part) and samples it in NumPy (:meth:`AlphaMask.alpha_np`); :class:`AlphaTable` holds the
masks of a scene's shapes and evaluates them at Dr.Jit surface hits
(:meth:`AlphaTable.covered_dr`), the alpha test of :mod:`scenes.backend.alpha_hit`. Both
samplers follow the same texel-selection rules (tests compare them). The closed forms
(:func:`checker_coverage`) are the covered fraction of a quad textured with a 2 x 2 checker.

References
----------
The Khronos Group, glTF 2.0 specification, 3.9.6 "Alpha Coverage" and 5.19 "Material"
(``alphaMode``, ``alphaCutoff`` default 0.5, minimum 0).
M. Segal and K. Akeley, The OpenGL Graphics System: A Specification, version 4.6 (core
profile), 2022: 8.14.2 "Coordinate Wrapping and Texel Selection" and table 8.20.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "ALPHA_ATTRIBUTE",
    "DEFAULT_CUTOFF",
    "AlphaError",
    "AlphaMask",
    "AlphaTable",
    "AlphaTexture",
    "WRAP_CODES",
    "checker_coverage",
    "checker_texture",
    "gltf_alpha_mode",
    "sample_np",
    "wrap_index_np",
]

#: glTF ``alphaCutoff`` when a ``MASK`` material does not give one (specification 5.19).
DEFAULT_CUTOFF = 0.5
#: glTF sampler wrap codes (the OpenGL enums) to the names used here.
WRAP_CODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_WRAP_ID = {"repeat": 0, "clamp": 1, "mirror": 2}
#: The Mitsuba mesh attribute holding a vertex colour's alpha (one channel) on a shape whose
#: mask has ``vertex_alpha``.
ALPHA_ATTRIBUTE = "vertex_alpha"


class AlphaError(ValueError):
    """A material's alpha description that is not accepted (one line naming it)."""


def gltf_alpha_mode(material: dict, *, label: str = "material") -> tuple[str, float | None]:
    """``(alphaMode, cutoff)`` of a glTF material (its JSON dictionary).

    ``"OPAQUE"`` (the default; alpha ignored, cutoff None) or ``"MASK"`` with its
    ``alphaCutoff`` (0.5 when absent). ``BLEND`` is refused: a blended surface has no single
    visible surface for the oracle to trace.

    Raises
    ------
    AlphaError
        ``BLEND``, an unknown mode, or an ``alphaCutoff`` that is not a finite number >= 0.
    """
    mode = material.get("alphaMode") or "OPAQUE"
    if mode == "BLEND":
        raise AlphaError(
            f"{label} has alphaMode BLEND; only OPAQUE and MASK are supported (a blended "
            "surface has no single visible surface to trace)"
        )
    if mode not in ("OPAQUE", "MASK"):
        raise AlphaError(f"{label} has alphaMode {mode!r}; expected OPAQUE, MASK or BLEND")
    if mode == "OPAQUE":
        return mode, None
    cutoff = material.get("alphaCutoff", DEFAULT_CUTOFF)
    if cutoff is None:
        cutoff = DEFAULT_CUTOFF
    if isinstance(cutoff, bool) or not isinstance(cutoff, int | float):
        raise AlphaError(f"{label} alphaCutoff must be a number, got {cutoff!r}")
    if not math.isfinite(cutoff) or cutoff < 0:
        raise AlphaError(f"{label} alphaCutoff must be a finite number >= 0, got {cutoff!r}")
    return mode, float(cutoff)


def wrap_index_np(i: np.ndarray, n: int | np.ndarray, wrap: str) -> np.ndarray:
    """Texel index ``i`` (integers, any value) wrapped into ``[0, n)`` (OpenGL 4.6 table
    8.20): ``repeat`` ``i mod n``; ``clamp`` (CLAMP_TO_EDGE) ``clamp(i, 0, n-1)``; ``mirror``
    (MIRRORED_REPEAT) ``(n-1) - m((i mod 2n) - n)`` with ``m(a) = a`` for ``a >= 0`` and
    ``-(1+a)`` otherwise."""
    i = np.asarray(i, dtype=np.int64)
    if wrap == "repeat":
        return np.mod(i, n)
    if wrap == "clamp":
        return np.clip(i, 0, np.asarray(n) - 1)
    if wrap == "mirror":
        a = np.mod(i, 2 * np.asarray(n)) - n
        return (np.asarray(n) - 1) - np.where(a >= 0, a, -(1 + a))
    raise AlphaError(f"wrap mode must be one of repeat, clamp, mirror; got {wrap!r}")


def sample_np(
    image: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    *,
    wrap_s: str = "repeat",
    wrap_t: str = "repeat",
    nearest: bool = False,
) -> np.ndarray:
    """One-channel texture ``image`` ((H, W), row 0 at ``v = 0`` as glTF's images) at texture
    coordinates ``u, v`` (any shape), float64.

    ``nearest``: texel ``(floor(u W), floor(v H))``; else bilinear between the texels around
    ``(u W - 1/2, v H - 1/2)`` (OpenGL 4.6 section 8.14.2); indices wrapped per axis by
    :func:`wrap_index_np`. A non-finite coordinate samples as 0.
    """
    img = np.asarray(image, dtype=np.float64)
    h, w = img.shape
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    finite = np.isfinite(u) & np.isfinite(v)
    u = np.where(finite, u, 0.0)
    v = np.where(finite, v, 0.0)
    if nearest:
        i = wrap_index_np(np.floor(u * w), w, wrap_s)
        j = wrap_index_np(np.floor(v * h), h, wrap_t)
        return np.where(finite, img[j, i], 0.0)
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    a, b = x - x0, y - y0
    i0, i1 = wrap_index_np(x0, w, wrap_s), wrap_index_np(x0 + 1, w, wrap_s)
    j0, j1 = wrap_index_np(y0, h, wrap_t), wrap_index_np(y0 + 1, h, wrap_t)
    out = (1 - a) * (1 - b) * img[j0, i0] + a * (1 - b) * img[j0, i1]
    out += (1 - a) * b * img[j1, i0] + a * b * img[j1, i1]
    return np.where(finite, out, 0.0)


@dataclass(frozen=True)
class AlphaTexture:
    """The alpha channel of a base colour texture as sampled: ``alpha`` (H, W) in [0, 1]
    (row 0 at ``v = 0``; alpha is linear in glTF, never sRGB-decoded), the sampler's wrap
    modes in ``s`` and ``t`` and its magnification filter (``nearest`` or bilinear)."""

    alpha: np.ndarray
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    nearest: bool = False

    def __post_init__(self):
        a = np.asarray(self.alpha, dtype=np.float32)
        if a.ndim != 2 or a.size == 0:
            raise AlphaError(f"alpha texture must be (H, W) with H, W >= 1, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise AlphaError("alpha texture has non-finite values")
        for axis, wrap in (("s", self.wrap_s), ("t", self.wrap_t)):
            if wrap not in _WRAP_ID:
                raise AlphaError(f"wrap_{axis} must be repeat, clamp or mirror; got {wrap!r}")
        object.__setattr__(self, "alpha", np.clip(a, 0.0, 1.0))

    def sample_np(self, u, v) -> np.ndarray:
        """The texture's alpha at ``u, v`` (:func:`sample_np`)."""
        return sample_np(
            self.alpha, u, v, wrap_s=self.wrap_s, wrap_t=self.wrap_t, nearest=self.nearest
        )


@dataclass(frozen=True)
class AlphaMask:
    """The alpha of one ``MASK`` material: ``factor`` (``baseColorFactor.a``), ``texture``
    (the base colour texture's alpha, or None), ``vertex_alpha`` (the shape's vertex colours
    carry alpha, read from :data:`ALPHA_ATTRIBUTE`) and ``cutoff`` (``alphaCutoff``).

    ``bsdf_opacity``: the alpha is also the ``opacity`` of the shape's Mitsuba ``mask`` BSDF
    (a Mitsuba XML scene), evaluated by Mitsuba itself with the filter and wrap mode its XML
    gives; only the Dr.Jit path (:meth:`AlphaTable.alpha_dr`) can sample it."""

    factor: float = 1.0
    texture: AlphaTexture | None = None
    cutoff: float = DEFAULT_CUTOFF
    vertex_alpha: bool = False
    name: str = ""
    bsdf_opacity: bool = False

    def __post_init__(self):
        for what, value in (("factor", self.factor), ("cutoff", self.cutoff)):
            if not math.isfinite(value) or value < 0:
                raise AlphaError(f"alpha mask {what} must be a finite number >= 0, got {value}")

    def alpha_np(self, u, v, vertex_alpha=None) -> np.ndarray:
        """Alpha at texture coordinates ``u, v`` (float64): ``factor`` x texture alpha x
        ``vertex_alpha`` (the interpolated vertex colour alpha where the mask uses it)."""
        if self.bsdf_opacity:
            raise AlphaError(
                f"alpha mask {self.name or 'unnamed'} is a Mitsuba mask BSDF's opacity: "
                "it is sampled by Mitsuba (the Dr.Jit path), not in NumPy"
            )
        u = np.asarray(u, dtype=np.float64)
        a = np.full(u.shape, float(self.factor))
        if self.texture is not None:
            a = a * self.texture.sample_np(u, v)
        if self.vertex_alpha and vertex_alpha is not None:
            a = a * np.asarray(vertex_alpha, dtype=np.float64)
        return a

    def covered_np(self, u, v, vertex_alpha=None) -> np.ndarray:
        """The alpha test: True where ``alpha >= cutoff``."""
        return self.alpha_np(u, v, vertex_alpha) >= self.cutoff

    def to_json(self) -> dict:
        t = self.texture
        return {
            "name": self.name,
            "factor": self.factor,
            "cutoff": self.cutoff,
            "vertex_alpha": self.vertex_alpha,
            "bsdf_opacity": self.bsdf_opacity,
            "texture": None
            if t is None
            else {
                "size": list(t.alpha.shape),
                "wrap": [t.wrap_s, t.wrap_t],
                "filter": "nearest" if t.nearest else "linear",
            },
        }


@dataclass
class AlphaTable:
    """The alpha masks of a scene: ``masks`` and ``shape_mask`` (one entry per shape, in
    ``LoadedScene.shape_names`` order: the index of its mask, -1 for an opaque shape)."""

    masks: list[AlphaMask]
    shape_mask: np.ndarray
    _dr: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        sm = np.asarray(self.shape_mask, dtype=np.int32).ravel()
        if sm.size and (sm.min() < -1 or sm.max() >= len(self.masks)):
            raise AlphaError(
                f"shape_mask entries must be -1 or a mask index below {len(self.masks)}"
            )
        self.shape_mask = sm

    @property
    def any(self) -> bool:
        """Whether any shape is alpha-tested."""
        return bool(np.any(self.shape_mask >= 0))

    def alpha_np(self, shape_index, u, v, vertex_alpha=None) -> np.ndarray:
        """Alpha at hits of shapes ``shape_index`` (int array; -1 or an opaque shape: 1)."""
        s = np.asarray(shape_index, dtype=np.int64)
        ok = (s >= 0) & (s < len(self.shape_mask))
        m = np.where(ok, self.shape_mask[np.where(ok, s, 0)], -1)
        u, v = np.broadcast_to(u, s.shape), np.broadcast_to(v, s.shape)
        va = None if vertex_alpha is None else np.broadcast_to(vertex_alpha, s.shape)
        out = np.ones(s.shape)
        for k, mask in enumerate(self.masks):  # a few materials, not pixels
            sel = m == k
            if np.any(sel):
                out[sel] = mask.alpha_np(u[sel], v[sel], None if va is None else va[sel])
        return out

    def covered_np(self, shape_index, u, v, vertex_alpha=None) -> np.ndarray:
        """The alpha test at hits of shapes ``shape_index``: True on opaque shapes."""
        s = np.asarray(shape_index, dtype=np.int64)
        ok = (s >= 0) & (s < len(self.shape_mask))
        m = np.where(ok, self.shape_mask[np.where(ok, s, 0)], -1)
        cut = np.array([mk.cutoff for mk in self.masks] + [0.0])[m]
        return (m < 0) | (self.alpha_np(s, u, v, vertex_alpha) >= cut)

    def to_json(self) -> dict:
        return {
            "masks": [m.to_json() for m in self.masks],
            "shape_mask": [int(i) for i in self.shape_mask],
        }

    def _tables(self):
        """Dr.Jit copies: per-mask parameters and every texture in one flat array."""
        if "tables" in self._dr:
            return self._dr["tables"]
        import mitsuba as mi

        texels, offset, rows = [], 0, []
        for m in self.masks:
            t = m.texture
            if t is None:
                rows.append((0, 1, 1, 0, 0, 0, 0))
                continue
            h, w = t.alpha.shape
            rows.append((offset, w, h, _WRAP_ID[t.wrap_s], _WRAP_ID[t.wrap_t], int(t.nearest), 1))
            texels.append(t.alpha.ravel())
            offset += t.alpha.size
        p = np.asarray(rows, dtype=np.int32).reshape(-1, 7)
        flat = np.concatenate(texels) if texels else np.ones(1, np.float32)
        f32 = np.float32

        tables = {
            "texels": mi.Float(flat.astype(f32)),
            "int": [mi.Int32(np.ascontiguousarray(p[:, k])) for k in range(7)],
            "factor": mi.Float(np.asarray([m.factor for m in self.masks], f32)),
            "cutoff": mi.Float(np.asarray([m.cutoff for m in self.masks], f32)),
            "vertex": mi.Bool(np.asarray([m.vertex_alpha for m in self.masks], bool)),
            "bsdf": mi.Bool(np.asarray([m.bsdf_opacity for m in self.masks], bool)),
        }
        self._dr["tables"] = tables
        return tables

    def registry_table(self, mi, dr, shapes) -> np.ndarray:
        """Int32 array mapping Mitsuba shape registry ids (of ``shapes``, the scene's shapes
        in ``shape_names`` order) to mask indices (-1: opaque or not a shape of the scene)."""
        reg = [int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in shapes]
        if len(reg) != len(self.shape_mask):
            raise AlphaError(f"alpha table has {len(self.shape_mask)} shapes, the scene {len(reg)}")
        table = np.full(max(reg, default=0) + 2, -1, dtype=np.int32)
        table[reg] = self.shape_mask
        return table

    def alpha_dr(self, mask, uv, vertex_alpha, active, bsdf_alpha=None):
        """Alpha (Dr.Jit ``Float``) of masks ``mask`` (Int32, >= 0 where ``active``) at
        texture coordinates ``uv`` (``Point2f``), times ``vertex_alpha`` (Float) where the
        mask uses vertex alpha and ``bsdf_alpha`` (Float: the mask BSDF's opacity) where it
        uses that. The same texel selection as :func:`sample_np`, in float32."""
        import drjit as dr
        import mitsuba as mi

        t = self._tables()
        m = dr.select(active, mask, 0)
        off, w, h, ws, wt, nearest, textured = (dr.gather(mi.Int32, c, m, active) for c in t["int"])
        a = dr.gather(mi.Float, t["factor"], m, active)
        u, v = dr.select(dr.isfinite(uv.x), uv.x, 0.0), dr.select(dr.isfinite(uv.y), uv.y, 0.0)
        wf, hf = mi.Float(w), mi.Float(h)
        near = nearest != 0
        x = dr.select(near, u * wf, u * wf - 0.5)
        y = dr.select(near, v * hf, v * hf - 0.5)
        x0, y0 = dr.floor(x), dr.floor(y)
        fx = dr.select(near, 0.0, x - x0)
        fy = dr.select(near, 0.0, y - y0)
        i0, j0 = mi.Int32(x0), mi.Int32(y0)
        i = (_wrap_dr(i0, w, ws), _wrap_dr(i0 + 1, w, ws))
        j = (_wrap_dr(j0, h, wt), _wrap_dr(j0 + 1, h, wt))
        on = active & (textured != 0)

        def texel(jj, ii):
            return dr.gather(mi.Float, t["texels"], off + jj * w + ii, on)

        tex = (1.0 - fx) * (1.0 - fy) * texel(j[0], i[0]) + fx * (1.0 - fy) * texel(j[0], i[1])
        tex += (1.0 - fx) * fy * texel(j[1], i[0]) + fx * fy * texel(j[1], i[1])
        a = dr.select(on, a * tex, a)
        uses_vertex = dr.gather(mi.Bool, t["vertex"], m, active)
        if vertex_alpha is not None:
            a = dr.select(uses_vertex, a * vertex_alpha, a)
        if bsdf_alpha is not None:
            a = dr.select(dr.gather(mi.Bool, t["bsdf"], m, active), a * bsdf_alpha, a)
        return a

    def covered_dr(self, mask, uv, vertex_alpha, active, bsdf_alpha=None):
        """The alpha test (Dr.Jit ``Bool``): True where ``mask < 0`` (an opaque shape) or the
        mask's alpha is at least its cutoff."""
        import drjit as dr
        import mitsuba as mi

        tested = active & (mask >= 0)
        cut = dr.gather(mi.Float, self._tables()["cutoff"], dr.select(tested, mask, 0), tested)
        alpha = self.alpha_dr(mask, uv, vertex_alpha, tested, bsdf_alpha)
        return ~tested | (alpha >= cut)


def _wrap_dr(i, n, wrap):
    """:func:`wrap_index_np` in Dr.Jit (Int32 ``i``, size ``n``, wrap id 0 repeat, 1 clamp,
    2 mirror per lane)."""
    import drjit as dr

    rep = i % n
    rep = dr.select(rep < 0, rep + n, rep)
    two = i % (2 * n)
    two = dr.select(two < 0, two + 2 * n, two) - n
    mir = (n - 1) - dr.select(two >= 0, two, -(1 + two))
    clamp = dr.clip(i, 0, n - 1)
    return dr.select(wrap == 0, rep, dr.select(wrap == 1, clamp, mir))


def checker_texture(lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """The 2 x 2 checker alpha texture ``[[hi, lo], [lo, hi]]`` (float32)."""
    return np.array([[hi, lo], [lo, hi]], dtype=np.float32)


def checker_coverage(
    *, lo: float = 0.0, hi: float = 1.0, cutoff: float = DEFAULT_CUTOFF, nearest: bool, wrap: str
) -> float:
    """Covered fraction of a quad spanning texture coordinates ``[0, 1]^2`` and textured with
    :func:`checker_texture` (``lo < hi``), under the alpha test ``alpha >= cutoff``.

    ``NEAREST``: each texel covers a quarter of the quad, so the fraction is 1, 1/2 or 0.
    ``LINEAR``: in texel units around the centres, ``alpha = lo + (hi - lo) (2 a b + 1/2)``
    with ``a, b`` the offsets ``x - 1/2, y - 1/2`` of the bilinear weights; the test is
    ``a b >= m``, ``m = (c - 1/2) / 2``, ``c = (cutoff - lo) / (hi - lo)``. Under ``repeat``
    ``a, b`` are uniform on ``[-1/2, 1/2]`` over the quad, and the area of ``a b >= m > 0`` is
    ``A(m) = 2 (1/4 - m + m ln 4m)``; under ``clamp`` (and ``mirror``, which on ``[0, 1]``
    selects the same texels) the outer quarter of the quad on each side is constant
    (``a = +-1/2`` with mass 1/4 each): ``A(m) / 4 + (1/2 - 2m) / 2 + 1/8``.
    For ``m < 0`` the fraction is ``1 - F(-m)`` by symmetry.
    """
    if not lo < hi:
        raise AlphaError(f"checker needs lo < hi, got lo={lo}, hi={hi}")
    if cutoff <= lo:
        return 1.0
    if cutoff > hi:
        return 0.0
    if nearest:
        return 0.5
    if wrap not in _WRAP_ID:
        raise AlphaError(f"wrap must be repeat, clamp or mirror; got {wrap!r}")
    c = (cutoff - lo) / (hi - lo)
    m = (c - 0.5) / 2.0

    def upper(mm: float) -> float:  # fraction with a b >= mm, 0 <= mm <= 1/4
        area = 0.5 if mm == 0 else 2.0 * (0.25 - mm + mm * math.log(4.0 * mm))
        if wrap == "repeat":
            return area
        return 0.25 * area + 0.5 * (0.5 - 2.0 * mm) + 0.125

    return upper(m) if m >= 0 else 1.0 - upper(-m)
