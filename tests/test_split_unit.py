"""sengine.geom.split, function by function, on small polygons whose pieces are worked out by hand.

test_split compares the cut with GEOS on random stars; these pin exact pieces (vertices, rings, marks,
order, sides), the degenerate paths (cuts through vertices and along edges, holes, refused cuts) and the
helpers, for the mutation run of docs/mutation.md.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import shapely
from _oracles import split_by_line

from sengine.geom.split import RingSet, _cycles, _hole_owner, _inside, _pieces, _signed, _twice_on_line, cut_lengths
from sengine.geom.split import split as split_

SQUARE = shapely.box(0, 0, 4, 4)
# a U (opening up), arms 3 m wide, base 3 m high
U_SHAPE = [(0, 0), (10, 0), (10, 10), (7, 10), (7, 3), (3, 3), (3, 10), (0, 10)]
# an E (comb opening right): three teeth 1 m high
COMB = shapely.Polygon([(0, 0), (5, 0), (5, 1), (1, 1), (1, 2), (5, 2), (5, 3), (1, 3), (1, 4), (5, 4), (5, 5), (0, 5)])


def split(rs, point, direction, **kw):
    """``split``, checking what holds for every call: shapes of the outputs, dtypes, valid counter-clockwise pieces."""
    pieces, parent, side, failed = split_(rs, point, direction, **kw)
    assert parent.dtype == np.int64 and side.dtype == np.int8 and failed.dtype == bool and pieces.flag.dtype == bool
    assert len(parent) == len(side) == pieces.n and failed.shape == (rs.n,)
    assert not failed[parent].any()
    out = pieces.polygons()
    assert shapely.is_valid(out).all() and (shapely.area(out) > 0).all()
    shell = np.r_[True, pieces.poly[1:] != pieces.poly[:-1]][: len(pieces.poly)]
    ar = pieces.ring_areas()
    assert (ar[shell] > 0).all() and (ar[~shell] < 0).all()  # shells counter-clockwise, holes clockwise
    return pieces, parent, side, failed


def wkt(pieces) -> list[str]:
    return [g.wkt for g in pieces.polygons()]


def with_flags(rs, flags) -> RingSet:
    return dataclasses.replace(rs, flag=np.asarray(flags, bool))


def test_signed_distances_and_abscissae_by_hand():
    rs = RingSet.from_polygons([SQUARE, shapely.box(10, 10, 11, 12)])
    # polygon 0: the line x = 1 upwards (direction of any length); polygon 1: y = 10 leftwards
    s, t, vp, d = _signed(rs, [(1, 0), (0, 10)], [(0, 3), (-2, 0)])
    assert vp.tolist() == [0, 0, 0, 0, 1, 1, 1, 1]
    assert d.tolist() == [[0, 1], [-1, 0]]
    # left of an upward line is x < 1: s = 1 - x; t = y
    assert rs.xy[:4].tolist() == [[4, 0], [4, 4], [0, 4], [0, 0]]
    assert s[:4].tolist() == [-3, -3, 1, 1] and t[:4].tolist() == [0, 4, 4, 0]
    # left of a leftward line is y < 10: s = 10 - y; t = -x
    assert rs.xy[4:].tolist() == [[11, 10], [11, 12], [10, 12], [10, 10]]
    assert s[4:].tolist() == [0, -2, -2, 0] and t[4:].tolist() == [-11, -11, -10, -10]
    # one point and direction for every polygon, as flat pairs
    s1, t1, _, _ = _signed(rs.take([0]), (1, 0), (0, 1))
    assert s1.tolist() == [-3, -3, 1, 1] and t1.tolist() == [0, 4, 4, 0]
    # a zero direction gives zeros, not NaN
    s0, t0, _, _ = _signed(rs.take([0]), [(1, 0)], [(0, 0)])
    assert s0.tolist() == [0, 0, 0, 0] and t0.tolist() == [0, 0, 0, 0]


def test_cut_lengths_by_hand():
    tri = shapely.Polygon([(10, 0), (13, 0), (13, 4)])  # legs 3, 4, hypotenuse 5
    rs = RingSet.from_polygons([SQUARE, tri, shapely.box(20, 0, 21, 1), shapely.Polygon()])
    n, left, right = cut_lengths(rs, [(1, 0), (10, 2), (0, 5), (0, 0)], [(0, 1), (1, 0), (1, 0), (1, 0)])
    assert n.dtype == np.int64 and n.tolist() == [2, 2, 0, 0]
    # square at x = 1: left (x < 1) 1 + 4 + 1, right 3 + 4 + 3; triangle at y = 2: above, half the legs
    # 4 and 5; the third square lies right of (below) its line, the empty polygon has nothing
    assert left.tolist() == [6, 4.5, 0, 0]
    assert right.tolist() == [10, 7.5, 4, 0]
    # only marked edges count: the square's right side (all right of x = 1) and bottom (1 m left of it)
    marked = with_flags(rs.take([0]), [True, False, False, True])  # edges from (4,0), (4,4), (0,4), (0,0)
    assert marked.xy.tolist() == [[4, 0], [4, 4], [0, 4], [0, 0]]
    n, left, right = cut_lengths(marked, [(1, 0)], [(0, 1)])
    assert n.tolist() == [2] and left.tolist() == [1] and right.tolist() == [7]


def test_cut_lengths_of_an_edge_on_the_line():
    """An edge on the line goes with the side its polygon's interior is on."""
    rs = RingSet.from_polygons([SQUARE])
    n, left, right = cut_lengths(rs, [(0, 0)], [(0, 1)])  # along the left side, interior on the right
    assert n.tolist() == [2] and left.tolist() == [0] and right.tolist() == [16]
    n, left, right = cut_lengths(rs, [(0, 0)], [(0, -1)])  # the same side, downwards: interior on the left
    assert n.tolist() == [0] and left.tolist() == [16] and right.tolist() == [0]
    n, left, right = cut_lengths(rs, [(0, 4)], [(1, 0)])  # along the top, interior below: right
    assert n.tolist() == [2] and left.tolist() == [0] and right.tolist() == [16]


