"""Coverage kept against distance: the shipped alpha-test rules (raster_models.alpha) against
the alpha-tested truth on the ``alpha-foliage`` cards, per distance band.

For each rule, per distance band (pixels grouped by the view depth of their first card,
alpha ignored, so every rule and the truth are compared over the same pixels):
``coverage kept`` = the rule's mean coverage / the truth's (1: no bias; below 1: foliage
lost). The truth is the oracle's alpha test at the texture's base level (``alphaCutoff``
0.5), ``spp`` stratified rays a pixel through :func:`scenes.backend.alpha_hit.closest_hit_alpha`.

The silhouette shift (:func:`silhouette_shift`) is measured where silhouettes are
resolved: one card seen orthographically with its texture magnified to 3 pixels a texel.

Run: ``python -m raster_oracle.oracle.studies.alpha_coverage [--n N] [--width W] [--height H]
[--samples S] [--spp K]``; it prints one line per rule and band, then each rule's shift.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass

import numpy as np

from ...raster_models.alpha.model import AlphaRasterParams, alpha_raster
from ...scenes.backend.alpha_hit import alpha_scene, closest_hit_alpha
from ...scenes.camera import Camera
from ...scenes.catalogue import alpha_foliage as af
from ...scenes.catalogue.factories import look_at
from ...scenes.geometry.uv_mesh import QUAD_FACES, uv_mesh
from ...scenes.shading.alpha import AlphaMask, AlphaTable, AlphaTexture

__all__ = [
    "PRESETS",
    "REPORT_SIZE",
    "FoliageView",
    "alpha_report",
    "coverage_by_band",
    "flicker",
    "foliage_view",
    "leaf_closeup",
    "main",
    "run_alpha_foliage",
    "silhouette_shift",
    "truth_and_depth",
]

#: The rules measured: name -> parameters (MSAA count set by the caller).
PRESETS = {
    "test/box": {"rule": "test", "mips": "box"},
    "test/coverage": {"rule": "test", "mips": "coverage"},
    "threejs-a2c/box": {"rule": "threejs-a2c", "mips": "box"},
    "filament-a2c/box (0.4)": {"rule": "filament-a2c", "mips": "box", "cutoff": 0.4},
    "hashed/box": {"rule": "hashed", "mips": "box"},
}


@dataclass
class FoliageView:
    """The ``alpha-foliage`` cards as one Mitsuba mesh, their alpha table and the camera."""

    mi_scene: object
    table: AlphaTable
    camera: Camera


def foliage_view(
    width: int, height: int, *, n: int, seed: int = 1, frame: int = 0, frames: int = 8
) -> FoliageView:
    """The built-in ``alpha-foliage:n=N:seed=S`` as loaded (its GLB read back: the alpha its
    PNG stores, REPEAT, LINEAR), at ``width`` x ``height``; ``frame`` > 0: that frame of a
    ``subpixel-pan`` of ``frames``."""
    from ... import scenes

    path = {"camera_path": "subpixel-pan", "frame": frame, "n_frames": frames} if frame else {}
    name = f"alpha-foliage:n={int(n)}:seed={int(seed)}"
    loaded = scenes.load(name, width=width, height=height, **path)
    return FoliageView(loaded.mi_scene, loaded.alpha, loaded.camera)


def flicker(
    *, n: int = 1000, width: int = 160, height: int = 90, frames: int = 8, samples: int = 4
) -> dict:
    """Flicker of each rule over a ``subpixel-pan`` (0.25 px a frame): the mean over pixels
    and frame pairs of ``|(c[k+1] - c[k]) - (t[k+1] - t[k])|``, the rule's frame-to-frame
    change of coverage less the truth's (4 x 4 stratified rays a pixel), and the truth's own
    mean ``|t[k+1] - t[k]|`` (``truth_change``)."""
    views = [foliage_view(width, height, n=n, frame=k, frames=frames) for k in range(frames)]
    truth = np.stack([truth_and_depth(v, 4)[0] for v in views])
    dt = np.diff(truth, axis=0)
    out = {"truth_change": float(np.abs(dt).mean()), "flicker": {}}
    for name, kw in PRESETS.items():  # five rules
        params = AlphaRasterParams(samples=samples, **kw)
        cov = np.stack(
            [alpha_raster(v.mi_scene, v.table, v.camera, params)["coverage"] for v in views]
        )
        out["flicker"][name] = float(np.abs(np.diff(cov, axis=0) - dt).mean())
    return out


def _rays(view: FoliageView, k: int):
    """The view's ``k x k`` stratified rays a pixel (NumPy ``o, d`` and the Mitsuba ray)."""
    import mitsuba as mi

    cam = view.camera
    h, w = cam.height, cam.width
    g = (np.arange(k) + 0.5) / k
    ys, xs = np.mgrid[0:h, 0:w]
    x = np.broadcast_to(xs[..., None, None] + g[None, None, None, :], (h, w, k, k)).ravel()
    y = np.broadcast_to(ys[..., None, None] + g[None, None, :, None], (h, w, k, k)).ravel()
    o, d, tmax = cam.rays(x, y)
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(np.ascontiguousarray(o[:, i], np.float32)) for i in range(3))),
        mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, i], np.float32)) for i in range(3))),
    )
    ray.maxt = mi.Float(tmax.astype(np.float32))
    return o, d, ray


