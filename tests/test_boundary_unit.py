"""sengine.geom.boundary, function by function, with values worked out by hand.

The boundary helpers are exercised in bulk by the lots and buildings nodes and by
test_split; these pin each function on small polygons (with holes, empty, touching at
exactly the tolerance) and compare ``segments_on_boundary`` with a brute-force oracle on
hypothesis-generated rectilinear pieces (exact in floating point), for the mutation run of
docs/mutation.md.
"""

from __future__ import annotations

import numpy as np
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.boundary import (
    _first_of,
    _ramp,
    polygon_parts,
    ring_segments,
    segments_on_boundary,
    segments_on_box,
    segments_on_lines,
    street_edges,
)
from sengine.geom.ringset import RingSet

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])

SQUARE_WITH_HOLE = shapely.Polygon([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (2, 2), (1, 2)]])
TRIANGLE = shapely.Polygon([(10, 0), (13, 0), (13, 4)])


def test_helpers():
    r = _ramp([3, 0, 2])
    assert r.tolist() == [0, 1, 2, 0, 1] and r.dtype == np.int64
    assert _ramp(np.array([2, 1], np.int32)).tolist() == [0, 1, 0]
    f = _first_of(np.array([0, 0, 2, 2, 2]), 4)
    assert f.tolist() == [0, 2, 2, 5, 5] and f.dtype == np.int64
    assert _first_of(np.array([], np.int64), 2).tolist() == [0, 0, 0]


def test_polygon_parts_keeps_polygons_of_positive_area_with_their_owner():
    multi = shapely.MultiPolygon([shapely.box(0, 0, 1, 1), shapely.box(5, 5, 7, 7)])
    flat = shapely.Polygon([(0, 0), (1, 1), (2, 2)])  # zero area
    geoms = [multi, shapely.LineString([(0, 0), (1, 0)]), shapely.Polygon(), flat, TRIANGLE, None]
    parts, own = polygon_parts(geoms, np.array([10, 11, 12, 13, 14, 15]))
    assert shapely.area(parts).tolist() == [1.0, 4.0, 6.0]
    assert own.tolist() == [10, 10, 14]
    # get_parts opens one level: a collection inside a collection is no Polygon, though it has an area
    nested = shapely.GeometryCollection([shapely.GeometryCollection([shapely.box(0, 0, 3, 3)]), TRIANGLE])
    parts, own = polygon_parts([nested], [4])
    assert shapely.area(parts).tolist() == [6.0] and own.tolist() == [4]
    gc = shapely.GeometryCollection([shapely.Point(0, 0), shapely.box(0, 0, 2, 1)])
    parts, own = polygon_parts(np.array([gc], dtype=object), [7])
    assert shapely.area(parts).tolist() == [2.0] and own.tolist() == [7]


def test_ring_segments_by_hand():
    p0, p1, idx, ring = ring_segments([TRIANGLE, SQUARE_WITH_HOLE, shapely.Polygon(), TRIANGLE])
    tri = [[10, 0], [13, 0], [13, 4]]
    assert p0.tolist() == tri + [[0, 0], [4, 0], [4, 4], [0, 4], [1, 1], [2, 1], [2, 2], [1, 2]] + tri
    assert p1.tolist() == [[13, 0], [13, 4], [10, 0]] + [[4, 0], [4, 4], [0, 4], [0, 0]] + [
        [2, 1],
        [2, 2],
        [1, 2],
        [1, 1],
    ] + [[13, 0], [13, 4], [10, 0]]
    assert idx.tolist() == [0] * 3 + [1] * 8 + [3] * 3 and idx.dtype == np.int64
    # hole-free polygons are numbered by their index, rings of holed ones after all polygons
    assert ring.tolist() == [0] * 3 + [4] * 4 + [5] * 4 + [3] * 3 and ring.dtype == np.int64


def test_ring_segments_of_two_holed_polygons_number_rings_apart():
    other = shapely.Polygon(
        [(20, 0), (30, 0), (30, 10), (20, 10)],
        [[(21, 1), (22, 1), (22, 2)], [(25, 5), (26, 5), (26, 6)]],
    )
    _, _, idx, ring = ring_segments(np.array([[SQUARE_WITH_HOLE, other]], dtype=object))  # 2-D input: raveled
    assert idx.tolist() == [0] * 8 + [1] * 10
    assert ring.tolist() == [2] * 4 + [3] * 4 + [4] * 4 + [5] * 3 + [6] * 3