def test_a_square_cut_in_two_by_hand():
    rs = RingSet.from_polygons([SQUARE])
    for chord_flag in (False, True):
        pieces, parent, side, failed = split(rs, [(1, 0)], [(0, 1)], chord_flag=chord_flag)
        assert not failed[0] and parent.tolist() == [0, 0] and side.tolist() == [1, 0]
        assert pieces.n == 2 and pieces.poly.tolist() == [0, 1]
        assert pieces.xy.tolist() == [[1, 4], [0, 4], [0, 0], [1, 0], [4, 0], [4, 4], [1, 4], [1, 0]]
        assert pieces.ring.tolist() == [0, 0, 0, 0, 1, 1, 1, 1]
        c = chord_flag
        assert pieces.flag.tolist() == [True, True, True, c, True, True, c, True]  # the chords: (1,0)-(1,4)
        assert pieces.areas().tolist() == [4, 12]
    # an unmarked polygon: only the chords take the mark
    pieces, _, _, _ = split(RingSet.from_polygons([SQUARE], flag=False), [(1, 0)], [(0, 1)], chord_flag=True)
    assert pieces.flag.tolist() == [False, False, False, True, False, False, True, False]


def test_a_batch_gives_all_left_pieces_then_all_right_ones():
    rs = RingSet.from_polygons([SQUARE, shapely.box(10, 0, 12, 2), shapely.box(20, 0, 21, 1)])
    pieces, parent, side, failed = split(rs, [(1, 0), (10, 1), (0, 5)], [(0, 1), (1, 0), (1, 0)])
    assert not failed.any()
    assert parent.tolist() == [0, 1, 0, 1, 2] and side.tolist() == [1, 1, 0, 0, 0]
    assert pieces.areas().tolist() == [4, 2, 12, 2, 1]
    assert wkt(pieces)[4] == "POLYGON ((21 0, 21 1, 20 1, 20 0, 21 0))"  # missed by its line: itself


def test_a_line_through_two_vertices_of_a_diamond():
    """Vertices on the line count as left: the chord runs from vertex to vertex."""
    rs = RingSet.from_polygons([shapely.Polygon([(0, -2), (2, 0), (0, 2), (-2, 0)])])
    pieces, parent, side, failed = split(rs, [(0, 0)], [(1, 0)])
    assert not failed[0] and side.tolist() == [1, 0]
    assert wkt(pieces) == ["POLYGON ((2 0, 0 2, -2 0, 2 0))", "POLYGON ((0 -2, 2 0, -2 0, 0 -2))"]
    assert pieces.flag.tolist() == [True, True, False, True, False, True]
    # turned a little, the line misses the vertices: the same pieces but for the rounding
    ang = np.deg2rad(33.0)
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    turned = dataclasses.replace(rs, xy=rs.xy @ rot.T)
    pieces2, _, side2, _ = split(turned, [(0.0, 0.0)], [rot[:, 0]])
    assert side2.tolist() == [1, 0] and np.allclose(pieces2.areas(), [4, 4], rtol=0, atol=1e-12)


def test_a_cut_along_a_marked_edge_keeps_its_mark():
    """The cut along a rectangle's top side: the rectangle itself, its top still marked (the chord runs along it)."""
    rs = RingSet.from_polygons([shapely.box(0, 0, 6, 2)])
    for chord_flag in (False, True):
        pieces, parent, side, failed = split(rs, [(0, 2)], [(1, 0)], chord_flag=chord_flag)
        assert not failed[0] and parent.tolist() == [0] and side.tolist() == [0]
        assert wkt(pieces) == ["POLYGON ((6 0, 6 2, 0 2, 0 0, 6 0))"]
        assert pieces.flag.all()
    # unmarked, the chord along it takes the chord's mark
    plain = RingSet.from_polygons([shapely.box(0, 0, 6, 2)], flag=False)
    pieces, _, _, _ = split(plain, [(0, 2)], [(1, 0)], chord_flag=True)
    assert pieces.flagged_length().tolist() == [6.0] and pieces.flag.tolist() == [
        False,
        True,
        False,
        False,
    ]  # the top: (6,2)-(0,2)
    # the mark covers only the chord of the marked edge's polygon, and one edge along the line of two
    rs2 = RingSet.from_polygons([shapely.box(0, 0, 6, 2), shapely.box(0, 0, 6, 2)])
    pieces, parent, _, _ = split(with_flags(rs2, [0, 1, 0, 0, 0, 0, 0, 0]), [(0, 2), (0, 2)], [(1, 0), (1, 0)])
    assert parent.tolist() == [0, 1] and pieces.flagged_length().tolist() == [6.0, 0.0]
    # the other way round the top lies left of the line: no crossing, the rectangle on the left
    pieces, parent, side, failed = split(rs, [(0, 2)], [(-1, 0)])
    assert side.tolist() == [1] and pieces.flag.all() and pieces.areas().tolist() == [12]