def _truth_samples(view: FoliageView, k: int) -> np.ndarray:
    """Whether each of the ``k x k`` rays a pixel meets a kept point (pixel-major, bool)."""
    import mitsuba as mi

    _, _, ray = _rays(view, k)
    alpha = alpha_scene(view.mi_scene, view.table)
    si, _, _ = closest_hit_alpha(view.mi_scene, ray, alpha, flags=mi.RayFlags.UV)
    return np.array(si.is_valid())


def truth_and_depth(view: FoliageView, spp_side: int):
    """Per pixel: the truth's coverage and the view depth of the first card (alpha ignored;
    0 where none)."""
    import mitsuba as mi

    cam = view.camera
    h, w, k = cam.height, cam.width, spp_side
    cover = _truth_samples(view, k).reshape(h, w, k * k).mean(axis=2)
    o, d, ray = _rays(view, k)
    first = view.mi_scene.ray_intersect(ray, mi.RayFlags.Minimal, False)
    hit = np.array(first.is_valid()).reshape(h, w, k * k)
    t = np.where(hit.ravel(), np.array(first.t, np.float64), 0.0)
    pts = (o + d * t[:, None]).reshape(h, w, k * k, 3)
    depth = np.where(hit, cam.view_depth(pts), np.inf).min(axis=2)
    return cover, np.where(np.isfinite(depth), depth, 0.0)


def coverage_by_band(
    *, n: int = 1000, width: int = 320, height: int = 180, samples: int = 4, spp_side: int = 4
) -> dict:
    """The study (see the module text): ``{"bands": [[lo, hi], ...], "truth": [per band],
    "pixels": [per band], "kept": {preset: [ratio per band]}}``."""
    view = foliage_view(width, height, n=n)
    truth, depth = truth_and_depth(view, spp_side)
    edges = af.band_edges()
    band = np.searchsorted(edges, depth, side="right") - 1
    out = {
        "bands": [[float(edges[b]), float(edges[b + 1])] for b in range(af.BANDS)],
        "truth": [],
        "pixels": [],
        "kept": {},
    }
    sel = [(band == b) & (depth > 0) for b in range(af.BANDS)]
    out["truth"] = [float(truth[s].mean()) for s in sel]
    out["pixels"] = [int(s.sum()) for s in sel]
    for name, kw in PRESETS.items():  # five rules
        cover = alpha_raster(
            view.mi_scene, view.table, view.camera, AlphaRasterParams(samples=samples, **kw)
        )["coverage"]
        out["kept"][name] = [float(cover[s].mean() / max(truth[s].mean(), 1e-12)) for s in sel]
    return out


def leaf_closeup(size: int, *, px_per_texel: float) -> FoliageView:
    """An orthographic view of one card, ``size`` pixels square, whose leaf texture (LINEAR,
    REPEAT) is magnified to ``px_per_texel`` pixels a texel: silhouettes a pixel can resolve."""
    import mitsuba as mi

    span = size / px_per_texel / 256.0  # texture coordinates across the view
    corners = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * span + 0.3
    scene = mi.load_dict({"type": "scene", "card": uv_mesh(mi, "card", corners, QUAD_FACES, uvs)})
    tex = AlphaTexture(af.texture_alpha(af.leaf_texture()), "repeat", "repeat", False)
    table = AlphaTable([AlphaMask(texture=tex, cutoff=af.CUTOFF)], np.array([0]))
    camera = Camera("orthographic", look_at((0, 0, 5), (0, 0, 0)), size, size, 0.1, 10.0)
    return FoliageView(scene, table, camera)


