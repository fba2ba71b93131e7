"""sengine.geom.ringset.RingSet, method by method, with values worked out by hand.

RingSet is exercised in bulk by the splitting tests (test_split, the lots nodes); these pin each
method on small polygons (with holes, empty, clockwise input, repeated vertices, far from the origin)
for the mutation run of docs/mutation.md.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.ringset import RingSet, _first_of, _ramp

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])

SQUARE_WITH_HOLE = shapely.Polygon([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (2, 2), (1, 2)]])
TRIANGLE = shapely.Polygon([(10, 0), (13, 0), (13, 4)])  # legs 3 and 4, hypotenuse 5


def test_helpers():
    assert _ramp([3, 0, 2]).tolist() == [0, 1, 2, 0, 1]
    assert _ramp(np.array([1, 1], np.int32)).dtype == np.int64
    f = _first_of(np.array([0, 0, 2, 2, 2]), 4)
    assert f.tolist() == [0, 2, 2, 5, 5] and f.dtype == np.int64


def test_from_polygons_arrays_by_hand():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE], flag=False)
    assert rs.n == 3
    # exterior counter-clockwise, hole clockwise (orient_polygons), closing vertices dropped
    assert rs.xy.tolist() == [
        [0, 0], [4, 0], [4, 4], [0, 4],
        [1, 1], [1, 2], [2, 2], [2, 1],
        [10, 0], [13, 0], [13, 4],
    ]  # fmt: skip
    assert rs.ring.tolist() == [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2] and rs.ring.dtype == np.int64
    assert rs.poly.tolist() == [0, 0, 2] and rs.poly.dtype == np.int64
    assert rs.flag.dtype == bool and not rs.flag.any()
    assert RingSet.from_polygons([TRIANGLE]).flag.all()


def test_from_polygons_orients_clockwise_input():
    cw = shapely.Polygon([(0, 0), (0, 2), (3, 2), (3, 0)])
    rs = RingSet.from_polygons([cw])
    assert rs.ring_areas().tolist() == [6.0]


def test_from_polygons_empty_and_wrong_types():
    rs = RingSet.from_polygons([])
    assert rs.n == 0 and rs.xy.shape == (0, 2)
    assert rs.ring.dtype == rs.poly.dtype == np.int64 and rs.flag.dtype == bool
    assert len(rs.polygons()) == 0
    assert len(rs.flag) == len(rs.ring) == len(rs.poly) == 0
    assert rs.polygons().dtype == object
    msg = r"^RingSet.from_polygons takes Polygons only \(explode MultiPolygons first\)$"
    with pytest.raises(TypeError, match=msg):
        RingSet.from_polygons([shapely.MultiPolygon([TRIANGLE])])
    with pytest.raises(TypeError, match=msg):
        RingSet.from_polygons([TRIANGLE, shapely.LineString([(0, 0), (1, 1)])])


def test_from_polygons_takes_empty_geometries_of_any_type():
    """An empty intersection may come back as an empty collection: it is an empty polygon here."""
    rs = RingSet.from_polygons([TRIANGLE, shapely.GeometryCollection(), shapely.LineString()])
    assert rs.n == 3 and rs.areas().tolist() == [6.0, 0.0, 0.0]


def test_cleaned_drops_repeats_and_short_rings():
    # a repeated vertex, a hole that is two points after dropping repeats, then a good hole
    p = shapely.Polygon(
        [(0, 0), (5, 0), (5, 0), (5, 5), (0, 5)],
        [[(1, 1), (1, 1), (2, 2), (2, 2)], [(3, 3), (4, 3), (4, 4)]],
    )
    rs = RingSet.from_polygons([p, TRIANGLE])
    assert len(rs.xy) == 4 + 3 + 3
    assert rs.ring.tolist() == [0, 0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert rs.poly.tolist() == [0, 0, 1]
    assert rs.areas().tolist() == [24.5, 6.0]


def test_cleaned_when_nothing_to_drop_is_the_same_object():
    rs = RingSet.from_polygons([TRIANGLE])
    assert rs.cleaned() is rs
    empty = RingSet.from_polygons([shapely.Polygon()])
    assert empty.cleaned() is empty and empty.n == 1


def test_spike_tips_are_vertices_where_the_ring_turns_straight_back():
    # (4, 0) -> (4, 6) -> (4, 3): the ring runs up past (4, 3) and straight back, (4, 6) is a tip;
    # a spike 1e-12 m wide is one too, one 1e-6 m wide is not (tol 1e-9 m); nor are straight-through
    # vertices, corners, or a repeated vertex (an edge shorter than tol).
    xy = np.array([(0, 0), (4, 0), (4, 6), (4, 3), (2, 3), (0, 3)], float)
    rs = RingSet(xy, np.zeros(6, np.int64), np.zeros(6, bool), np.array([0]), 1)
    assert rs.spike_tips(1e-9).tolist() == [False, False, True, False, False, False]
    for width, tip in ((1e-12, True), (1e-6, False)):
        thin = RingSet(xy + [[0, 0], [0, 0], [width, 0], [0, 0], [0, 0], [0, 0]], rs.ring, rs.flag, rs.poly, 1)
        assert thin.spike_tips(1e-9)[2] == tip
    # the tip as the ring's first vertex (its edge in is the ring's last), and a repeated vertex
    assert RingSet(np.roll(xy, -2, axis=0), rs.ring, rs.flag, rs.poly, 1).spike_tips(1e-9).tolist()[0]
    rep = RingSet(
        np.array([(0, 0), (5, 0), (5, 1e-12), (5, 5)], float),
        np.zeros(4, np.int64),
        np.zeros(4, bool),
        np.array([0]),
        1,
    )
    assert not rep.spike_tips(1e-9).any()
    assert not RingSet.from_polygons([SQUARE_WITH_HOLE, TRIANGLE]).spike_tips(1e-9).any()


def test_polygons_round_trip():
    polys = [SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE]
    out = RingSet.from_polygons(polys).polygons()
    assert len(out) == 3
    assert out[1].is_empty
    assert shapely.equals(out[0], SQUARE_WITH_HOLE) and shapely.equals(out[2], TRIANGLE)
    assert list(out[0].interiors[0].coords) == [(1, 1), (1, 2), (2, 2), (2, 1), (1, 1)]


def test_polygons_of_ringless_sets():
    out = RingSet.from_polygons([shapely.Polygon(), shapely.Polygon()]).polygons()
    assert len(out) == 2 and all(g.is_empty and g.geom_type == "Polygon" for g in out)


def test_next_vertex_by_hand():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, TRIANGLE])
    assert rs.next_vertex().tolist() == [1, 2, 3, 0, 5, 6, 7, 4, 9, 10, 8]


def test_areas_and_lengths_by_hand():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE])
    assert rs.ring_areas().tolist() == [16.0, -1.0, 6.0]
    assert rs.areas().tolist() == [15.0, 0.0, 6.0]
    assert rs.edge_lengths().tolist() == [4, 4, 4, 4, 1, 1, 1, 1, 3, 4, 5]
    assert rs.vertex_poly().tolist() == [0] * 8 + [2] * 3
    assert len(RingSet.from_polygons([shapely.Polygon()]).ring_areas()) == 0


def test_ring_areas_far_from_the_origin_are_exact():
    """A 0.1 m square 10,000 km out: the area is computed from the ring's first vertex."""
    x0, y0 = 1e7, 1e7
    sq = shapely.Polygon([(x0, y0), (x0 + 0.125, y0), (x0 + 0.125, y0 + 0.125), (x0, y0 + 0.125)])
    assert RingSet.from_polygons([sq]).ring_areas().tolist() == [0.015625]