def test_a_chord_partly_along_a_marked_edge():
    """An L cut along its inner step: the chord from its outer side to the step's corner is not on an edge."""
    ell = shapely.Polygon([(0, 0), (4, 0), (4, 2), (2, 2), (2, 4), (0, 4)])
    pieces, parent, side, failed = split(RingSet.from_polygons([ell]), [(0, 2)], [(-1, 0)])
    assert not failed[0] and side.tolist() == [1, 0]
    out = pieces.polygons()
    assert shapely.equals(out, [shapely.box(0, 0, 4, 2), shapely.box(0, 2, 2, 4)]).all()
    assert pieces.flagged_length().tolist() == [10.0, 6.0]  # the chord (0,2)-(2,2) is unmarked


def test_a_comb_cut_across_its_teeth():
    """Six crossings on one line (sorted by lexsort): the spine and three teeth."""
    pieces, parent, side, failed = split(RingSet.from_polygons([COMB]), [(3, 0)], [(0, 1)])
    assert not failed[0] and parent.tolist() == [0, 0, 0, 0] and side.tolist() == [1, 0, 0, 0]
    assert wkt(pieces) == [
        "POLYGON ((3 1, 1 1, 1 2, 3 2, 3 3, 1 3, 1 4, 3 4, 3 5, 0 5, 0 0, 3 0, 3 1))",
        "POLYGON ((3 0, 5 0, 5 1, 3 1, 3 0))",
        "POLYGON ((3 2, 5 2, 5 3, 3 3, 3 2))",
        "POLYGON ((3 4, 5 4, 5 5, 3 5, 3 4))",
    ]
    assert pieces.flag.tolist() == [True, True, True, False] * 6
    n, left, right = cut_lengths(RingSet.from_polygons([COMB]), [(3, 0)], [(0, 1)])
    assert n.tolist() == [6] and left.tolist() == [21] and right.tolist() == [15]
    # the same comb turned over (the cut downwards): the teeth on the left, in the order of their rings
    pieces, parent, side, failed = split(RingSet.from_polygons([COMB]), [(3, 5)], [(0, -1)])
    assert side.tolist() == [1, 1, 1, 0] and pieces.areas().tolist() == [2, 2, 2, 11]


def test_a_u_cut_across_its_arms_with_a_hole_in_one():
    """Two pieces above the line: the hole goes to the arm that holds it (the point-in-ring test)."""
    hole_right = [(8, 6), (8, 8), (9, 8), (9, 6)]
    hole_left = [(1, 6), (1, 8), (2, 8), (2, 6)]
    rs = RingSet.from_polygons([shapely.Polygon(U_SHAPE, [hole_right]), shapely.Polygon(U_SHAPE, [hole_left])])
    pieces, parent, side, failed = split(rs, [(0, 5), (0, 5)], [(1, 0), (1, 0)])
    assert not failed.any()
    assert parent.tolist() == [0, 0, 1, 1, 0, 1] and side.tolist() == [1, 1, 1, 1, 0, 0]
    assert wkt(pieces)[:4] == [
        "POLYGON ((10 5, 10 10, 7 10, 7 5, 10 5), (8 6, 8 8, 9 8, 9 6, 8 6))",
        "POLYGON ((3 5, 3 10, 0 10, 0 5, 3 5))",
        "POLYGON ((10 5, 10 10, 7 10, 7 5, 10 5))",
        "POLYGON ((3 5, 3 10, 0 10, 0 5, 3 5), (1 6, 1 8, 2 8, 2 6, 1 6))",
    ]
    base = "POLYGON ((7 5, 7 3, 3 3, 3 5, 0 5, 0 0, 10 0, 10 5, 7 5))"
    assert wkt(pieces)[4:] == [base, base]
    assert pieces.areas().tolist() == [13, 15, 15, 13, 42, 42]


def test_holes_on_one_side_and_cut_open():
    holed = shapely.box(0, 0, 10, 10).difference(shapely.box(4, 4, 6, 6))
    rs = RingSet.from_polygons([holed, holed, holed])
    pieces, parent, side, failed = split(rs, [(0, 8), (0, 5), (0, 2)], [(1, 0), (1, 0), (-1, 0)])
    assert not failed.any()
    assert parent.tolist() == [0, 1, 2, 0, 1, 2] and side.tolist() == [1, 1, 1, 0, 0, 0]
    # the hole below the first line (right of it), above the third (right of it: lines run the other way)
    assert shapely.get_num_interior_rings(pieces.polygons()).tolist() == [0, 0, 0, 1, 0, 1]
    assert pieces.areas().tolist() == [20, 48, 20, 76, 48, 76]
    assert wkt(pieces)[1] == "POLYGON ((10 5, 10 10, 0 10, 0 5, 4 5, 4 6, 6 6, 6 5, 10 5))"


def test_a_clockwise_polygon_is_refused_and_its_batch_goes_on():
    """Crossings that do not alternate (here: a ring given clockwise) fail; the others are cut as alone."""
    sq = RingSet.from_polygons([SQUARE])
    cw = RingSet(sq.xy[::-1].copy(), np.zeros(4, np.int64), np.ones(4, bool), np.zeros(1, np.int64), 1)
    rs = RingSet.concat([sq, cw, RingSet.from_polygons([shapely.box(10, 0, 12, 2)]), cw])
    pt, d = [(1, 0), (1, 0), (10, 1), (1, 0)], [(0, 1), (0, 1), (1, 0), (0, 1)]
    pieces, parent, side, failed = split(rs, pt, d, chord_flag=True)
    assert failed.tolist() == [False, True, False, True]
    assert parent.tolist() == [0, 2, 0, 2] and side.tolist() == [1, 1, 0, 0]
    assert pieces.areas().tolist() == [4, 2, 12, 2]
    assert pieces.flag[:4].tolist() == [True] * 4  # chord_flag passed on to the polygons cut again
    # a clockwise ring the line misses is no crossing problem: itself
    pieces, parent, side, failed = split_(cw, [(9, 0)], [(0, 1)])
    assert not failed[0] and parent.tolist() == [0] and side.tolist() == [1]