def test_ring_segments_of_nothing():
    p0, p1, idx, ring = ring_segments([])
    assert p0.shape == p1.shape == (0, 2) and len(idx) == len(ring) == 0
    p0, _, idx, _ = ring_segments([shapely.Polygon()])
    assert p0.shape == (0, 2) and len(idx) == 0


# ---------------------------------------------------------------------------------------------
# segments_on_boundary


def _brute(geoms, owner, polys, tol):
    """Per segment of ``geoms``: on its owner's boundary, and the nearest such owner segment."""
    p0, p1, idx, ring = ring_segments(geoms)
    b0, b1, bown, _ = ring_segments(polys)
    on = np.zeros(len(idx), bool)
    match = np.full(len(idx), -1)
    for s in range(len(idx)):
        m = 0.5 * (p0[s] + p1[s])
        cand = np.flatnonzero(bown == owner[idx[s]])
        best = None
        for b in cand:  # point-to-segment distance, squared, by hand
            e = b1[b] - b0[b]
            t = 0.0 if not e.any() else min(max(np.dot(m - b0[b], e) / np.dot(e, e), 0.0), 1.0)
            d = m - b0[b] - t * e
            dd = float(np.dot(d, d))
            if dd <= tol * tol and (best is None or dd < best[0]):
                best = (dd, b)
        if best is not None:
            on[s], match[s] = True, best[1]
    return p0, p1, idx, ring, on, match


def test_segments_on_boundary_by_hand():
    blocks = [shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 10)]
    lots = [
        shapely.box(0, 0, 5, 5),  # bottom and left on block 0
        shapely.box(3, 3, 6, 6),  # inside: none
        shapely.box(20, 5, 30, 10),  # owner 1: left, top, right
        shapely.box(25, 0, 30, 5),  # given owner 0: block 1 is not its owner, none
    ]
    p0, p1, idx, ring, on, match = segments_on_boundary(lots, [0, 0, 1, 0], blocks, return_match=True)
    q = ring_segments(lots)
    for a, b in zip((p0, p1, idx, ring), q):
        assert np.array_equal(a, b)
    # box() runs counter-clockwise from (xmax, ymin): right, top, left, bottom
    assert on.tolist() == [False, False, True, True] + [False] * 4 + [True, True, True, False] + [False] * 4
    # block segments in ring_segments order: block 0 are 0..3, block 1 are 4..7 (right, top, left, bottom)
    assert match.tolist() == [-1, -1, 2, 3] + [-1] * 4 + [4, 5, 6, -1] + [-1] * 4
    assert match.dtype == np.int64 and on.dtype == bool
    assert len(segments_on_boundary(lots, [0, 0, 1, 0], blocks)) == 5  # no match without return_match
    assert np.array_equal(segments_on_boundary(lots, [0, 0, 1, 0], blocks)[4], on)


def test_segments_on_boundary_default_tolerance_and_short_owner_segments():
    block = shapely.box(0, 0, 10, 10)
    near = shapely.box(2, 1e-7, 4, 3)  # bottom 1e-7 m above the block's: on at the default 1e-6 m
    far = shapely.box(2, 0.5, 4, 3)  # bottom 0.5 m above: off
    on = segments_on_boundary([near, far], [0, 0], [block])[4]
    assert on.tolist() == [False, False, False, True] + [False] * 4
    # owner segments shorter than 1 m: the projection divides by the squared length, not by 1
    small = shapely.box(0, 0, 0.5, 0.5)
    lot = shapely.box(0.1, 0.1, 0.4, 0.3)  # right, left and bottom 0.1 from the block's, top 0.2
    _, _, _, _, on, match = segments_on_boundary([lot], [0], [small], tol=0.15, return_match=True)
    assert on.tolist() == [True, False, True, True] and match.tolist() == [0, -1, 2, 3]


def test_segments_on_boundary_chunks_stop_at_their_geometry():
    # with chunk=3 a box (4 segments) is queried as 3 + 1 segments: the second chunk must not run into the next lot,
    # whose right side lies on block 0 but which block 1 owns
    blocks = [shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 10)]
    lots = [shapely.box(0, 0, 5, 5), shapely.box(5, 0, 10, 5)]
    for chunk in (1, 2, 3, 12):
        _, _, _, _, on, match = segments_on_boundary(lots, [0, 1], blocks, chunk=chunk, return_match=True)
        assert on.tolist() == [False, False, True, True] + [False] * 4, chunk
        assert match.tolist() == [-1, -1, 2, 3] + [-1] * 4, chunk
        on = segments_on_boundary(lots, [0, 0], blocks, chunk=chunk)[4]
        assert on.tolist() == [False, False, True, True] + [True, False, False, True], chunk


