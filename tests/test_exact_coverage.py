"""Analytic coverage (issue 28): closed forms of the exact channels and their agreement with
the Monte Carlo coverage on every built-in triangle scene."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from raster_oracle.scenes.camera import Camera
from raster_oracle.scenes.catalogue.builtin import BUILTIN_SCENES
from raster_oracle.scenes.geometry.exact_coverage import TriangleSet, exact_coverage_of
from raster_oracle.scenes.geometry.pixel_area import edge_pieces, pixel_area, tagged_pixel_area

#: Relative accuracy the issue asks of a triangle's summed coverage (float64 rounding of the
#: per-cell terms is about 1e-15 of the film size).
AREA_REL = 1e-9
#: Absolute accuracy of a hand-computed pixel area (float64 rounding of pixel-sized sums).
PIXEL_ABS = 1e-12
#: Standard errors within which the 1024-spp Monte Carlo coverage must agree with the exact
#: channel, and the fraction of valid pixels that must (issue 28).
Z_LIMIT = 4.0
AGREE_FRACTION = 0.999


def _ortho(width=16, height=16):
    """Orthographic camera at the origin looking down +Z whose film position of world
    ``(x, y)`` is ``(width/2 - x, height/2 - y)`` (Mitsuba's local +X is the image's left)."""
    half = width / 2.0
    to_world = np.diag([half, half, 1.0, 1.0])
    return Camera("orthographic", to_world, width, height, 0.1, 100.0)


def _quad(x0, x1, y0, y1, z):
    """Two triangles of the world rectangle ``[x0, x1] x [y0, y1]`` at depth ``z``."""
    c = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], dtype=np.float64)
    return np.stack([c[[0, 1, 2]], c[[0, 2, 3]]])


def _tset(*parts):
    tris = np.concatenate(parts)
    shape = np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)])
    return TriangleSet(tris, shape, np.zeros(len(tris)))


def _overlap_1d(a0, a1, b0, b1):
    return np.clip(np.minimum(a1, b1) - np.maximum(a0, b0), 0.0, None)


def _rect_in_pixels(x0, x1, y0, y1, w, h):
    """Hand formula: area of the film rectangle ``[x0, x1] x [y0, y1]`` in each pixel."""
    xs, ys = np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)
    return _overlap_1d(ys, ys + 1, y0, y1)[:, None] * _overlap_1d(xs, xs + 1, x0, x1)[None, :]


def test_triangle_coverage_sums_to_projected_area():
    """Perspective camera, a tilted triangle inside the film: the coverage summed over the
    pixels is its projected area (shoelace of the projected vertices)."""
    cam = Camera("perspective", np.eye(4), 64, 48, 0.1, 100.0, fov_x=50.0)
    tri = np.array([[[0.31, 0.2, 3.0], [-1.1, -0.4, 4.5], [0.9, -0.6, 2.6]]])
    film = cam.project(tri[0])
    x, y = film[:, 0], film[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert np.all((film > 0) & (film < [64, 48]))
    ex = exact_coverage_of(cam, _tset(tri), np.zeros((48, 64), int))
    assert ex.coverage.sum() == pytest.approx(area, rel=AREA_REL)
    assert ex.valid.all()
    # it was cut into film tiles: their shared borders cancel in the pixel areas
    assert ex.stats["tile_pieces"] > 1


def test_triangle_crossing_the_near_plane_keeps_the_part_beyond_it():
    """A triangle reaching behind the camera is clipped at the near plane: its coverage is
    the projected area of the clipped polygon (vertices on the near plane by hand)."""
    cam = Camera("perspective", np.eye(4), 32, 32, 1.0, 100.0, fov_x=90.0)
    # in the plane y = -0.5, from z = 0 (behind the near plane) to z = 3
    tri = np.array([[[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, -0.5, 3.0]]])
    # the clipped polygon: the two edges meet z = 1 at x = -/+ (0.5 - 1/6)
    u = 0.5 - 1.0 / 6.0
    poly = np.array([[-u, -0.5, 1.0], [u, -0.5, 1.0], [0.0, -0.5, 3.0]])
    film = cam.project(poly)
    clipped = shapely.clip_by_rect(shapely.Polygon(film), 0, 0, 32, 32).area
    ex = exact_coverage_of(cam, _tset(tri), np.zeros((32, 32), int))
    assert clipped > 1.0
    assert ex.coverage.sum() == pytest.approx(clipped, rel=AREA_REL)


def test_quad_partly_hidden_by_a_nearer_quad():
    """Back quad (shape 0) at z = 5, a nearer quad (shape 1) at z = 2 over part of it: in
    every pixel the back quad's visible area is its rectangle less the front one's, the
    coverage their union's, all by the rectangle-overlap formula."""
    w = h = 16
    cam = _ortho(w, h)
    # film rectangles: back [2.25, 11.5] x [3.5, 12.75], front [7.75, 14.2] x [1.3, 8.6]
    back = _quad(8 - 11.5, 8 - 2.25, 8 - 12.75, 8 - 3.5, 5.0)
    front = _quad(8 - 14.2, 8 - 7.75, 8 - 8.6, 8 - 1.3, 2.0)
    a_back = _rect_in_pixels(2.25, 11.5, 3.5, 12.75, w, h)
    a_front = _rect_in_pixels(7.75, 14.2, 1.3, 8.6, w, h)
    a_both = _rect_in_pixels(7.75, 11.5, 3.5, 8.6, w, h)
    centre = np.full((h, w), -1)
    cy, cx = np.indices((h, w)) + 0.5
    centre[(cx > 2.25) & (cx < 11.5) & (cy > 3.5) & (cy < 12.75)] = 0
    centre[(cx > 7.75) & (cx < 14.2) & (cy > 1.3) & (cy < 8.6)] = 1
    ex = exact_coverage_of(cam, _tset(back, front), centre)
    assert ex.valid.all()
    np.testing.assert_allclose(ex.coverage, a_back + a_front - a_both, atol=PIXEL_ABS)
    hand = np.where(centre == 0, a_back - a_both, np.where(centre == 1, a_front, 0.0))
    hand = np.where(centre < 0, 1.0 - (a_back + a_front - a_both), hand)
    np.testing.assert_allclose(ex.front_coverage, hand, atol=PIXEL_ABS)
    # the overlap pixels: e.g. pixel (8, 5) lies in both; the back quad is hidden there
    overlap = (a_both > 0) & (centre == 0)
    assert overlap.any()
    assert np.all(ex.front_coverage[overlap] < a_back[overlap])