def test_refused_cuts_along_edges_in_a_batch():
    """A slit or a spike on a piece fails its polygon only; ``touch_tol`` sets how near counts as on."""
    exact = shapely.Polygon([(0, 0), (2, 0), (2, 4), (1, 4), (1, 2), (-1, 2), (-1, 0)])  # inner side on x = 1
    rs = RingSet.from_polygons([SQUARE, exact, shapely.box(10, 0, 12, 2)])
    pieces, parent, side, failed = split(rs, [(1, 0), (1, 0), (10, 1)], [(0, 1), (0, 1), (1, 0)])
    assert failed.tolist() == [False, True, False]
    assert parent.tolist() == [0, 2, 0, 2] and pieces.areas().tolist() == [4, 2, 12, 2]
    # an L whose inner step is 1e-7 m off the line: a thin sliver, checked (and refused) within the tolerance
    ell = shapely.Polygon([(0, 0), (4, 0), (4, 2), (1, 2 + 1e-7), (1, 4), (0, 4)])
    one = RingSet.from_polygons([ell])
    assert split_(one, [(0, 2)], [(1, 0)], touch_tol=1e-6)[3].tolist() == [True]
    pieces, parent, side, failed = split(one, [(0, 2)], [(1, 0)], touch_tol=1e-9)
    assert not failed[0] and len(parent) == 2  # the upper piece keeps a 3 m sliver 1e-7 m high: valid
    assert np.isclose(pieces.areas().sum(), ell.area, rtol=1e-12)


def test_split_of_empty_and_missed_polygons():
    rs = RingSet.from_polygons([shapely.Polygon(), SQUARE, shapely.Polygon()])
    pieces, parent, side, failed = split(rs, [(0, 0), (9, 9), (0, 0)], [(1, 0), (1, 0), (1, 0)])
    assert failed.tolist() == [False] * 3 and parent.tolist() == [1] and side.tolist() == [0]
    # a line touching only a corner: the square on the right, whole
    pieces, parent, side, failed = split(RingSet.from_polygons([SQUARE]), [(4, 4)], [(1, -1)])
    assert parent.tolist() == [0] and side.tolist() == [0] and pieces.areas().tolist() == [16]
    assert len(pieces.xy) == 4  # the corner once, not repeated
    pieces, parent, side, failed = split(RingSet.from_polygons([]), np.zeros((0, 2)), np.zeros((0, 2)))
    assert pieces.n == 0 and len(parent) == 0 and len(failed) == 0


def test_pieces_of_turned_polygons_partition_them():
    """Stars with and without holes, turned and moved far from the origin, cut through their centre:
    the pieces on each side are GEOS's intersection with that half-plane, and keep the outline's length."""
    rng = np.random.default_rng(7)
    polys, pts, dirs = [], [], []
    for i in range(24):
        k = 5 + i % 7
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        r = rng.uniform(3, 10, k)
        p = shapely.Polygon(np.c_[r * np.cos(ang), r * np.sin(ang)])
        if not p.is_valid:
            continue
        if i % 3 == 0 and p.contains(shapely.box(-1, -1, 1, 1)):
            p = p.difference(shapely.box(-1, -1, 1, 1))
        p = shapely.affinity.translate(shapely.affinity.rotate(p, 17.0 * i), 5e5, 5.6e6)
        a = rng.uniform(0, np.pi)
        polys.append(p)
        pts.append((5e5 + rng.uniform(-1.5, 1.5), 5.6e6 + rng.uniform(-1.5, 1.5)))
        dirs.append((np.cos(a), np.sin(a)))
    polys, pts, dirs = np.array(polys, dtype=object), np.array(pts), np.array(dirs)
    rs = RingSet.from_polygons(polys)
    pieces, parent, side, failed = split(rs, pts, dirs)
    assert not failed.any()
    out = pieces.polygons()
    left, right = split_by_line(polys, pts, dirs)
    for s, ref in ((1, left), (0, right)):
        got = np.bincount(parent[side == s], weights=shapely.area(out[side == s]), minlength=len(polys))
        assert np.allclose(got, shapely.area(ref), rtol=0, atol=1e-6)
        # each side's pieces are the parts of GEOS's side (as many, the same union)
        assert np.bincount(parent[side == s], minlength=len(polys)).tolist() == [len(shapely.get_parts(g)) for g in ref]
    marked = np.bincount(parent, weights=pieces.flagged_length(), minlength=len(polys))
    assert np.allclose(marked, shapely.length(polys), rtol=1e-12)
    n, lft, rgt = cut_lengths(rs, pts, dirs)
    assert np.allclose(lft + rgt, shapely.length(polys), rtol=1e-12)
    assert (n >= 2).all() and (n % 2 == 0).all()