def test_segments_on_boundary_at_exactly_the_tolerance():
    block = shapely.box(0, 0, 10, 10)
    tol = 0.5  # exact in binary: the squared distance equals tol * tol
    out = [  # a lot outside each side of the block, its near side exactly tol away
        shapely.box(2, -3, 4, -0.5),
        shapely.box(2, 10.5, 4, 13),
        shapely.box(-3, 2, -0.5, 4),
        shapely.box(10.5, 2, 13, 4),
    ]
    for lot in out:
        _, _, _, _, on = segments_on_boundary([lot], [0], [block], tol=tol)
        assert on.sum() == 1, lot
        _, _, _, _, on = segments_on_boundary([lot], [0], [block], tol=0.499)
        assert on.sum() == 0, lot
    # the same with a long lot queried in chunks of one segment
    comb = shapely.Polygon([(0, -0.5), (1, -0.5), (2, -0.5), (3, -0.5), (3, -2), (0, -2)])
    _, _, _, _, on = segments_on_boundary([comb], [0], [block], tol=tol, chunk=1)
    assert on.tolist() == [True, True, True, False, False, False]
    _, _, _, _, on = segments_on_boundary([comb], [0], [block], tol=tol, chunk=2)
    assert on.tolist() == [True, True, True, False, False, False]


def test_segments_on_boundary_end_of_owner_segment_and_degenerate_owner_segments():
    # the midpoint past the end of the owner's segment: distance to its end point
    block = shapely.Polygon([(0, 0), (10, 0), (10, 10), (0, 10)])
    lot = shapely.Polygon([(10.3, -0.4), (10.3, 0.4), (10.5, 0.0)])  # right of the corner (10, 0)
    p0, p1, _, _, on, match = segments_on_boundary([lot], [0], [block], tol=0.5, return_match=True)
    # segment 0 midpoint (10.3, 0): 0.3 from the corner; segment 1 midpoint (10.4, 0.2): sqrt(0.2) = 0.447;
    # segment 2 midpoint (10.4, -0.2): 0.447 from the corner, nearer the bottom side's end than any other
    assert on.tolist() == [True, True, True]
    # the corner is the end of the bottom side (0) and the start of the right side (1): tie, the lower
    assert match.tolist() == [0, 1, 0]
    # a polygon with a repeated first vertex has a zero-length boundary segment 0, measured as a point:
    # a lot segment whose midpoint is nearest that corner ties segments 0 (the point), 1 and 4: the lowest wins
    rep = shapely.Polygon([(0, 0), (0, 0), (10, 0), (10, 10), (0, 10)])
    b0, b1, _, _ = ring_segments([rep])
    assert (b0 == b1).all(axis=1).tolist() == [True, False, False, False, False]
    lot2 = shapely.box(-4, -4, -2, -2)  # right (-2, -3), top (-3, -2): sqrt(13) from the corner; others 5
    _, _, _, _, on, match = segments_on_boundary([lot2], [0], [rep], tol=4.0, return_match=True)
    want = _brute([lot2], np.array([0]), [rep], 4.0)
    assert on.tolist() == want[4].tolist() and match.tolist() == want[5].tolist()
    assert on.tolist() == [True, True, False, False] and match.tolist() == [0, 0, -1, -1]


def test_segments_on_boundary_nearest_match_wins_over_lower_index():
    # two owner segments both within tol of a lot segment: the nearer one is chosen even with a higher index
    block = shapely.Polygon([(0, 0), (10, 0), (10, 1), (0, 1)])  # bottom 0, right 1, top 2, left 3
    lot = shapely.box(2, 0.6, 4, 0.9)  # top side y=0.9: 0.1 from the top, 0.9 from the bottom
    _, _, _, _, on, match = segments_on_boundary([lot], [0], [block], tol=2.0, return_match=True)
    want = _brute([lot], np.array([0]), [block], 2.0)
    assert match.tolist() == want[5].tolist()
    # every side of the lot is nearer the top (2) than the bottom (0), both within tol
    assert on.all() and match.tolist() == [2, 2, 2, 2]
    low = shapely.box(2, 0.1, 4, 0.3)  # and this one nearer the bottom
    _, _, _, _, on, match = segments_on_boundary([low], [0], [block], tol=2.0, return_match=True)
    assert on.all() and match.tolist() == [0, 0, 0, 0]