def silhouette_shift(
    preset: str, *, size: int = 192, px_per_texel: float = 3.0, samples: int = 4, spp_side=8
) -> dict:
    """Mean silhouette shift of ``preset`` on :func:`leaf_closeup`, in pixels (positive:
    outwards): (covered area of the rule - the truth's) / the truth's contour length, the
    length by Cauchy-Crofton from the truth's ``spp_side``-fold grid (``pi/4`` x the grid's
    transitions x its spacing)."""
    view = leaf_closeup(size, px_per_texel=px_per_texel)
    truth_cover, _ = truth_and_depth(view, spp_side)
    fine = _truth_mask(view, spp_side)
    transitions = np.count_nonzero(np.diff(fine, axis=0)) + np.count_nonzero(np.diff(fine, axis=1))
    length = math.pi / 4 * transitions / spp_side
    params = AlphaRasterParams(samples=samples, **PRESETS[preset])
    cover = alpha_raster(view.mi_scene, view.table, view.camera, params)["coverage"]
    return {
        "shift_px": float((cover.sum() - truth_cover.sum()) / length),
        "contour_px": float(length),
        "truth_area_px": float(truth_cover.sum()),
    }


def _truth_mask(view: FoliageView, k: int) -> np.ndarray:
    """The truth's kept points on the view's ``k``-fold grid, (H k, W k) bool."""
    cover_samples = _truth_samples(view, k)
    h, w = view.camera.height, view.camera.width
    return cover_samples.reshape(h, w, k, k).transpose(0, 2, 1, 3).reshape(h * k, w * k)


#: Film size of the report's bands (the study's; docs/research.md) and of its close-up.
REPORT_SIZE = (320, 180)


def alpha_report(*, quick: bool = True, size=None) -> dict:
    """The report's record: coverage kept per distance band by every rule of :data:`PRESETS`
    (4x MSAA, 1000 cards, truth 4 x 4 rays a pixel; ``size`` overrides :data:`REPORT_SIZE`)
    and each rule's silhouette shift on a close-up (96 px square when ``quick``, else 192).
    A band without pixels (tiny films) has ``None`` for its values."""
    import time

    t0 = time.perf_counter()
    width, height = size or REPORT_SIZE
    with np.errstate(invalid="ignore", divide="ignore"):
        res = coverage_by_band(n=1000, width=width, height=height, samples=4, spp_side=4)
    close = 96 if quick else 192
    shifts = {name: silhouette_shift(name, size=close, samples=4)["shift_px"] for name in PRESETS}

    def clean(values):
        return [None if v is None or not math.isfinite(v) else float(v) for v in values]

    return {
        "schema": "raster-oracle.studies.alpha-foliage/1",
        "quick": quick,
        "resolution": [int(width), int(height)],
        "cards": 1000,
        "samples": 4,
        "truth_rays_per_pixel": 16,
        "bands": res["bands"],
        "pixels": res["pixels"],
        "truth": clean(res["truth"]),
        "kept": {name: clean(v) for name, v in res["kept"].items()},
        "closeup_px": close,
        "silhouette_shift_px": {k: float(v) for k, v in shifts.items()},
        "wall_seconds": time.perf_counter() - t0,
    }


def run_alpha_foliage(out, *, quick: bool = True, size=None) -> dict:
    """:func:`alpha_report`, written as ``out/alpha_foliage.json`` and ``.html`` when ``out``
    is given; returns the record."""
    from ...reports.sections import alpha_foliage_section
    from .output import write_study

    data = alpha_report(quick=quick, size=size)
    if out is not None:
        section = alpha_foliage_section(data)
        title = "Alpha-tested foliage"
        write_study(out, name="alpha_foliage", data=data, section=section, title=title)
    return data


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="alpha_coverage", description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--samples", type=int, default=4)
    ap.add_argument("--spp", type=int, default=4, help="truth rays per pixel side")
    args = ap.parse_args(argv)
    from ...scenes import backend

    backend.select()
    res = coverage_by_band(
        n=args.n, width=args.width, height=args.height, samples=args.samples, spp_side=args.spp
    )
    head = "band (m)".ljust(24) + "".join(f"{lo:6.1f}-{hi:<6.1f}" for lo, hi in res["bands"])
    print(head)
    print("truth coverage".ljust(24) + "".join(f"{v:13.3f}" for v in res["truth"]))
    for name, kept in res["kept"].items():
        print(f"{name:24s}" + "".join(f"{v:13.3f}" for v in kept))
    fl = flicker(n=args.n, samples=args.samples)
    print(
        f"flicker over a sub-pixel pan (160 x 90, 8 frames; truth's own change "
        f"{fl['truth_change']:.4f}):"
    )
    for name, v in fl["flicker"].items():
        print(f"{name:24s}{v:13.4f}")
    print("silhouette shift (px, + outwards) on a close-up at 3 px a texel:")
    for name in PRESETS:
        print(f"{name:24s}{silhouette_shift(name, samples=args.samples)['shift_px']:+13.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