def test_twice_on_line_by_hand():
    """Two edges of one polygon on its line overlapping by more than ``tol``: a slit."""
    # a square with a slit cut in from its bottom side along y = 0 ... (0.5,0) back to (3,0)
    slit = shapely.Polygon([(0, 0), (3, 0), (1, 1e-15), (0.5, 0), (0.5, -1), (4, -1), (4, 2), (0, 2)])
    u = shapely.Polygon([(0, 0), (1, 0), (1, 1), (2, 1), (2, 0), (3, 0), (3, 2), (0, 2)])
    rs = RingSet.from_polygons([slit, u, SQUARE])
    got = _twice_on_line(rs, [(0, 0), (0, 0), (0, 0)], [(1, 0), (1, 0), (1, 0)], 1e-9)
    assert got.dtype == bool and got.tolist() == [True, False, False]
    # edges meeting end to end on the line (a straight side in two edges): no overlap
    two = shapely.Polygon([(0, 0), (1, 0), (2, 0), (2, 2), (0, 2)])
    assert _twice_on_line(RingSet.from_polygons([two]), [(0, 0)], [(1, 0)], 1e-9).tolist() == [False]
    # overlaps up to tol are rounding, not slits; edges within tol of the line count as on it
    near = shapely.Polygon([(0, 0), (3, 0), (1, 1e-3), (0.5, 0), (0.5, -1), (4, -1), (4, 2), (0, 2)])
    rn = RingSet.from_polygons([near])
    assert _twice_on_line(rn, [(0, 0)], [(1, 0)], 1e-9).tolist() == [False]  # (1, 1e-3) is off the line
    assert _twice_on_line(rn, [(0, 0)], [(1, 0)], 2e-3).tolist() == [True]
    # edges [0, 0.5 + 5e-10] and [0.5, 3] on the line: an overlap of 5e-10 m
    xy = np.array([(0, 0), (0.5 + 5e-10, 0), (0.5 + 5e-10, 1), (0.5, 1), (0.5, 0), (3, 0), (3, 2), (0, 2)])
    rt = RingSet(xy, np.zeros(8, np.int64), np.ones(8, bool), np.zeros(1, np.int64), 1)
    assert _twice_on_line(rt, [(0, 0)], [(1, 0)], 1e-9).tolist() == [False]
    assert _twice_on_line(rt, [(0, 0)], [(1, 0)], 1e-10).tolist() == [True]
    # sorted by their low end, whatever their order on the ring (the line the other way)
    assert _twice_on_line(rs, [(0, 0)] * 3, [(-1, 0)] * 3, 1e-9).tolist() == [True, False, False]


def test_cycles_by_hand():
    nxt = np.array([2, 0, 1, 4, 3, 5, 7, 8, 9, 6])  # (0 2 1) (3 4) (5) (6 7 8 9)
    rep, rank = _cycles(nxt, 4)
    assert rep.tolist() == [0, 0, 0, 3, 3, 5, 6, 6, 6, 6]
    assert rank.tolist() == [0, 2, 1, 0, 1, 0, 0, 1, 2, 3]
    assert rank.dtype == np.int64
    rep, rank = _cycles(np.zeros(0, np.int64), 0)
    assert len(rep) == len(rank) == 0 and rank.dtype == np.int64
    # one long cycle: 0 -> 36 -> 35 ... -> 1 -> 0
    nxt = (np.arange(37) - 1) % 37
    rep, rank = _cycles(nxt, 37)
    assert (rep == 0).all() and rank.tolist() == [0] + list(range(36, 0, -1))
    perm = np.random.default_rng(3).permutation(50)
    rep, rank = _cycles(perm, 50)
    for i in range(50):  # the representative is the cycle's minimum; rank counts steps from it
        j, steps, low = i, 0, i
        while True:
            j = perm[j]
            low = min(low, j)
            if j == i:
                break
        assert rep[i] == low
        j = low
        while j != i:
            j, steps = perm[j], steps + 1
        assert rank[i] == steps


def test_inside_by_hand():
    ring = np.array([[0.0, 0], [4, 0], [4, 4], [2, 1], [0, 4]])  # a notch from the top
    assert _inside(np.array([1.0, 0.5]), ring) is True
    assert _inside(np.array([2.0, 3.0]), ring) is False  # in the notch
    assert _inside(np.array([3.5, 2.0]), ring) is True
    assert _inside(np.array([5.0, 2.0]), ring) is False
    assert _inside(np.array([4.0, 2.0]), ring) is False  # on the right side: outside (half-open in x)
    assert _inside(np.array([-1.0, 2.0]), ring) is False
    assert _inside(np.array([1.0, 2.0]), ring[::-1]) is True  # either orientation
    # on the bottom side (a horizontal edge at the point's height: no crossing, no 0/0 read): inside,
    # on the top side outside (half-open in y)
    assert _inside(np.array([1.0, 0.0]), np.array([[0.0, 0], [4, 0], [4, 4], [0, 4]])) is True
    assert _inside(np.array([2.0, 4.0]), np.array([[0.0, 0], [4, 0], [4, 4], [0, 4]])) is False