def test_segments_on_boundary_empty_inputs():
    out = segments_on_boundary([], [], [shapely.box(0, 0, 1, 1)], return_match=True)
    assert len(out) == 6 and all(len(a) == 0 for a in out)
    # owners without any boundary segment
    p0, _, idx, _, on, match = segments_on_boundary(
        [shapely.box(0, 0, 1, 1)], [0], [shapely.Polygon()], return_match=True
    )
    assert len(p0) == 4 and not on.any() and (match == -1).all()
    _, _, _, _, on = segments_on_boundary([shapely.box(0, 0, 1, 1)], [0], [shapely.Polygon()])
    assert on.tolist() == [False] * 4


def test_segments_on_boundary_matches_index_all_polys_and_only_the_used_owners():
    # return_match numbers over every polygon's segments, even when only the last owns pieces
    blocks = [shapely.box(0, 0, 10, 10), SQUARE_WITH_HOLE, shapely.box(20, 0, 30, 10)]
    lots = [shapely.box(20, 0, 25, 5), shapely.box(1, 1, 2, 2)]
    own = np.array([2, 1])
    got = segments_on_boundary(lots, own, blocks, return_match=True)
    want = _brute(lots, own, blocks, 1e-6)
    assert got[4].tolist() == want[4].tolist() and got[5].tolist() == want[5].tolist()
    assert got[5][:4].tolist() == [-1, -1, 14, 15]  # block 2's left and bottom: after 4 + 8 segments
    assert got[5][4:].tolist() == [9, 10, 11, 8]  # the hole as given: (1,1) -> (2,1) is 8
    on = segments_on_boundary(lots, own, blocks)[4]
    assert on.tolist() == got[4].tolist()


coord = st.integers(0, 12)


@st.composite
def rect_pieces(draw):
    """Blocks as axis-aligned boxes (some with a box hole) and lots as boxes inside or near them."""
    nb = draw(st.integers(1, 3))
    blocks = []
    for i in range(nb):
        x0, y0 = 30 * i, draw(st.integers(0, 5))
        w, h = draw(st.integers(4, 14)), draw(st.integers(4, 14))
        b = shapely.box(x0, y0, x0 + w, y0 + h)
        if draw(st.booleans()) and w > 4 and h > 4:
            b = b.difference(shapely.box(x0 + 2, y0 + 2, x0 + w - 2, y0 + h - 2))
        blocks.append(b)
    lots, owner = [], []
    for _ in range(draw(st.integers(1, 8))):
        o = draw(st.integers(0, nb - 1))
        bx0, by0, bx1, by1 = blocks[o].bounds
        x0 = bx0 + draw(st.integers(-1, 3))
        y0 = by0 + draw(st.integers(-1, 3))
        x1 = min(bx1 + draw(st.integers(0, 1)), x0 + draw(st.integers(1, 16)))
        y1 = min(by1 + draw(st.integers(0, 1)), y0 + draw(st.integers(1, 16)))
        if x1 <= x0 or y1 <= y0:
            continue
        lot = shapely.box(x0, y0, x1, y1)
        if draw(st.booleans()):  # a notched lot: more segments, some on no boundary
            lot = lot.difference(shapely.box(x0, y0, x0 + (x1 - x0) / 2, y0 + (y1 - y0) / 2))
        if lot.geom_type != "Polygon" or lot.is_empty:
            continue
        other = draw(st.integers(0, nb - 1)) if draw(st.integers(0, 4)) == 0 else o  # a wrong owner now and then
        lots.append(lot)
        owner.append(other)
    tol = draw(st.sampled_from([1e-6, 0.5, 1.0]))
    chunk = draw(st.sampled_from([1, 2, 3, 12]))
    return lots, np.array(owner, np.int64), blocks, tol, chunk