@pytest.mark.parametrize(
    "corners",
    [
        # a vertical edge at film x = 5.5 through pixel column 5
        [(0, 0), (5.5, 0), (5.5, 16), (0, 16)],
        # a diagonal through the corners of pixel (5, 5): film (5, 5) to (6, 6)
        [(-1, -1), (17, 17), (-1, 17)],
    ],
)
def test_pixel_split_in_half_by_an_edge(corners):
    """A pixel cut exactly in half by an edge has coverage 0.5."""
    w = h = 16
    cam = _ortho(w, h)
    film = np.asarray(corners, dtype=np.float64)
    world = np.column_stack([w / 2 - film[:, 0], h / 2 - film[:, 1], np.full(len(film), 3.0)])
    fan = np.stack([world[[0, k, k + 1]] for k in range(1, len(world) - 1)])
    ex = exact_coverage_of(cam, _tset(fan), np.zeros((h, w), int))
    assert ex.coverage[5, 5] == pytest.approx(0.5, abs=PIXEL_ABS)
    assert ex.front_coverage[5, 5] == pytest.approx(0.5, abs=PIXEL_ABS)


def test_pixel_area_of_holes_and_tags():
    """A square with a hole covers 1 around the hole and 0 inside it; each tag's area is
    read per pixel from one set of edge pieces."""
    ring = shapely.Polygon(
        shapely.box(0, 0, 4, 4).exterior.coords, [shapely.box(1, 1, 3, 3).exterior.coords]
    )
    area = pixel_area([ring], 4, 4)
    hand = np.ones((4, 4))
    hand[1:3, 1:3] = 0.0
    np.testing.assert_allclose(area, hand, atol=PIXEL_ABS)
    tri = shapely.Polygon([(0.1, 0.2), (3.9, 1.2), (1.2, 3.1)])
    pieces = edge_pieces([ring, tri], 4, 4, tags=[3, 7])
    np.testing.assert_allclose(
        tagged_pixel_area(pieces, np.full((4, 4), 7)), pixel_area([tri], 4, 4)
    )
    assert np.all(tagged_pixel_area(pieces, np.full((4, 4), 5)) == 0.0)


