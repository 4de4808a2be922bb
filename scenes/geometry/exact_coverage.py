"""Analytic (zero-noise) pixel coverage of triangle scenes: ``coverage_exact`` and
``front_coverage_exact``.

Every triangle of the scene (float64 from Mitsuba's float32 vertices) is clipped against the
camera's near and far planes (Mitsuba's rays run from the near to the far plane) and
projected to film pixels. Where the projections of two triangles overlap and the two do not
interpenetrate, one of them is in front over the whole overlap: for a perspective camera the
inverse ray distance ``1/s`` to a plane is an affine function of the film position, so its
sign of difference over the convex overlap is decided by the overlap's vertices (an
orthographic camera: ``s`` itself). Each triangle's visible region is its projection less the
union of the triangles in front of it (shapely 2, vectorised over all triangles and pairs);
visible regions are disjoint, and their exact areas inside each pixel
(:mod:`scenes.geometry.pixel_area`) give

- ``coverage_exact``: the area fraction of the pixel covered by any geometry;
- ``front_coverage_exact``: the area fraction whose nearest surface belongs to the shape seen
  through the pixel centre (a Mitsuba shape: a whole mesh, rectangle, sphere, ...), the sky
  counting as one: the quantity the Monte Carlo ``front_coverage`` estimates;
- ``coverage_exact_valid``: 1 where both are exact, 0 where they are not known exactly.

Not exact, hence ``valid = 0``: pixels touched by the visible part of an overlap where two
triangles interpenetrate or are coplanar (a depth tie: which one a ray tracer keeps is
rounding), and pixels within the tessellation bound of the visible silhouette of a curved
shape (sphere, cylinder, disk: tessellated here with a stated chord error, never passed off
as exact). The channels are float64 geometry rounded to float32 at the end; the area of a
triangle summed over the pixels matches its projected area to about 1e-13 relative.

The work is in modules of its own: the triangles (:mod:`.coverage_triangles`), their
clipping, projection and tiles (:mod:`.coverage_projection`), the estimate and the budget
(:mod:`.coverage_cost`), the polygon path (:mod:`.coverage_polygons`) and the layered path
(:mod:`.coverage_layered`, :mod:`.coverage_edges`); this one decides which runs.

References
----------
Auzinger, Wimmer, Jeschke, "Analytic Visibility on the GPU", Computer Graphics Forum 32(2),
2013. doi:10.1111/cgf.12046
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass

import numpy as np

from .coverage_cost import OutOfTime, OverBudget, deadline_check, estimate_cost, polygon_seconds
from .coverage_layered import layered_coverage
from .coverage_polygons import polygon_coverage
from .coverage_projection import FILM_MARGIN, project, tile
from .coverage_triangles import MEMO_KEY, TriangleSet, scene_triangle_set

__all__ = [
    "MEMO_KEY",
    "ExactCoverage",
    "NotExact",
    "OutOfTime",
    "OverBudget",
    "estimate_cost",
    "TriangleSet",
    "exact_coverage",
    "exact_coverage_of",
    "scene_triangle_set",
]

#: The layered path is tried when the polygon path's estimate exceeds this many seconds
#: (below it the polygon path runs: small scenes keep their channels bit for bit).
LAYERED_ABOVE_S = 5.0
#: Key of the last view's exact coverage in ``LoadedScene.memo``: it depends on the geometry
#: and the camera only, so the noise-floor reference (seed + 1) of the same view reuses it.
RESULT_MEMO_KEY = "exact_coverage_result"


#: Largest rounding error (px) of clipped and projected vertices that still counts as exact:
#: float64 rounding of world coordinates of magnitude ``M`` seen at the near plane is about
#: ``M * 2^-52 * pixels per unit there``; a ground of +-1e30 gives 1e16 px.
ROUNDING_PX_MAX = 1e-6


class NotExact(Exception):
    """The scene's geometry cannot be clipped and projected exactly in float64 (coordinates
    so large that rounding moves vertices by more than :data:`ROUNDING_PX_MAX` pixels), or its
    visible surface is not its triangles (alpha-tested shapes: glTF ``MASK``)."""


@dataclass
class ExactCoverage:
    """The exact channels (``(H, W)`` float64) and a record of how they were made."""

    coverage: np.ndarray
    front_coverage: np.ndarray
    valid: np.ndarray
    stats: dict


def exact_coverage(
    loaded, centre: np.ndarray, *, budget=None, check=None, deadline=None
) -> ExactCoverage:
    """Exact ``coverage``, ``front_coverage`` and validity of ``loaded``'s current view.

    Parameters
    ----------
    loaded : a :class:`scenes.loaded.LoadedScene` (its camera and film size are used).
    centre : ``(H*W,)`` or ``(H, W)`` int shape index seen through each pixel centre
        (-1: sky), as the Monte Carlo ``front_coverage`` uses it.
    budget, check, deadline : as :func:`exact_coverage_of` takes them. A view refused by the
        estimate, stopped at its deadline or not exact is refused again at once (the noise
        floor's reference of the same view).
    """
    centre = np.ascontiguousarray(centre, dtype=np.int64)
    view = json.dumps(loaded.camera.to_json(), sort_keys=True)
    key = (view, hashlib.sha256(centre.tobytes()).hexdigest())
    slot = loaded.memo.get(RESULT_MEMO_KEY)
    if slot is not None and slot[0] == key:
        done = slot[1]
        over = isinstance(done, OverBudget) and budget is not None
        again = isinstance(done, NotExact | OutOfTime)
        if again or (over and done.estimate["seconds"] > budget):
            raise done  # the same view refused again (the noise floor's reference)
        if not isinstance(done, Exception):
            return done
    try:
        _refuse_alpha(loaded)
        out = exact_coverage_of(
            loaded.camera,
            scene_triangle_set(loaded),
            centre,
            budget=budget,
            check=check,
            deadline=deadline,
        )
    except (OverBudget, NotExact, OutOfTime) as exc:
        exc.view = key  # said once per view by the caller
        loaded.memo[RESULT_MEMO_KEY] = (key, exc)
        raise exc.with_traceback(None) from None  # the memo keeps no frames alive
    loaded.memo[RESULT_MEMO_KEY] = (key, out)
    return out


def _refuse_alpha(loaded) -> None:
    """:class:`NotExact` for a scene with alpha-tested shapes: the alpha test cuts their
    triangles along texture contours that no polygon here follows (as curved shapes'
    silhouettes are not exact, these shapes' coverage is not)."""
    table = getattr(loaded, "alpha", None)
    if table is not None and table.any:
        names = [loaded.shape_names[i] for i in np.nonzero(table.shape_mask >= 0)[0]]
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        raise NotExact(
            f"alpha-tested shapes ({shown}: glTF MASK) cut their triangles along texture "
            "contours; their coverage is sampled, not exact"
        )


def exact_coverage_of(
    camera,
    tset: TriangleSet,
    centre: np.ndarray,
    *,
    grid_offset=(0.0, 0.0),
    check=None,
    budget: float | None = None,
    deadline: float | None = None,
) -> ExactCoverage:
    """:func:`exact_coverage` of the triangles ``tset`` seen by ``camera`` (a
    :class:`scenes.camera.Camera`; its film size is the output's).

    ``grid_offset`` ``(ox, oy)`` in ``[-1, 1]`` pixels moves the pixel grid: pixel ``(x, y)``
    then covers ``[x + ox, x + ox + 1) x [y + oy, y + oy + 1)`` (the expected coverage of a
    sample under random sub-pixel translations of the scene is the coverage of such a box).
    ``check``: called between chunks of the long loops (a signal handler runs there).
    ``budget``: seconds of estimated work (:func:`estimate_cost`) allowed; over it,
    :class:`OverBudget` is raised before the work (before each path's own work).
    ``deadline``: a ``time.perf_counter()`` time; the work checks it between its chunks and
    raises :class:`OutOfTime` once past it (the estimate can be wrong; the deadline holds).

    Where the polygon path would cost more than :data:`LAYERED_ABOVE_S` by the estimate and
    the shapes have one depth order wherever they overlap (no interpenetration or tie
    between shapes, no curved shape) the visible boundaries come from
    :mod:`scenes.geometry.coverage_edges` (``stats["method"] == "layered"``: work in
    proportion to the overlapping pairs, no polygon booleans); otherwise each triangle's
    visible polygon is its projection less the union of what is in front of it
    (``"polygons"``).
    """
    t0 = time.perf_counter()
    cam = camera
    off = np.asarray(grid_offset, dtype=np.float64)
    if off.shape != (2,) or not np.all(np.abs(off) <= FILM_MARGIN):
        raise ValueError(f"grid_offset must be two values in [-1, 1] pixels, got {grid_offset!r}")
    est = estimate_cost(cam, tset)
    if not est["rounding_px"] <= ROUNDING_PX_MAX:
        raise NotExact(
            f"coordinates too large for exact clipping in float64: rounding up to "
            f"{est['rounding_px']:.3g} px (more than {ROUNDING_PX_MAX:g})"
        )
    if budget is not None and est["seconds"] > budget:
        raise OverBudget(est, budget)
    if est["triangles"] == 0:  # nothing between the near and far planes in view
        return _empty_view(cam, centre, est, t0)
    stop = deadline_check(check, deadline, t0)
    try:
        return _run_paths(cam, tset, centre, off, est, (budget, stop, t0))
    except OutOfTime as exc:
        exc.estimate = est  # what the estimate said of the work the deadline stopped
        raise


def _run_paths(cam, tset, centre, off, est, limits) -> ExactCoverage:
    """The layered path where it pays (and the shapes allow it), else the polygon path."""
    budget, stop, t0 = limits
    w, h = cam.width, cam.height
    polys, tri_idx = project(cam, tset.tris, stop)
    polys, tri_idx = tile(polys, tri_idx, w, h)
    poly_s = polygon_seconds(est)
    # the layered path where it pays; below, the polygon path (the bytes of before)
    fast = None
    if poly_s > LAYERED_ABOVE_S:
        fast = layered_coverage(cam, polys, tri_idx, tset, centre, off, stop)
    if fast is not None:
        cov, front_cov, valid, stats = fast
        stats.update(estimate=est, seconds=time.perf_counter() - t0)
        return ExactCoverage(cov, front_cov, valid, stats)
    est = dict(est, path="polygons", seconds=poly_s)
    stop()
    if budget is not None and est["seconds"] > budget:
        raise OverBudget(est, budget)
    cov, front_cov, valid, stats = polygon_coverage(cam, polys, tri_idx, tset, centre, off, stop)
    stats.update(estimate=est, seconds=time.perf_counter() - t0)
    return ExactCoverage(cov, front_cov, valid, stats)


def _empty_view(cam, centre, est, t0) -> ExactCoverage:
    """Nothing in view: coverage 0 everywhere (exact), front coverage 1 where the centre
    sees the sky."""
    w, h = cam.width, cam.height
    zero = np.zeros((h, w))
    centre = np.asarray(centre, dtype=np.int64).reshape(h, w)
    stats = {
        "triangles_projected": 0,
        "tile_pieces": 0,
        "occlusion_pairs": 0,
        "unresolved_pairs": 0,
        "curved_triangles": 0,
        "invalid_pixels": 0,
        "method": "empty",
        "estimate": est,
        "seconds": time.perf_counter() - t0,
    }
    return ExactCoverage(zero, np.where(centre < 0, 1.0, 0.0), np.ones((h, w), bool), stats)