@SETTINGS
@given(rect_pieces())
def test_segments_on_boundary_equals_brute_force(case):
    lots, owner, blocks, tol, chunk = case
    got = segments_on_boundary(lots, owner, blocks, tol=tol, chunk=chunk, return_match=True)
    want = _brute(lots, owner, blocks, tol)
    for a, b in zip(got[:4], want[:4]):
        assert np.array_equal(a, b)
    assert got[4].tolist() == want[4].tolist()
    assert got[5].tolist() == want[5].tolist()
    assert segments_on_boundary(lots, owner, blocks, tol=tol, chunk=chunk)[4].tolist() == want[4].tolist()


# ---------------------------------------------------------------------------------------------
# segments_on_box, segments_on_lines, street_edges


def test_segments_on_box_each_side_and_tolerance():
    box = (0.0, 0.0, 10.0, 20.0)
    p0 = np.array([[0, 1], [10, 1], [1, 0], [1, 20], [0.001, 5], [0.002, 5], [0, 0], [5, 5], [0, 5]])
    p1 = np.array([[0, 9], [10, 9], [9, 0], [9, 20], [0.001, 6], [0.002, 6], [10, 20], [6, 6], [10, 5]])
    got = segments_on_box(p0, p1, box)
    assert got.tolist() == [True, True, True, True, True, False, False, False, False]
    assert segments_on_box(p0, p1, box, tol=0.0025)[5]
    assert not segments_on_box(p0, p1, box, tol=0.0)[4]
    # one end on the bottom, the other on the left: on no single side
    assert segments_on_box([[0, 0]], [[0, 0]], box).tolist() == [True]
    assert segments_on_box([0, 3], [10, 3], box).tolist() == [False]  # flat input: one segment
    assert segments_on_box(p0, p1, None).tolist() == [False] * 9
    assert segments_on_box(np.zeros((0, 2)), np.zeros((0, 2)), box).tolist() == []
    assert segments_on_box(np.zeros((0, 2)), np.zeros((0, 2)), box).dtype == bool
    assert segments_on_box(p0, p1, None).dtype == bool


def test_segments_on_lines_by_hand():
    front = shapely.LineString([(0, 0), (10, 0)])
    p0 = np.array([[1, 0], [1, 0.01], [1, 0.03], [1, 5], [1, 5]])
    p1 = np.array([[3, 0], [3, 0.01], [3, 0.03], [3, 5], [3, 5]])
    lines = np.array([front, front, front, front, None], dtype=object)
    assert segments_on_lines(p0, p1, lines).tolist() == [True, True, False, False, True]
    assert segments_on_lines(p0, p1, lines, tol=0.03).tolist() == [True, True, True, False, True]
    assert segments_on_lines(p0, p1, lines, tol=0.0).tolist() == [True, False, False, False, True]
    assert not shapely.is_prepared(front)  # the caller's geometry is left unprepared
    shapely.prepare(front)
    assert segments_on_lines(p0, p1, lines).tolist() == [True, True, False, False, True]
    assert shapely.is_prepared(front)  # and a prepared one stays prepared
    nothing = segments_on_lines(p0, p1, np.array([None] * 5, dtype=object))
    assert nothing.tolist() == [True] * 5 and nothing.dtype == bool


def test_street_edges_by_hand():
    rs = RingSet.from_polygons([shapely.box(0, 0, 10, 10), shapely.box(10, 0, 20, 10)], flag=False)
    # counter-clockwise from (xmax, ymin): right, top, left, bottom of each square
    assert rs.xy.tolist()[:4] == [[10, 0], [10, 10], [0, 10], [0, 0]]
    box = (0.0, 0.0, 20.0, 10.0)
    assert street_edges(rs, [0, 1]).tolist() == [True] * 8
    assert street_edges(rs, [0, 1], box=box).tolist() == [True, False, False, False, False, False, True, False]
    fronts = [shapely.LineString([(0, 10), (20, 10)]), None]
    got = street_edges(rs, [0, 1], fronts=fronts)
    assert got.tolist() == [False, True, False, False] + [True] * 4
    got = street_edges(rs, [0, 1], fronts=fronts, box=box)
    assert got.tolist() == [False, False, False, False, False, False, True, False]
    # a block's front given by owner index: the second square owned by block 0 too
    got = street_edges(rs, [0, 0], fronts=fronts)
    assert got.tolist() == [False, True, False, False, False, True, False, False]
    empty = RingSet.from_polygons([])
    assert street_edges(empty, [], fronts=[None], box=box).tolist() == []
