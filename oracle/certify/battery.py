"""The self-check: closed-form checks of the oracle and two models on the active backend.

Each check renders a tiny scene (a few thousand pixels) and compares with an answer known
without the backend: a plate's hard shadow from a sun, a spot and a point light (plane
geometry, :mod:`.geometry`), the pixel coverage of a straight edge (exact areas), ACAA
counting a coplanar decal twice, an IZB 1-spp pixel equal to the oracle's own centre ray,
a point light's shadow map against the plate's closed form,
the shaded colour against Mitsuba's ``direct`` integrator, and the same bytes for a pixel
whose samples are split over launches. Every failure the first CUDA run showed (a trace
disabled by OptiX, sums rounded in another order, the spot and point light families)
fails one of them; so does a trace that returns no hits or a perturbed intersection on
any backend (tests inject both into the LLVM backend).

:func:`run_battery` returns one :class:`Check` per check; under 30 s on two CPU cores.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ... import raster_models as rm
from ... import scenes
from ...scenes.backend.raycast import trace_film
from ...scenes.catalogue.builtin import BuiltinScene
from ..reference.render import ReferenceSettings, render_reference
from . import geometry as G

__all__ = ["CHECKS", "Check", "run_battery"]


@dataclass(frozen=True)
class Check:
    """One check's outcome: ``figure`` compared with ``bound`` by ``op`` (``"<="`` or
    ``">="``); ``what`` says what the figure is."""

    name: str
    figure: float
    bound: float
    op: str
    what: str
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        if not math.isfinite(self.figure):
            return False
        return self.figure <= self.bound if self.op == "<=" else self.figure >= self.bound

    def line(self) -> str:
        """``name  figure op bound  pass|FAIL  what``: one line of ``doctor --check``."""
        verdict = "pass" if self.passed else "FAIL"
        return (
            f"{self.name:<16} {self.figure:>11.4g} {self.op} {self.bound:<9.4g} {verdict:<4}  "
            f"{self.what} ({self.seconds:.1f} s)"
        )

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "figure": self.figure if math.isfinite(self.figure) else str(self.figure),
            "bound": self.bound,
            "op": self.op,
            "passed": self.passed,
            "what": self.what,
        }


#: Pixels of the plate scenes (small: every check runs in a second or two on a CPU).
PLATE_SIZE = (64, 36)
#: Fewest pixels in shadow a plate scene must show (the check itself would be idle otherwise).
MIN_SHADOW_PIXELS = 100


def _plate(light: str, size=PLATE_SIZE):
    return scenes.load(
        BuiltinScene(f"selfcheck-{light}", G.plate_scene(light), f"plate, {light}", *size)
    )


def _centres(loaded):
    cam = loaded.camera
    yy, xx = np.mgrid[0 : cam.height, 0 : cam.width]
    return xx.ravel() + 0.5, yy.ravel() + 0.5


def _shadow_check(light: str) -> Check:
    """Pixel-centre rays of the oracle (surface hit and shadow ray) against the plate's
    closed form: every scored pixel must agree (shape seen and lit or not)."""
    loaded = _plate(light)
    truth = G.plate_truth(loaded)
    g = trace_film(loaded, *_centres(loaded))
    s = truth["scored"]
    wrong = (g["shape"][s] != truth["shape"][s]) | (g["lit"][s] != truth["lit"][s])
    shadowed = int((~truth["lit"][s] & (truth["shape"][s] >= 0)).sum())
    figure = float(wrong.sum()) if shadowed >= MIN_SHADOW_PIXELS else math.inf
    return Check(
        f"{light}-shadow",
        figure,
        0.0,
        "<=",
        f"pixel centres differing from the closed form, of {int(s.sum())} ({shadowed} shadowed)",
    )


#: A jittered 8x8 grid estimates a straight edge's area within a few of its cells: RMS over
#: the edge pixels well under 1/16 (the reference tests' bound).
EDGE_RMS = 0.05


def _edge_check() -> Check:
    """The reference's coverage of the plate (alone against the sky) in the pixels one of
    its four straight edges crosses, against the exact area of that edge's half-plane."""
    loaded = scenes.load(
        BuiltinScene("selfcheck-edge", G.plate_scene("sun", with_ground=False), "plate", 64, 36)
    )
    cam = loaded.camera
    h, y = G.PLATE_HALF, G.PLATE_HEIGHT
    corners = cam.project(np.array([[-h, y, -h], [-h, y, h], [h, y, h], [h, y, -h]]))
    centre = corners.mean(axis=0)  # inside: the projection of a convex quad is convex
    cover = []
    for k in range(4):  # the plate's four edges
        a, b = corners[k], corners[(k + 1) % 4]
        la, lb = a[1] - b[1], b[0] - a[0]
        lc = -(la * a[0] + lb * a[1])
        sign = 1.0 if la * centre[0] + lb * centre[1] + lc >= 0 else -1.0
        cover.append(G.half_plane_coverage(sign * la, sign * lb, sign * lc, cam.width, cam.height))
    cover = np.stack(cover)
    partial = (cover > 0) & (cover < 1)
    # pixels one edge crosses while the other three half-planes hold them whole
    single = (partial.sum(0) == 1) & ((cover == 1) | partial).all(0)
    exact = np.where(partial, cover, 1.0).min(0)
    ch, _ = render_reference(loaded, ReferenceSettings(spp=64, channels=("coverage",)), quiet=True)
    err = ch["coverage"][single] - exact[single]
    figure = float(np.sqrt(np.mean(err**2))) if single.sum() >= 40 else math.inf
    return Check(
        "edge-coverage",
        figure,
        EDGE_RMS,
        "<=",
        f"RMS coverage error on {int(single.sum())} pixels a straight edge crosses (64 spp)",
    )