def test_interpenetrating_quads_are_split_along_their_intersection():
    """A quad tilted through a flat one (z = 5 + 0.2 (x - 0.3): nearer for x < 0.3): each is
    visible on its side of the intersection line, film x = 7.7, exactly."""
    w = h = 16
    cam = _ortho(w, h)
    flat = _quad(-4, 4, -4, 4, 5.0)  # film [4, 12] x [4, 12]
    tilted = _quad(-3, 3, -3, 3, 5.0)  # film [5, 11] x [5, 11]
    tilted[..., 2] += 0.2 * (tilted[..., 0] - 0.3)
    a_flat = _rect_in_pixels(4, 12, 4, 12, w, h)
    a_tilted_seen = _rect_in_pixels(7.7, 11, 5, 11, w, h)  # world x in [-3, 0.3]
    centre = np.full((h, w), -1)
    cy, cx = np.indices((h, w)) + 0.5
    centre[(cx > 4) & (cx < 12) & (cy > 4) & (cy < 12)] = 0
    centre[(cx > 7.7) & (cx < 11) & (cy > 5) & (cy < 11)] = 1
    ex = exact_coverage_of(cam, _tset(flat, tilted), centre)
    assert ex.valid.all()
    np.testing.assert_allclose(ex.coverage, a_flat, atol=PIXEL_ABS)
    hand = np.where(centre == 1, a_tilted_seen, a_flat - a_tilted_seen)
    hand = np.where(centre < 0, 1.0 - a_flat, hand)
    np.testing.assert_allclose(ex.front_coverage, hand, atol=PIXEL_ABS)
    assert 0.0 < ex.front_coverage[8, 7] < 1.0  # the line crosses pixel column 7


def test_coplanar_quads_of_two_shapes_are_not_exact_where_they_overlap():
    """Two shapes in one plane (a decal): which one a ray tracer keeps is rounding, so their
    overlap is marked not exact; the rest of the film is exact."""
    w = h = 16
    cam = _ortho(w, h)
    ex = exact_coverage_of(
        cam, _tset(_quad(-4, 4, -4, 4, 5.0), _quad(-2, 2, -2, 2, 5.0)), np.zeros((h, w), int)
    )
    overlap = _rect_in_pixels(6, 10, 6, 10, w, h) > 0
    assert not ex.valid[overlap].any()
    assert ex.valid[~overlap].all()


#: Built-in scenes whose shapes are alpha-tested: their coverage is not the triangles' (exact
#: coverage refuses them, tests/test_alpha_gltf.py).
ALPHA_TESTED = {"alpha-foliage"}


def _triangle_scenes():
    """Built-in scenes made only of triangle meshes and rectangles (glTF scenes: meshes)."""
    out = []
    for name, entry in BUILTIN_SCENES.items():
        if name in ALPHA_TESTED:
            continue
        if entry.kind == "gltf":
            out.append(name)
            continue
        d = entry.factory(32, 18)
        kinds = {v.get("type") for v in d.values() if isinstance(v, dict)}
        if not kinds & {"sphere", "cylinder", "disk"}:
            out.append(name)
    return out