def test_hole_owner_and_pieces_by_hand():
    """Cycles of two parents: shells, a hole with one candidate shell, one with two, one with none."""
    a = shapely.box(0, 0, 4, 4)
    b = shapely.box(10, 0, 14, 4)
    c = shapely.box(20, 0, 24, 4)
    holes = [shapely.box(1, 1, 2, 2).exterior, shapely.box(11, 1, 12, 2).exterior, shapely.box(30, 1, 31, 2).exterior]
    hole_polys = [shapely.Polygon(shapely.orient_polygons(shapely.Polygon(h)).exterior.coords[::-1]) for h in holes]
    cs = RingSet(
        *_cat([a, hole_polys[0], b, c, hole_polys[1], hole_polys[2]]),
    )
    cyc_par = np.array([0, 0, 1, 1, 1, 2])  # parent of each cycle
    bad = np.zeros(3, bool)
    out, par = _pieces(cs, cyc_par, bad)
    assert par.tolist() == [0, 1, 1] and out.n == 3
    assert bad.tolist() == [False, False, True]  # parent 2: a hole and no shell
    assert out.poly.tolist() == [0, 0, 1, 1, 2]
    assert out.ring_areas().tolist() == [16, -1, 16, -1, 16]
    assert shapely.get_num_interior_rings(out.polygons()).tolist() == [1, 1, 0]  # the hole went into b
    # _hole_owner itself: index into shell_ids
    bad = np.zeros(3, bool)
    ar = cs.ring_areas()
    shell_ids, hole_ids = np.flatnonzero(ar > 0), np.flatnonzero(ar < 0)
    res = _hole_owner(cs, cyc_par[cs.poly], shell_ids, hole_ids, bad)
    assert res.tolist() == [0, 1, -1] and bad.tolist() == [False, False, True]
    # a hole outside both shells of its parent: refused
    far = shapely.Polygon(shapely.box(40, 1, 41, 2).exterior.coords)
    far = shapely.Polygon(shapely.orient_polygons(far).exterior.coords[::-1])
    cs2 = RingSet(*_cat([b, c, far]))
    bad = np.zeros(1, bool)
    res = _hole_owner(cs2, np.zeros(3, np.int64), np.array([0, 1]), np.array([2]), bad)
    assert res.tolist() == [-1] and bad.tolist() == [True]
    # flat cycles (collinear leftovers) are dropped, shells kept in order
    flat = shapely.Polygon([(0, 0), (2, 0), (1, 0)])
    cs3 = RingSet(*_cat([a, flat, b]))
    out, par = _pieces(cs3, np.array([0, 0, 1]), np.zeros(2, bool))
    assert par.tolist() == [0, 1] and out.areas().tolist() == [16, 16] and out.n == 2


def _cat(polys):
    """RingSet arrays with one polygon per ring, rings as given (orientation kept)."""
    xy, ring = [], []
    for i, p in enumerate(polys):
        c = np.asarray(p.exterior.coords)[:-1]
        xy.append(c)
        ring += [i] * len(c)
    k = len(polys)
    return np.concatenate(xy), np.array(ring, np.int64), np.ones(len(ring), bool), np.arange(k), k