def _decal_check() -> Check:
    """ACAA on ``decal``: where every sample of a pixel ties with a coplanar twin, it is
    counted twice (colour exactly twice MSAA's: float32 sums of equal terms); where no
    sample ties, ACAA is MSAA (in shadow too: a disabled shadow trace lights them)."""
    loaded = scenes.load("decal", width=64, height=36)
    msaa = rm.run("msaa", loaded, samples=8).outputs["color"].astype(np.float64)
    acaa = rm.run("acaa", loaded, samples=8).outputs
    cam = loaded.camera
    tie = np.zeros((cam.height, cam.width), bool)
    for name in ("decal", "panel"):
        verts, faces = loaded.mesh_data[name]
        tie |= _covered_by(cam, verts.astype(np.float64)[faces])
    sel = tie & (msaa.sum(-1) > 1e-3)
    ratio = acaa["color"][sel] / msaa[sel]
    plain = acaa["ties"] == 0
    ties_ok = (acaa["ties"][sel] == 8).all() and sel.sum() >= 50 and plain.sum() >= 500
    twice = float(np.abs(ratio - 2.0).max()) if sel.sum() else math.inf
    same = float(np.abs(acaa["color"][plain] - msaa[plain]).max()) if plain.any() else math.inf
    return Check(
        "acaa-decal-ties",
        max(twice, same) if ties_ok else math.inf,
        1e-5,
        "<=",
        f"largest |ACAA/MSAA - 2| on {int(sel.sum())} pixels of coplanar twins and "
        f"|ACAA - MSAA| on {int(plain.sum())} without ties",
    )


def _covered_by(cam, triangles) -> np.ndarray:
    """Pixels whose four corners all lie inside one of ``triangles`` ((T, 3, 3) world)."""
    yy, xx = np.mgrid[0 : cam.height, 0 : cam.width].astype(np.float64)
    out = np.zeros(xx.shape, bool)
    for tri in triangles:  # a few triangles
        p = cam.project(tri)
        inside = np.ones(xx.shape, bool)
        for dx in (0.0, 1.0):
            for dy in (0.0, 1.0):
                px, py = xx + dx, yy + dy
                signs = [
                    (p[(k + 1) % 3, 0] - p[k, 0]) * (py - p[k, 1])
                    - (p[(k + 1) % 3, 1] - p[k, 1]) * (px - p[k, 0])
                    for k in range(3)
                ]
                pos = np.all([s > 0 for s in signs], axis=0)
                neg = np.all([s < 0 for s in signs], axis=0)
                inside &= pos | neg
        out |= inside
    return out


def _izb_check() -> Check:
    """IZB at one sample a pixel against the oracle's centre ray (plate under a spot light):
    equal outside IZB's epsilon band."""
    loaded = _plate("spot")
    truth = G.plate_truth(loaded)
    g = trace_film(loaded, *_centres(loaded))
    res = rm.run("izb", loaded)
    vis = res.outputs["visibility"].ravel()
    band = res.outputs["epsilon_band"].ravel() > 0
    receiver = (g["shape"] >= 0) & g["shadow_tested"]
    scored = receiver & ~band & truth["scored"]
    wrong = (vis[scored] == 1.0) != g["lit"][scored]
    shadowed = int((~g["lit"][scored]).sum())
    figure = float(wrong.sum()) if shadowed >= MIN_SHADOW_PIXELS else math.inf
    return Check(
        "izb-centre-ray",
        figure,
        0.0,
        "<=",
        f"1-spp IZB pixels differing from the oracle's centre ray, of {int(scored.sum())}",
    )


#: Largest fraction of receivers a 1024-texel perspective shadow map of a point light may
#: get wrong against the closed form (the bound of the models' perspective-map test; LLVM
#: gets none wrong on this scene, the first CUDA run 5 % on ``point``).
SHADOW_MAP_WRONG = 0.003


