"""sengine.geom.polygons, function by function, with values worked out by hand.

The face, lot and building tests use these in bulk; these pin each function on small inputs
(rotated frames, degenerate geometries, the threaded paths against one call) for the mutation run
of docs/mutation.md.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import shapely.affinity

import sengine.geom.polygons as P
from sengine.geom.polygons import (
    LOCAL_MIN,
    PARALLEL_MIN,
    buffer_local,
    clip_frame_boxes,
    containing,
    frame_boxes,
    inset,
    largest_share,
    obb_frame,
    right_of_lines,
    shared_areas,
    strtree_query,
    subtract_buffers,
    threaded,
)


def rect(cx, cy, length, width, theta, short_first=False):
    """A length x width rectangle centred on (cx, cy), long side at angle theta (rad)."""
    c, s = np.cos(theta), np.sin(theta)
    ax, ay = np.array([c, s]), np.array([-s, c])
    signs = ((-1, -1), (1, -1), (1, 1), (-1, 1))
    if short_first:
        signs = signs[1:] + signs[:1]
    return shapely.Polygon([(cx, cy) + sx * length / 2 * ax + sy * width / 2 * ay for sx, sy in signs])


# --- obb_frame -----------------------------------------------------------------------------------


def test_obb_frame_of_rotated_rectangles():
    geoms = [rect(100, -50, 20, 8, 0.3), rect(5, 7, 12, 3, 2.0, short_first=True), shapely.box(0, 0, 4, 4)]
    center, axis, length, width = obb_frame(geoms)
    assert np.allclose(center, [[100, -50], [5, 7], [2, 2]], atol=1e-9)
    assert np.allclose(length, [20, 12, 4]) and np.allclose(width, [8, 3, 4])
    assert np.allclose(np.hypot(axis[:, 0], axis[:, 1]), 1.0)
    for k, t in ((0, 0.3), (1, 2.0)):
        assert abs(axis[k] @ [np.cos(t), np.sin(t)]) == pytest.approx(1.0, abs=1e-9)


def test_obb_frame_axis_is_a_unit_vector_for_small_boxes():
    center, axis, length, width = obb_frame([rect(1, 2, 0.5, 0.2, 0.7)])
    assert np.hypot(*axis[0]) == pytest.approx(1.0) and length[0] == pytest.approx(0.5)
    assert abs(axis[0] @ [np.cos(0.7), np.sin(0.7)]) == pytest.approx(1.0)


def test_obb_frame_of_lines_points_and_empties():
    geoms = [
        shapely.LineString([(0, 0), (10, 2)]),  # wider than tall
        shapely.LineString([(1, 1), (2, 9)]),  # taller than wide
        shapely.Point(3, 4),
        shapely.Polygon(),
        shapely.LineString([(0, 0), (3, 0)]),  # a flat envelope (not a polygon)
    ]
    center, axis, length, width = obb_frame(geoms)
    assert center[2].tolist() == [3, 4] and center[3].tolist() == [0, 0]
    assert length[2] == width[2] == length[3] == width[3] == 0.0
    assert axis[2].tolist() == [1, 0] and axis[3].tolist() == [1, 0]
    assert axis[4].tolist() == [1, 0] and length[4] == 3.0 and width[4] == 0.0 and center[4].tolist() == [1.5, 0]
    assert center[1].tolist() == [1.5, 5] and axis[1].tolist() == [0, 1] and length[1] == 8 and width[1] == 1
    # GEOS's envelope of a line is a line: the bounding box frame
    assert center[0].tolist() == [5, 1] and axis[0].tolist() == [1, 0] and length[0] == 10 and width[0] == 2
    c, a, ln, w = obb_frame([])
    assert c.shape == (0, 2) and a.shape == (0, 2) and ln.shape == w.shape == (0,)


# --- frame_boxes ---------------------------------------------------------------------------------


def test_frame_boxes_by_hand():
    (box,) = frame_boxes([10, 20], [0, 1], [1], 3, -2, 0.5)  # a along +y, b along -x
    assert shapely.get_coordinates(box).tolist() == [[12, 21], [12, 23], [9.5, 23], [9.5, 21], [12, 21]]
    boxes = frame_boxes([[0, 0], [5, 5]], [[1, 0], [1, 0]], [0, -1], [2, 1], 0, [1, 3])
    assert shapely.bounds(boxes).tolist() == [[0, 0, 2, 1], [4, 5, 6, 8]]


# --- threaded, strtree_query, inset --------------------------------------------------------------


def test_threaded_is_one_call():
    polys = np.array([shapely.box(0, 0, k + 1, 1) for k in range(10)])
    one = shapely.area(polys)
    for threads in (None, 1, 2, 3):
        assert np.array_equal(threaded(shapely.area, polys, threads=threads, min_size=1), one)
    assert np.array_equal(threaded(shapely.area, polys[:1], threads=3, min_size=1), one[:1])
    d = np.arange(10.0) / 10
    same = threaded(shapely.buffer, polys, d, threads=4, min_size=5, quad_segs=1)
    assert shapely.equals_exact(same, shapely.buffer(polys, d, quad_segs=1), 0).all()


def test_strtree_query_threads_give_the_one_call_output():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, (PARALLEL_MIN + 37, 2))
    geoms = shapely.box(xy[:, 0], xy[:, 1], xy[:, 0] + 3, xy[:, 1] + 3)
    tree = shapely.STRtree(geoms[::2])
    want = tree.query(geoms)
    for threads in (None, 1, 2, 3):
        got = strtree_query(tree, geoms, threads=threads)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def comb(teeth: int, x0: float, y0: float) -> shapely.Polygon:
    """A 2 km square with a hole whose ring runs out and back along ``teeth`` dead ends (zero-width spurs)."""
    k = np.arange(teeth)
    base = np.column_stack([2000.0 * (k + 0.5) / teeth, np.zeros(teeth)])  # along the hole's bottom side
    tip = base + np.column_stack([3.0 * np.sin(k), 20.0 + 30.0 * (k % 7) / 7])  # into the hole, slanted
    ring = np.concatenate([np.stack([base, tip, base], axis=1).reshape(-1, 2), [(2000.0, 2000.0), (0.0, 2000.0)]])
    shell = [(-500.0, -500.0), (2500.0, -500.0), (2500.0, 2500.0), (-500.0, 2500.0)]
    return shapely.Polygon(np.add(shell, (x0, y0)), [ring[::-1] + (x0, y0)])


def test_buffer_local_moves_long_rings_only_and_gives_the_buffer_in_place():
    far = (653390.554747, 5603108.119533)  # UTM metres, as Liège's land face
    small = shapely.Polygon(shapely.box(0, 0, 30, 20).exterior.coords[:-1][::-1]).buffer(0)
    polys = np.array([comb(LOCAL_MIN // 3 + 1, *far), shapely.transform(small, lambda xy: xy + far), small])
    assert shapely.get_num_coordinates(polys).tolist()[0] >= LOCAL_MIN > shapely.get_num_coordinates(polys[1])
    d = np.array([-7.3, -2.0, 1.5])
    got = buffer_local(polys, d, quad_segs=2)
    want = shapely.buffer(polys, d, quad_segs=2)
    assert shapely.to_wkb(got[1:]).tolist() == shapely.to_wkb(want[1:]).tolist()  # short rings: same bytes
    # the long ring: the buffer of the same polygon at the origin, moved back to the float
    at_origin = shapely.buffer(comb(LOCAL_MIN // 3 + 1, 0.0, 0.0), -7.3, quad_segs=2)
    assert shapely.is_valid(got[0]) and got[0].area > 0.9 * polys[0].area
    assert shapely.hausdorff_distance(got[0], shapely.transform(at_origin, lambda xy: xy + far)) < 1e-6
    assert got[0].area == pytest.approx(want[0].area, rel=1e-9)
    # every spur kept clear by the distance: no vertex of the hole's ring (the tips among them) nearer
    # than 7.3 m, less the sag of round joins of 2 chords a quarter circle (under 8 %)
    ring = shapely.points(shapely.get_coordinates(polys[0].interiors[0]))
    assert shapely.distance(ring, got[0]).min() > 7.3 * 0.92
    # scalar distance, other keywords, and inset's mitred and rounded paths go through it
    assert shapely.equals_exact(buffer_local(polys[:1], -7.3, quad_segs=2), got[:1], 0).all()
    assert shapely.equals_exact(inset(polys[:1], 7.3, rounded=[True]), got[:1], 0).all()
    mitred = inset(polys[:2], [7.3, 2.0])
    assert shapely.is_valid(mitred).all() and mitred[1].equals(shapely.buffer(polys[1], -2.0, join_style="mitre"))


def test_buffer_local_of_any_polygon_is_its_buffer(monkeypatch):
    monkeypatch.setattr(P, "LOCAL_MIN", 4)  # every polygon moved
    rng = np.random.default_rng(5)
    c = rng.uniform(-200, 200, (40, 2)) + (5.2e5, 4.9e6)
    polys = shapely.buffer(shapely.points(c), rng.uniform(5, 40, 40), quad_segs=3)
    polys = shapely.difference(polys, shapely.buffer(shapely.points(c + 1.0), 2.0))  # with holes
    d = rng.uniform(-6, 3, 40)
    got, want = buffer_local(polys, d, join_style="mitre"), shapely.buffer(polys, d, join_style="mitre")
    assert shapely.is_valid(got).all()
    np.testing.assert_allclose(shapely.area(got), shapely.area(want), rtol=1e-9)
    assert max(shapely.hausdorff_distance(got, want)) < 1e-6


def test_inset_square_and_per_polygon_distances():
    polys = [shapely.box(0, 0, 10, 10), shapely.box(0, 0, 10, 4)]
    out = inset(polys, [1.0, 2.5])
    assert shapely.equals(out[0], shapely.box(1, 1, 9, 9))
    assert out[1].is_empty  # thinner than twice the distance
    assert shapely.equals(inset(polys[0], 2.0), shapely.box(2, 2, 8, 8))


def test_inset_mitre_limit_and_rounded_joins():
    ell = shapely.Polygon([(0, 0), (10, 0), (10, 4), (4, 4), (4, 10), (0, 10)])
    sharp = inset([ell], 1.0)[0]
    assert sharp.area == pytest.approx(8 * 2 + 2 * 6)  # an L of arms 2 wide, mitred
    blunt = inset([ell], 1.0, rounded=[True])[0]
    # the re-entrant corner rounded by two segments a quarter circle: the unit square less their fan
    assert blunt.area == pytest.approx(28 + 1 - 2 * 0.5 * np.sin(np.pi / 4))
    # a thin notch: its sharp re-entrant tip is mitre-limited (bevelled: more ground left)
    notch = shapely.Polygon([(0, 0), (10, 0), (10, 10), (5.5, 10), (5, 4), (4.5, 10), (0, 10)])
    areas = [inset([notch], 0.5, mitre_limit=1.0)[0].area, inset([notch], 0.5)[0].area]  # 1, the default 3
    areas.append(inset([notch], 0.5, mitre_limit=10.0)[0].area)
    assert areas[0] > areas[1] + 0.5 > areas[2] + 1.0
    assert areas[1] == inset([notch], 0.5, mitre_limit=3.0)[0].area
    # the mitre limit reaches the polygons not rounded when some are
    mixed = inset([notch, ell], 0.5, mitre_limit=10.0, rounded=[False, True])
    assert mixed[0].area == areas[2]
    both = inset([ell, ell], 1.0, rounded=[False, True])
    assert both[0].equals(sharp) and both[1].equals(blunt)
    assert inset([ell], 1.0, rounded=[False])[0].equals(sharp)


def test_inset_threads_give_the_one_thread_result():
    rng = np.random.default_rng(4)
    xy = rng.uniform(0, 1000, (PARALLEL_MIN + 11, 2))
    notch = shapely.Polygon([(0, 0), (10, 0), (10, 10), (5.5, 10), (5, 4), (4.5, 10), (0, 10)])
    polys = np.array([shapely.affinity.translate(notch, x, y) for x, y in xy])  # sharp re-entrant tips
    d = rng.uniform(0.3, 0.6, len(xy))
    for mitre in (3.0, 10.0):
        one = inset(polys, d, threads=1, mitre_limit=mitre)
        for threads in (2, 3):
            got = inset(polys, d, threads=threads, mitre_limit=mitre)
            assert shapely.to_wkb(got).tolist() == shapely.to_wkb(one).tolist()


# --- clip_frame_boxes ----------------------------------------------------------------------------


def test_clip_frame_boxes_is_the_intersection_with_the_frame_box():
    rng = np.random.default_rng(5)
    k = 40
    geoms = shapely.buffer(shapely.points(rng.uniform(0, 50, (k, 2))), rng.uniform(2, 9, k), quad_segs=3)
    center = shapely.get_coordinates(shapely.centroid(geoms)) + rng.uniform(-3, 3, (k, 2))
    t = rng.uniform(0, np.pi, k)
    axis = np.c_[np.cos(t), np.sin(t)]
    a0, b0 = rng.uniform(-6, 0, k), rng.uniform(-6, 0, k)
    a1, b1 = a0 + rng.uniform(1, 8, k), b0 + rng.uniform(1, 8, k)
    got = clip_frame_boxes(geoms, center, axis, a0, a1, b0, b1)
    want = shapely.intersection(geoms, frame_boxes(center, axis, a0, a1, b0, b1))
    assert shapely.is_valid(got).all()
    assert np.allclose(shapely.area(got), shapely.area(want), atol=1e-9)
    assert np.allclose(shapely.area(shapely.symmetric_difference(got, want)), 0.0, atol=1e-7)
    assert (shapely.area(want) > 0).sum() > 30  # the check is not vacuous
    empty = clip_frame_boxes([], [], [], [], [], [], [])
    assert len(empty) == 0 and empty.dtype == object


def test_clip_frame_boxes_by_hand():
    sq = shapely.box(0, 0, 10, 10)
    (piece,) = clip_frame_boxes([sq], [5, 5], [0, 1], [-2], 20, -1, 3)  # a along +y, b along -x
    assert shapely.equals(piece, shapely.box(2, 3, 6, 10))


# --- containing, shared_areas, largest_share -----------------------------------------------------


def test_clip_frame_boxes_flat_and_reversed_frames_and_scalars():
    sq = shapely.box(0, 0, 10, 10)
    # a zero-width interval is no rectangle: nothing is kept (it once gave a 1 m strip)
    flat_a, flat_b = clip_frame_boxes([sq, sq], [0, 0], [1, 0], [2, 2], [2, 6], [1, 3], [5, 3])
    assert flat_a.is_empty and flat_b.is_empty
    # reversed ends are the interval between them, as frame_boxes makes it
    (rev,) = clip_frame_boxes([sq], [0, 0], [1, 0], [6], [2], [5], [1])
    assert rev.equals(shapely.box(2, 1, 6, 5))
    # scalar bounds and one frame broadcast over every geometry
    got = clip_frame_boxes([sq, shapely.box(0, 0, 3, 3)], [0, 0], [1, 0], 2, 6, 1, 5)
    assert got[0].equals(shapely.box(2, 1, 6, 5)) and got[1].equals(shapely.box(2, 1, 3, 3))
    # a flat row among good ones leaves the good ones as the all-good call makes them
    mixed = clip_frame_boxes([sq, sq], [0, 0], [1, 0], [2, 2], [2, 6], [1, 1], [5, 5])
    assert mixed[0].is_empty and mixed[1].equals(shapely.box(2, 1, 6, 5))


def test_containing_lowest_index_and_none():
    polys = [shapely.box(0, 0, 10, 10), shapely.box(5, 5, 15, 15), shapely.box(20, 0, 30, 10)]
    pts = shapely.points([(7, 7), (12, 12), (1, 1), (17, 2), (10, 2), (25, 5), (8, 8)])
    # (10, 2) is on a boundary: not within; (7, 7) and (8, 8) lie in 0 and 1: the lowest
    assert containing(pts, polys).tolist() == [0, 1, 0, -1, -1, 2, 0]
    assert containing(pts, []).tolist() == [-1] * 7
    out = containing([], polys)
    assert out.dtype == np.int64 and len(out) == 0
    assert containing(shapely.points([(50, 50)]), polys).tolist() == [-1]


def test_shared_areas_empty_and_disjoint():
    for g, o in (([], [shapely.box(0, 0, 1, 1)]), ([shapely.box(0, 0, 1, 1)], [])):
        gi, oi, area = shared_areas(g, o)
        assert len(gi) == len(oi) == len(area) == 0 and gi.dtype == oi.dtype == np.int64
    gi, oi, area = shared_areas([shapely.box(0, 0, 1, 1)], [shapely.box(5, 5, 6, 6)])
    assert len(gi) == len(area) == 0
    tri = shapely.Polygon([(0, 0), (10, 0), (0, 10)])  # the box lies in its bounding box, off the triangle
    gi, oi, area = shared_areas([tri], [shapely.box(8, 8, 9, 9), shapely.box(1, 1, 2, 2)])
    assert gi.tolist() == [0] and oi.tolist() == [1] and area.tolist() == [1.0]


def test_largest_share_ties_and_misses():
    lots = [shapely.box(0, 0, 10, 10), shapely.box(10, 0, 20, 10)]
    things = [shapely.box(6, 0, 14, 1), shapely.box(12, 0, 13, 1), shapely.box(30, 0, 31, 1), shapely.box(9, 0, 10, 1)]
    assert largest_share(things, lots).tolist() == [0, 1, -1, 0]
    assert largest_share([], lots).tolist() == []


# --- subtract_buffers ----------------------------------------------------------------------------


def test_subtract_buffers_by_hand():
    sq = shapely.box(0, 0, 10, 10)
    other = shapely.box(20, 0, 30, 10)
    through = shapely.LineString([(-5, 5), (15, 5)])
    out = subtract_buffers([sq, other], [through], [0], 1.0)
    assert out[0].area == pytest.approx(80.0) and out[1] is other
    short = shapely.LineString([(3, 5), (7, 5)])
    q = 8 * np.sin(np.pi / 8)  # two half caps: a 16-gon of radius 1
    for cap, cut in (("flat", 8.0), ("square", 12.0), ("round", 8.0 + q)):
        assert subtract_buffers([sq], [short], [0], 1.0, cap_style=cap)[0].area == pytest.approx(100 - cut)
    r2 = subtract_buffers([sq], [short], [0], 1.0, quad_segs=1)[0].area  # a square diamond at each end
    assert r2 == pytest.approx(100 - 8.0 - 2.0)


def test_subtract_buffers_distances_rounds_and_zero():
    sq = shapely.box(0, 0, 10, 10)
    a = shapely.LineString([(-5, 2), (15, 2)])
    b = shapely.LineString([(-5, 8), (15, 8)])
    c = shapely.LineString([(2, -5), (2, 15)])
    out = subtract_buffers([sq], [a, b, c], [0, 0, 0], [0.5, 1.0, 0.0])
    assert out[0].area == pytest.approx(100 - 10 - 20)  # c at 0 takes nothing
    assert subtract_buffers([sq], [a], [0], 0.0)[0] is sq
    assert subtract_buffers([sq], [a], [0], -1.0)[0] is sq
    # three distances on one polygon: three rounds
    out = subtract_buffers([sq, sq], [a, b, c, a], [0, 0, 0, 1], [0.5, 1.0, 1.5, 2.0])
    assert out[0].area == pytest.approx(100 - 10 - 20 - 3 * 7)
    assert out[1].area == pytest.approx(100 - 40)


def test_subtract_buffers_distances_apart_by_more_than_a_mm_stay_apart():
    sq = shapely.box(0, 0, 10, 10)
    a = shapely.LineString([(-5, 2), (15, 2)])
    b = shapely.LineString([(-5, 8), (15, 8)])
    out = subtract_buffers([sq], [a, b], [0, 0], [1.0, 1.3])
    assert out[0].area == pytest.approx(100 - 20 - 26)


def test_subtract_buffers_merges_lines_of_one_distance():
    sq = shapely.box(0, 0, 10, 10)
    parts = [shapely.LineString([(-5, 5), (5, 5)]), shapely.LineString([(5, 5), (15, 5)])]
    merged = subtract_buffers([sq], parts, [0, 0], [1.0, 1.0004])  # equal to the mm: one buffer of the longer reach
    assert merged[0].area == pytest.approx(100 - 10 * 2 * 1.0004)


# --- right_of_lines ------------------------------------------------------------------------------


def test_right_of_lines_by_hand():
    box = (0, 0, 10, 10)
    east = shapely.LineString([(-1, 5), (11, 5)])
    (south,) = right_of_lines([east], box)
    assert shapely.equals(south, shapely.box(0, 0, 10, 5))
    (north,) = right_of_lines([east.reverse()], box)
    assert shapely.equals(north, shapely.box(0, 5, 10, 10))
    none = right_of_lines([], box)
    assert len(none) == 0 and none.dtype == object
    assert len(right_of_lines([shapely.LineString([(2, 5), (8, 5)])], box)) == 0  # ends inside: closes nothing
    assert len(right_of_lines([shapely.LineString([(20, 5), (30, 5)])], box)) == 0  # outside: the box is whole


def test_right_of_lines_probes_a_millimetre_off_long_lines():
    """A 3 km coast 1 m inside a 4 m tall box: probes must stay a millimetre off it, whatever its length."""
    (south,) = right_of_lines([shapely.LineString([(-1, 1), (3001, 1)])], (0, 0, 3000, 4))
    assert shapely.equals(south, shapely.box(0, 0, 3000, 1))


def test_right_of_lines_votes_add_up():
    """The middle part is right of two segments and left of one: 2 - 1 > 0, it is kept."""
    low = shapely.LineString([(11, 2), (5, 2), (-1, 2)])  # westwards: the right is north
    high = shapely.LineString([(11, 8), (-1, 8)])
    parts = right_of_lines([low, high], (0, 0, 10, 10))
    assert sorted(shapely.bounds(parts).tolist()) == [[0, 2, 10, 8], [0, 8, 10, 10]]


def test_right_of_lines_repeated_vertices_and_two_coasts():
    box = (0, 0, 10, 10)
    east = shapely.LineString([(-1, 2), (4, 2), (4, 2), (11, 2)])  # a repeated vertex: no probe of length 0
    west = shapely.LineString([(11, 8), (-1, 8)])
    parts = right_of_lines([east, west], box)
    assert sorted(shapely.bounds(parts).tolist()) == [[0, 0, 10, 2], [0, 8, 10, 10]]