def test_flagged_length_counts_marked_edges_per_polygon():
    a = RingSet.from_polygons([SQUARE_WITH_HOLE], flag=True)
    b = RingSet.from_polygons([TRIANGLE], flag=False)
    rs = RingSet.concat([a, b])
    assert rs.flagged_length().tolist() == [20.0, 0.0]
    flag = rs.flag.copy()
    flag[10] = True  # the hypotenuse
    rs2 = RingSet(rs.xy, rs.ring, flag, rs.poly, rs.n)
    assert rs2.flagged_length().tolist() == [20.0, 5.0]


def test_take_by_mask_and_by_indices():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE])
    assert rs.take(np.ones(3, bool)) is rs
    for sel in ([False, True, True], [1, 2]):
        t = rs.take(sel)
        assert t.n == 2 and t.poly.tolist() == [1] and t.ring.tolist() == [0, 0, 0]
        assert t.areas().tolist() == [0.0, 6.0]
    t = rs.take([0])
    assert t.n == 1 and t.ring.tolist() == [0, 0, 0, 0, 1, 1, 1, 1] and t.areas().tolist() == [15.0]


def test_permuted_reorders_and_selects():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE])
    p = rs.permuted([2, 0, 1])
    assert p.n == 3 and p.areas().tolist() == [6.0, 15.0, 0.0]
    assert p.ring.tolist() == [0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2] and p.poly.tolist() == [0, 1, 1]
    assert p.xy[:3].tolist() == [[10, 0], [13, 0], [13, 4]]
    f = RingSet.concat([RingSet.from_polygons([TRIANGLE], flag=False), RingSet.from_polygons([TRIANGLE])])
    assert f.permuted([1, 0]).flag.tolist() == [True] * 3 + [False] * 3
    q = rs.permuted(np.array([2, 2], np.int32))
    assert q.n == 2 and q.areas().tolist() == [6.0, 6.0] and q.ring.tolist() == [0, 0, 0, 1, 1, 1]