def _shadow_map_check() -> Check:
    """A shadow map of the plate under a point light (a perspective map per cube face, the
    model's defaults) against the closed form, on the scored receivers."""
    loaded = _plate("point")
    truth = G.plate_truth(loaded)
    vis = rm.run("shadow-map", loaded, resolution=1024).outputs["visibility"].ravel()
    scored = truth["scored"] & (truth["shape"] >= 0)
    wrong = (vis[scored] >= 0.5) != truth["lit"][scored]
    return Check(
        "point-shadow-map",
        float(wrong.mean()) if scored.sum() else math.inf,
        SHADOW_MAP_WRONG,
        "<=",
        f"fraction of {int(scored.sum())} receivers a point light's shadow map gets wrong",
    )


#: Z-test of the colour against Mitsuba's ``direct``: per pixel-channel, Sidak-corrected at
#: ALPHA over the image; passes when PASS_RATE of the pixel-channels pass (Mitsuba's own
#: render tests' rule). VARIANCE_FLOOR: pixels where both estimates are noiseless.
ALPHA, PASS_RATE, VARIANCE_FLOOR = 0.01, 0.9975, 1e-8


def _color_check() -> Check:
    """The oracle's colour of ``point`` (a point light, a sphere and boxes) against
    Mitsuba's ``direct`` integrator (four independently seeded renders)."""
    from scipy.special import erfc

    from ...scenes import backend

    mi = backend.mitsuba()
    loaded = scenes.load("point", width=40, height=24)
    ch, _ = render_reference(
        loaded, ReferenceSettings(spp=128, seed=3, channels=("color",)), quiet=True
    )
    ours = np.stack([ch[f"color.{c}"] for c in "RGB"], -1).astype(np.float64)
    ours_se = np.stack([ch[f"color_stderr.{c}"] for c in "RGB"], -1).astype(np.float64)
    integrator = mi.load_dict({"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})
    runs = np.stack(
        [
            np.array(mi.render(loaded.mi_scene, integrator=integrator, spp=32, seed=k))
            for k in range(4)  # four seeds: a standard error for Mitsuba's estimate
        ]
    ).astype(np.float64)
    theirs, theirs_se = runs.mean(0), runs.std(0, ddof=1) / 2.0
    z = np.abs(ours - theirs) / np.sqrt(ours_se**2 + theirs_se**2 + VARIANCE_FLOOR)
    alpha = 1 - (1 - ALPHA) ** (1 / z.size)
    figure = float(np.mean(erfc(z / np.sqrt(2)) >= alpha))
    what = "fraction of pixel-channels agreeing with Mitsuba's direct (point light)"
    if np.array_equal(runs[0], runs[1]):  # no error bar for Mitsuba's estimate: no verdict
        figure, what = math.nan, "Mitsuba's renders with seeds 0 and 1 are identical"
    return Check("color-vs-direct", figure, PASS_RATE, ">=", what)


def _launch_check() -> Check:
    """A pixel's 256 samples in one launch and split over launches of 96: the same bytes in
    every channel (the sums must not depend on the launch)."""
    loaded = _plate("point", size=(8, 6))
    settings = ReferenceSettings(spp=256, channels=("visibility", "coverage", "color"))
    whole, _ = render_reference(loaded, settings, quiet=True)
    split, _ = render_reference(loaded, settings, quiet=True, samples_per_launch=96)
    differ = sum(int(np.count_nonzero(whole[k] != split[k])) for k in whole)
    return Check(
        "launch-bytes",
        float(differ),
        0.0,
        "<=",
        "values differing between one launch and launches of 96 samples",
    )


#: Name -> check function, in the order ``doctor --check`` prints them.
CHECKS = {
    "sun-shadow": lambda: _shadow_check("sun"),
    "spot-shadow": lambda: _shadow_check("spot"),
    "point-shadow": lambda: _shadow_check("point"),
    "edge-coverage": _edge_check,
    "acaa-decal-ties": _decal_check,
    "izb-centre-ray": _izb_check,
    "point-shadow-map": _shadow_map_check,
    "color-vs-direct": _color_check,
    "launch-bytes": _launch_check,
}


def run_battery(*, names=None, on_check=None) -> list[Check]:
    """Run the checks ``names`` (default: all of :data:`CHECKS`) on the active backend.

    ``on_check``: called with each :class:`Check` as it finishes (``doctor`` prints them).
    A check that raises counts as failed (figure NaN), with the error in ``what``.
    """
    out = []
    for name in names or CHECKS:  # nine checks
        t0 = time.perf_counter()
        try:
            check = CHECKS[name]()
        except Exception as exc:  # a broken backend may fail in any way: report it
            check = Check(name, math.nan, 0.0, "<=", f"raised {type(exc).__name__}: {exc}")
        check = Check(**{**check.__dict__, "seconds": time.perf_counter() - t0})
        out.append(check)
        if on_check is not None:
            on_check(check)
    return out