def test_no_floating_point_warnings():
    """Edges parallel to the line (0/0 and x/0 in the crossing share, masked out) and horizontal edges in the
    point-in-ring test raise no warning."""
    rs = RingSet.from_polygons([SQUARE, COMB, shapely.box(10, 0, 12, 2)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cut_lengths(rs, [(0, 2), (0, 2.5), (0, 0)], [(1, 0), (1, 0), (1, 0)])
        split_(rs, [(0, 2), (0, 2.5), (0, 0)], [(1, 0), (1, 0), (1, 0)])
        assert _inside(np.array([1.0, 0.0]), np.array([[0.0, 0], [4, 0], [4, 4], [0, 4]]))


def test_crossings_at_vertices_are_the_vertices_themselves():
    """A vertex on the line is a crossing at exactly that vertex, whichever end of its edge it is: the
    crossing point is interpolated from the nearer end (0.9 + (0.3 - 0.9) is not 0.3 in floating point)."""
    # a trapezoid below y = 0 whose top (0.9, 0) .. (1.7, 0) carries a rectangle above it
    p = shapely.Polygon([(0.9, 0), (0.3, -1), (3.9, -1), (1.7, 0), (1.7, 1), (0.9, 1)])
    verts = {tuple(c) for c in np.asarray(p.exterior.coords)}
    turned = shapely.affinity.affine_transform(p, [0, -1, 1, 0, 0, 0])  # (x, y) -> (-y, x): the line x = 0
    for poly, point, d in (
        (p, (0, 0), (1, 0)),
        (p, (0, 0), (-1, 0)),
        (turned, (0, 0), (0, 1)),
        (turned, (0, 0), (0, -1)),
    ):
        vs = verts if poly is p else {(-y, x) for x, y in verts}
        pieces, parent, side, failed = split(RingSet.from_polygons([poly]), [point], [d])
        assert not failed[0] and len(parent) == 2
        assert {tuple(c) for c in pieces.xy.tolist()} <= vs
        assert np.allclose(sorted(pieces.areas().tolist()), [0.8, poly.area - 0.8], rtol=1e-12)


def test_a_vertex_touching_the_line_from_either_end_of_its_ring():
    """Two crossings at one vertex (the line touches the polygon there): ordered by the edges' directions,
    whether the ring starts at that vertex or not."""
    for ring in (
        [(4, 0), (4, 4), (0, 4), (0, 0)],
        [(4, 4), (0, 4), (0, 0), (4, 0)],
        [(0, 4), (0, 0), (4, 0), (4, 4)],
    ):
        rs = RingSet.from_polygons([shapely.Polygon(ring), shapely.Polygon(ring)])
        pieces, parent, side, failed = split(rs, [(4, 4), (4, 4)], [(1, -1), (-1, 1)])
        assert not failed.any() and parent.tolist() == [1, 0] and side.tolist() == [1, 0]
        assert pieces.areas().tolist() == [16, 16] and len(pieces.xy) == 8
    # the notch's tip touches y = 1 from above; the line crosses the sides too: four crossings
    notch = shapely.Polygon([(0, 0), (4, 0), (4, 4), (2, 1), (0, 4)])
    pieces, parent, side, failed = split(RingSet.from_polygons([notch]), [(0, 1)], [(-1, 0)])
    assert not failed[0] and side.tolist() == [1, 0, 0] and pieces.areas().tolist() == [4, 3, 3]
    # the other way round the tip counts as above the line: the upper piece would touch itself there
    assert split_(RingSet.from_polygons([notch]), [(0, 1)], [(1, 0)])[3].tolist() == [True]


def _sides_match_geos(polys, pts, dirs, *, atol, counts=False):
    """``split`` cuts every polygon, and each side's area per parent (and with ``counts``, its
    number of pieces) is GEOS's ``split_by_line``'s."""
    pieces, parent, side, failed = split(RingSet.from_polygons(polys), pts, dirs)
    assert not failed.any()
    left, right = split_by_line(polys, pts, dirs)
    out = pieces.polygons()
    for s, ref in ((1, left), (0, right)):
        got = np.bincount(parent[side == s], weights=shapely.area(out[side == s]), minlength=len(polys))
        assert np.allclose(got, shapely.area(ref), rtol=0, atol=atol)
        if counts:
            assert np.bincount(parent[side == s], minlength=len(polys)).tolist() == [
                len(shapely.get_parts(g)) for g in ref
            ]


def test_sliver_cuts_at_shallow_angles():
    """Thin quadrilaterals cut along their length at a shallow angle: the crossings lie close together along
    the line while the crossed edges run far along it (their order must be exact)."""
    rng = np.random.default_rng(11)
    polys, pts, dirs = [], [], []
    for _ in range(40):
        w, h = rng.uniform(5, 50), rng.uniform(0.05, 0.5)
        q = np.array([(0, 0), (w, rng.uniform(-h, h) * 0.2), (w, h), (0, h * rng.uniform(0.5, 1.5))])
        ang = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        p = shapely.Polygon(q @ rot.T)
        if not p.is_valid:
            continue
        c = np.asarray(p.centroid.coords[0])
        a = ang + rng.uniform(-0.02, 0.02)
        polys.append(shapely.orient_polygons(p))
        pts.append(c)
        dirs.append((np.cos(a), np.sin(a)))
    polys, pts, dirs = np.array(polys, dtype=object), np.array(pts), np.array(dirs)
    _sides_match_geos(polys, pts, dirs, atol=1e-9)


def test_chords_along_marked_edges_of_a_three_armed_comb():
    """An E opening up, cut along its arms' tops: three chords, each along a marked top (the third chord
    too: every chord's first crossing is looked at)."""
    e = shapely.Polygon(
        [(0, 0), (10, 0), (10, 2), (8, 2), (8, 1), (6, 1), (6, 2), (4, 2), (4, 1), (2, 1), (2, 2), (0, 2)]
    )
    pieces, parent, side, failed = split(RingSet.from_polygons([e]), [(0, 2)], [(1, 0)])
    assert not failed[0] and side.tolist() == [0] and pieces.areas().tolist() == [16]
    assert pieces.flagged_length().tolist() == [e.length]
    u = shapely.Polygon([(0, 0), (6, 0), (6, 2), (4, 2), (4, 1), (2, 1), (2, 2), (0, 2)])
    pieces, parent, side, failed = split(RingSet.from_polygons([u]), [(0, 2)], [(1, 0)])
    assert not failed[0] and pieces.flagged_length().tolist() == [u.length]


def test_refused_polygons_cut_again_keep_the_call_s_settings():
    """A batch with a polygon refused at the pairing (a clockwise ring) is cut again without it: with the
    same ``touch_tol``, and a polygon refused in that second cut is reported too."""
    sq = RingSet.from_polygons([SQUARE])
    cw = RingSet(sq.xy[::-1].copy(), np.zeros(4, np.int64), np.ones(4, bool), np.zeros(1, np.int64), 1)
    ell = RingSet.from_polygons([shapely.Polygon([(0, 0), (4, 0), (4, 2), (1, 2 + 1e-7), (1, 4), (0, 4)])])
    exact = RingSet.from_polygons([shapely.Polygon([(0, 0), (2, 0), (2, 4), (1, 4), (1, 2), (-1, 2), (-1, 0)])])
    rs = RingSet.concat([cw, ell, exact, sq])
    pt, d = [(1, 0), (0, 2), (1, 0), (1, 0)], [(0, 1), (1, 0), (0, 1), (0, 1)]
    pieces, parent, side, failed = split(rs, pt, d, touch_tol=1e-6)
    assert failed.tolist() == [True, True, True, False] and parent.tolist() == [3, 3]
    pieces, parent, side, failed = split(rs, pt, d)
    assert failed.tolist() == [True, False, True, False] and sorted(parent.tolist()) == [1, 1, 3, 3]


def test_flat_leftovers_are_measured_against_their_own_cycle():
    """A big holed polygon and a small one in one call: a piece's flatness is judged by its own size, so
    the small pieces (1 mm) stay."""
    big = shapely.box(0, 0, 1e5, 1e5).difference(shapely.box(1e4, 1e4, 2e4, 2e4))
    small = shapely.box(0, 0, 1e-3, 1e-3).difference(shapely.box(2e-4, 2e-4, 4e-4, 4e-4))
    tiny = shapely.affinity.scale(small, 1e-2, 1e-2, origin=(0, 0))  # 10 um: pieces of 5e-11 m2 are no flat leftovers
    # cut along its top (two edges): a flat leftover of three vertices above the line, with a holed piece
    rect = shapely.Polygon([(0, 0), (6, 0), (6, 2), (3, 2), (0, 2)])
    above = shapely.box(0, 0, 10, 10).difference(shapely.box(4, 7, 6, 9))  # its hole above the line
    rs = RingSet.from_polygons([big, small, tiny, rect, above])
    pieces, parent, side, failed = split(rs, [(0, 5e4), (0, 5e-4), (0, 5e-6), (0, 2), (0, 5)], [(1, 0)] * 5)
    assert not failed.any() and parent.tolist() == [0, 1, 2, 4, 0, 1, 2, 3, 4]
    want = [5e9, 5e-7, 5e-11, 46, 5e9 - 1e8, 5e-7 - 4e-8, 5e-11 - 4e-12, 12, 50]
    assert np.allclose(pieces.areas(), want, rtol=1e-9, atol=0)
    assert pieces.n == 9 and pieces.poly.tolist() == [0, 1, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 8]


def test_helpers_at_their_edges():
    assert [x.tolist() for x in _cycles(np.array([0]), 1)] == [[0], [0]]
    bad = np.zeros(2, bool)
    cs = RingSet(*_cat([shapely.Polygon(shapely.box(1, 1, 2, 2).exterior.coords[::-1])]))
    res = _hole_owner(cs, np.array([1]), np.zeros(0, np.int64), np.array([0]), bad)  # a hole and no shell
    assert res.tolist() == [-1] and bad.tolist() == [False, True]
    # a short direction is normalized too
    s, t, _, d = _signed(RingSet.from_polygons([SQUARE]), [(1, 0)], [(0, 0.5)])
    assert d.tolist() == [[0, 1]] and s.tolist() == [-3, -3, 1, 1] and t.tolist() == [0, 4, 4, 0]


def test_twice_on_line_at_its_tolerance():
    """Ends exactly ``tol`` off the line count as on it; an overlap of exactly ``tol`` is no slit."""
    on = [(0.0, 0.0)]
    d = [(1.0, 0.0)]

    def twice(xy, tol=0.5):
        xy = np.asarray(xy, np.float64)
        k = len(xy)
        return _twice_on_line(
            RingSet(xy, np.zeros(k, np.int64), np.ones(k, bool), np.zeros(1, np.int64), 1), on, d, tol
        )[0]

    assert twice([(0, 0), (3, 0), (1, 0.5), (1, 2), (0, 2)])  # (3,0)-(1,0.5) ends tol off: on the line
    assert twice([(0, 2), (1, 2), (1, 0.5), (3, 0), (0, 0)])  # (1,0.5)-(3,0) starts tol off
    assert not twice([(0, 0), (3, 0), (3, 1), (2.5, 1), (2.5, 0), (4, 0), (4, 2), (0, 2)])  # overlap 0.5
    # three edges on the line: only the second and third overlap
    assert twice([(0, 0), (1, 0), (1, 1), (2, 1), (2, 0), (4, 0), (4, 1), (3, 1), (3, 0), (5, 0), (5, 2), (0, 2)], 0.1)


def test_a_comb_cut_obliquely_matches_geos():
    """Lines crossing the comb's long edges at shallow angles: crossings a tooth apart along the line on
    edges that run 4 m along it (ordered by where each line crosses, exactly, or the pairing breaks)."""
    lines = [((0.0, y0), (1.0, slope)) for slope in (0.15, 0.3, 0.45, 0.7, -0.35, -0.6) for y0 in (0.3, 1.1, 2.6)]
    lines += [((5.0, y0), (-1.0, -slope)) for (_, y0), (_, slope) in lines[:9]]
    polys = np.array([COMB] * len(lines), dtype=object)
    pts, dirs = np.array([p for p, _ in lines]), np.array([d for _, d in lines])
    _sides_match_geos(polys, pts, dirs, atol=1e-12, counts=True)


def test_an_apex_touching_the_line_with_both_edges_ahead():
    """The two crossings at a touching apex are ordered by the cotangents of its edges (both edges run
    ahead along the line here): the triangle stays whole on its side, with 2 crossings or 4."""
    below = [(0, 0), (3, -3), (4, -1)]  # apex (0, 0) on y = 0, the triangle to the right of (1, 0)
    above = [(0, 0), (4, 1), (3, 3)]  # the same above, to the right of (-1, 0)
    cases = []
    for tri, d in ((below, (1, 0)), (above, (-1, 0))):
        for k in range(3):
            cases.append((tri[k:] + tri[:k], d))
    polys = [shapely.Polygon(r) for r, _ in cases]
    pts = [(20, 0) if d == (1, 0) else (-20, 0) for _, d in cases]  # the apex 20 m behind the point
    pieces, parent, side, failed = split(RingSet.from_polygons(polys), pts, [d for _, d in cases])
    assert not failed.any() and parent.tolist() == list(range(len(cases))) and not side.any()
    assert pieces.areas().tolist() == [4.5] * len(cases)
    # the apex at x = 0.9, its first edge to x = 0.3: the crossing's abscissa is the apex's own (0.3 + (0.9 -
    # 0.3) is not 0.9 in floating point), equal to the other crossing's, and the edges' directions order them
    tri = shapely.Polygon([(0.9, 0), (0.3, -3), (4, -1)])
    pieces, parent, side, failed = split(RingSet.from_polygons([tri]), [(0, 0)], [(1, 0)])
    assert not failed[0] and side.tolist() == [0] and np.isclose(pieces.areas()[0], tri.area, rtol=1e-12)
    # a thin notch whose tip touches y = 1 from above, both its edges running to larger x
    notch = shapely.Polygon([(0, 0), (4, 0), (4, 5), (3.5, 5), (2, 1), (3, 5), (0, 5)])
    for d in ((-1, 0), (1, 0)):
        pieces, parent, side, failed = split_(RingSet.from_polygons([notch]), [(0, 1)], [d])
        if d == (1, 0):
            assert failed.tolist() == [True]  # the tip counts as above: the upper piece touches itself
            continue
        assert not failed[0] and np.isclose(pieces.areas().sum(), notch.area, rtol=1e-12)
        assert sorted(pieces.areas().tolist()) == [4, 5, 10]  # below; right of the notch (2 .. 0.5 wide); left (2 .. 3)