def test_concat():
    e = RingSet.concat([])
    assert e.n == 0 and e.xy.shape == (0, 2) and e.ring.dtype == e.poly.dtype == np.int64 and e.flag.dtype == bool
    a = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon()])
    b = RingSet.from_polygons([TRIANGLE], flag=False)
    c = RingSet.concat([a, b, RingSet.concat([])])
    assert c.n == 3 and c.ring.tolist() == [0] * 4 + [1] * 4 + [2] * 3 and c.poly.tolist() == [0, 0, 2]
    assert c.flag.tolist() == [True] * 8 + [False] * 3
    assert c.ring.dtype == c.poly.dtype == np.int64 and c.flag.dtype == bool


def test_extent_along_by_hand():
    rs = RingSet.from_polygons([SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE])
    ref, lo, hi = rs.extent_along([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert ref.tolist() == [[0, 0], [0, 0], [10, 0]]
    assert lo.tolist() == [0.0, np.inf, 0.0] and hi.tolist() == [4.0, -np.inf, 4.0]
    d = np.tile([0.6, 0.8], (3, 1))
    ref, lo, hi = rs.extent_along(d)
    assert lo[2] == 0.0 and hi[2] == pytest.approx(3 * 0.6 + 4 * 0.8)
    assert lo[0] == 0.0 and hi[0] == pytest.approx(4 * 1.4)


def test_extent_along_with_trailing_empty_polygons():
    rs = RingSet.from_polygons([TRIANGLE, shapely.Polygon(), shapely.Polygon()])
    ref, lo, hi = rs.extent_along(np.tile([1.0, 0.0], (3, 1)))
    assert ref.tolist() == [[10, 0], [0, 0], [0, 0]]
    assert lo.tolist() == [0.0, np.inf, np.inf] and hi.tolist() == [3.0, -np.inf, -np.inf]


def test_extent_along_of_an_empty_set():
    rs = RingSet.from_polygons([shapely.Polygon()])
    ref, lo, hi = rs.extent_along([1.0, 0.0])
    assert ref.tolist() == [[0, 0]] and lo.tolist() == [np.inf] and hi.tolist() == [-np.inf]


def rect(cx, cy, length, width, theta):
    """A length x width rectangle centred on (cx, cy), long side at angle theta (rad)."""
    c, s = np.cos(theta), np.sin(theta)
    ax, ay = np.array([c, s]), np.array([-s, c])
    pts = [(cx, cy) + sx * length / 2 * ax + sy * width / 2 * ay for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return shapely.Polygon(pts)


def test_min_rect_axis_of_rotated_rectangles():
    theta = np.array([0.3, 1.2, 2.5])
    polys = [rect(100, 50, 20, 8, t) for t in theta]
    polys.append(shapely.Polygon([(0, 0), (0, -2), (9, -2), (9, 0)]))  # first edge is the short side
    polys.append(shapely.Polygon())
    axis = RingSet.from_polygons(polys).min_rect_axis()
    want = np.r_[np.c_[np.cos(theta), np.sin(theta)], [[1.0, 0.0], [1.0, 0.0]]]
    assert np.allclose(np.abs(np.einsum("ij,ij->i", axis, want)), 1.0, atol=1e-12)
    assert np.allclose(np.hypot(axis[:, 0], axis[:, 1]), 1.0)
    assert axis[4].tolist() == [1.0, 0.0]


def test_min_rect_axis_ignores_holes_and_zero_length_edges():
    outer = rect(0, 0, 30, 10, 0.4)
    hole = rect(0, 0, 4, 1, 1.3)
    p = shapely.Polygon(outer.exterior.coords, [hole.exterior.coords])
    axis = RingSet.from_polygons([p]).min_rect_axis()
    assert abs(axis[0] @ [np.cos(0.4), np.sin(0.4)]) == pytest.approx(1.0, abs=1e-12)


def test_min_rect_axis_big_polygons_use_the_oriented_envelope():
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    ell = shapely.Polygon(
        np.c_[30 * np.cos(t), 10 * np.sin(t)] @ [[np.cos(0.5), np.sin(0.5)], [-np.sin(0.5), np.cos(0.5)]]
    )
    rs = RingSet.from_polygons([ell, rect(0, 0, 5, 1, 2.0), shapely.Polygon()])
    axis = rs.min_rect_axis(max_vertices=128)
    assert axis[2].tolist() == [1.0, 0.0]
    only_big = RingSet.from_polygons([ell]).min_rect_axis()
    assert abs(only_big[0] @ [np.cos(0.5), np.sin(0.5)]) == pytest.approx(1.0, abs=2e-3)
    assert abs(axis[0] @ [np.cos(0.5), np.sin(0.5)]) == pytest.approx(1.0, abs=2e-3)
    assert abs(axis[1] @ [np.cos(2.0), np.sin(2.0)]) == pytest.approx(1.0, abs=1e-12)
    # the same from the edge-aligned search when the limit is raised
    axis2 = rs.min_rect_axis(max_vertices=500)
    assert abs(axis2[0] @ [np.cos(0.5), np.sin(0.5)]) == pytest.approx(1.0, abs=2e-2)
    assert RingSet.from_polygons([]).min_rect_axis().shape == (0, 2)
    assert RingSet.from_polygons([shapely.Polygon()]).min_rect_axis().tolist() == [[1.0, 0.0]]


def test_min_rect_axis_picks_the_smallest_edge_aligned_box():
    """A triangle obtuse at (2, 3): the box along (0, 0)-(10, 0) is 10 x 3, those along the other edges larger."""
    tri = shapely.Polygon([(0, 0), (10, 0), (2, 3)])
    axis = RingSet.from_polygons([tri]).min_rect_axis()
    assert abs(axis[0] @ [1.0, 0.0]) == pytest.approx(1.0, abs=1e-12)


coord = st.integers(-20, 20).map(float)


@SETTINGS
@given(st.lists(st.tuples(coord, coord, st.integers(1, 9).map(float), st.integers(1, 9).map(float)), max_size=6))
def test_ringset_round_trip_and_measures_match_shapely(boxes):
    polys = [shapely.box(x, y, x + w, y + h) for x, y, w, h in boxes]
    rs = RingSet.from_polygons(polys)
    out = rs.polygons()
    assert len(out) == len(polys)
    assert all(shapely.equals(a, b) for a, b in zip(out, polys))
    assert np.allclose(rs.areas(), shapely.area(polys)) if polys else rs.n == 0
    assert np.allclose(rs.flagged_length(), shapely.length(polys)) if polys else True
    order = np.arange(len(polys))[::-1]
    assert all(shapely.equals(a, polys[i]) for a, i in zip(rs.permuted(order).polygons(), order))


def sawtooth(n: int) -> shapely.Polygon:
    """An n-vertex 40 x 10 rectangle outline, every other vertex pushed 1 m out: no edge is along a side."""
    t = np.linspace(0, 100, n, endpoint=False)  # along the perimeter of [0, 40] x [0, 10]
    ring = shapely.box(0, 0, 40, 10).exterior
    pts = shapely.get_coordinates(shapely.line_interpolate_point(ring, t + 0.3))
    c = np.array([20.0, 5.0])
    out = pts + (np.arange(n) % 2)[:, None] * np.sign(pts - c) * [1.0, 1.0]
    return shapely.Polygon(out)


def test_min_rect_axis_switches_to_the_envelope_above_max_vertices():
    """128 exterior vertices: the edge-aligned search (no edge lies along the hull); 129: GEOS's envelope."""
    from sengine.geom.polygons import obb_frame

    for n, envelope in ((128, False), (129, True)):
        p = sawtooth(n)
        assert len(p.exterior.coords) - 1 == n and p.is_valid
        axis = RingSet.from_polygons([p]).min_rect_axis()[0]
        env = obb_frame([p])[1][0]
        assert (abs(axis @ env) > 1 - 1e-9) == envelope


def edge_box_areas(p: shapely.Polygon) -> np.ndarray:
    """Area of the box aligned with each exterior edge of p (brute force)."""
    xy = np.asarray(p.exterior.coords)[:-1]
    e = np.roll(xy, -1, axis=0) - xy
    e /= np.hypot(e[:, 0], e[:, 1])[:, None]
    a, b = xy @ e.T, xy @ np.c_[-e[:, 1], e[:, 0]].T
    return np.ptp(a, axis=0) * np.ptp(b, axis=0)


@st.composite
def star_polygons(draw):
    """Simple polygons: 3-12 vertices at random radii and whole-degree angles round a centre, any scale and place."""
    k = draw(st.integers(3, 12))
    deg = draw(st.lists(st.integers(0, 359), min_size=k, max_size=k, unique=True))
    ang = np.radians(np.sort(deg)) + draw(st.floats(0, 1))  # whole degrees apart: no vanishing edge
    rad = np.asarray(draw(st.lists(st.floats(0.3, 1.0), min_size=k, max_size=k)))
    scale = draw(st.sampled_from([0.2, 3.0, 50.0]))
    cx, cy = draw(st.integers(-1000, 1000)), draw(st.integers(-1000, 1000))
    p = shapely.Polygon(np.c_[cx + scale * rad * np.cos(ang), cy + scale * rad * np.sin(ang)])
    return p if p.is_valid and p.area > 1e-3 * scale**2 else None


@SETTINGS
@given(st.lists(star_polygons(), min_size=1, max_size=4))
def test_min_rect_axis_is_the_smallest_edge_aligned_box(polys):
    polys = [p for p in polys if p is not None]
    rs = RingSet.from_polygons(polys)
    axis = rs.min_rect_axis()
    for p, ax in zip(shapely.orient_polygons(np.array(polys, object)), axis):
        xy = np.asarray(p.exterior.coords)[:-1]
        length, width = np.ptp(xy @ ax), np.ptp(xy @ [-ax[1], ax[0]])
        scale = np.sqrt(p.area)
        assert length >= width - 1e-9 * scale  # the long side
        assert length * width == pytest.approx(edge_box_areas(p).min(), rel=1e-9)