#: Scenes whose test takes 20 s or more on this machine (thousands of crossing blades; 13
#: finely tessellated glTF spheres).
SLOW_EXACT = {"foliage", "pbr-spheres"}


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_EXACT else n for n in _triangle_scenes()],
)
def test_monte_carlo_agrees_with_exact_on_triangle_scenes(name):
    """1024-spp Monte Carlo coverage and front coverage agree with the exact channels within
    4 standard errors on at least 99.9 % of the valid pixels."""
    from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
    from raster_oracle.scenes.loader import load

    loaded = load(name, width=48, height=27)
    settings = ReferenceSettings(spp=1024, channels=("coverage", "coverage_exact"))
    ch, stats = render_reference(loaded, settings, quiet=True)
    valid = ch["coverage_exact_valid"] > 0.5
    assert valid.any()
    for mc in ("coverage", "front_coverage"):
        z = (ch[mc] - ch[f"{mc}_exact"].astype(np.float64)) / ch[f"{mc}_stderr"]
        assert np.mean(np.abs(z[valid]) <= Z_LIMIT) >= AGREE_FRACTION, mc
        check = stats["coverage_exact"]["monte_carlo_vs_exact"][mc]
        assert check["pixels"] == int(valid.sum())


@pytest.mark.parametrize("name", ["curved", "point", "glossy"])
def test_curved_shapes_are_exact_only_away_from_their_silhouettes(name):
    """Scenes with spheres and cylinders: the exact channels agree with the 1024-spp Monte
    Carlo ones on the valid pixels; on ``curved`` (spheres and a cylinder only) every pixel
    whose samples disagree lies on a curved silhouette and is marked not exact."""
    from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference
    from raster_oracle.scenes.loader import load

    loaded = load(name, width=48, height=27)
    settings = ReferenceSettings(spp=1024, channels=("coverage", "coverage_exact"))
    ch, _ = render_reference(loaded, settings, quiet=True)
    valid = ch["coverage_exact_valid"] > 0.5
    assert valid.any() and not valid.all()
    for mc in ("coverage", "front_coverage"):
        z = (ch[mc] - ch[f"{mc}_exact"].astype(np.float64)) / ch[f"{mc}_stderr"]
        assert np.mean(np.abs(z[valid]) <= Z_LIMIT) >= AGREE_FRACTION, mc
        if name == "curved":
            mixed = (ch[mc] > 0) & (ch[mc] < 1)
            assert mixed.any() and not np.any(mixed & valid), mc


def test_failed_polygon_operation_claims_nothing_exact(monkeypatch):
    """A polygon operation failing on degenerate input leaves every pixel not exact and the
    reason in the provenance, never a partial channel passed off as exact."""
    from raster_oracle.oracle.reference import coverage as ref_coverage
    from raster_oracle.scenes.geometry import exact_coverage as ec
    from raster_oracle.scenes.loader import load

    def fail(loaded, centre):
        raise shapely.errors.GEOSException("TopologyException: side location conflict")

    monkeypatch.setattr(ec, "exact_coverage", fail)
    loaded = load("plate", width=16, height=9)
    channels, record = ref_coverage.exact_channels(loaded, np.zeros(16 * 9, int), {})
    assert not channels["coverage_exact_valid"].any()
    assert record["valid_fraction"] == 0.0 and "side location conflict" in record["error"]


def test_grid_offset_out_of_range_is_refused():
    with pytest.raises(ValueError, match="grid_offset must be two values in"):
        exact_coverage_of(
            _ortho(), _tset(_quad(-1, 1, -1, 1, 3.0)), np.zeros((16, 16), int), grid_offset=(1.5, 0)
        )
