"""sengine.geom.planar on small plane graphs whose faces, walks and rings are worked out by hand.

test_planar and test_geometry compare the faces with scipy, GEOS and the stack walk on random input;
these pin every field of PlanarFaces and the helpers on a few graphs, for the mutation run of
docs/mutation.md (its planar.py row is not measured yet).
"""

from __future__ import annotations

import numpy as np

from sengine.geom.planar import (
    _cycle_order,
    _nesting,
    _orient,
    _split_walk,
    planar_faces,
    ring_crossings,
    signed_area,
    split_walks,
    spur_polygons,
    star_simple,
    trace_faces,
)

# two unit squares side by side (nodes 0..5), a dead end into the right one (4 -> 6), a triangle
# apart (7, 8, 9) and a self-loop at node 3
XY = np.array([[0, 0], [2, 0], [4, 0], [4, 2], [2, 2], [0, 2], [3, 1], [10, 10], [11, 10], [10, 11]], float)
U = np.array([0, 1, 2, 3, 4, 5, 1, 4, 7, 8, 9, 3])
V = np.array([1, 2, 3, 4, 5, 0, 4, 6, 8, 9, 7, 3])


def test_faces_of_two_squares_a_dead_end_and_a_triangle():
    pf = planar_faces(XY, U, V)
    assert [g.wkt for g in pf.polygons] == [
        "POLYGON ((0 0, 2 0, 2 2, 0 2, 0 0))",
        "POLYGON ((2 0, 4 0, 4 2, 2 2, 2 0))",
        "POLYGON ((10 10, 11 10, 10 11, 10 10))",
    ]
    # left and right of each edge: the shared side 1 -> 4 has the left square on its left
    assert pf.edge_faces.dtype == np.int64
    assert pf.edge_faces.tolist() == [
        [0, -1], [1, -1], [1, -1], [1, -1], [0, -1], [0, -1], [0, 1], [-1, -1], [2, -1], [2, -1], [2, -1], [-1, -1]
    ]  # fmt: skip
    assert [g.wkt for g in pf.outline] == [
        "POLYGON ((2 0, 4 0, 4 2, 2 2, 0 2, 0 0, 2 0))",
        "POLYGON ((11 10, 10 11, 10 10, 11 10))",
    ]
    assert pf.bridge.tolist() == [False] * 7 + [True] + [False] * 4
    assert pf.counts == {
        "edges": 12, "self_loops": 1, "duplicates": 0, "bridges": 1,
        "degenerate": 0, "pinched": 0, "holes": 0, "faces": 3,
    }  # fmt: skip
    # the walks of the graph without its bridge, each from its lowest half-edge
    assert pf.walk_vertex.tolist() == [0, 1, 4, 5, 1, 0, 5, 4, 3, 2, 1, 2, 3, 4, 7, 8, 9, 8, 7, 9]
    assert pf.walk_start.tolist() == [0, 4, 10, 14, 17, 20] and pf.walk_start.dtype == np.int64
    assert pf.walk_area.tolist() == [4, -8, 4, 0.5, -0.5]
    assert pf.walk_polygon.tolist() == [0, -1, 1, 2, -1]
    tr = pf.spur_trace
    assert tr["u"].tolist() == [0, 0, 1, 1, 2, 3, 4, 4, 7, 7, 8] and tr["v"].tolist() == [
        1,
        5,
        2,
        4,
        3,
        4,
        5,
        6,
        8,
        9,
        9,
    ]
    assert tr["area"].tolist() == [4, -8, 4, 0.5, -0.5] and tr["face"].tolist() == [0, 2, 3]
    assert tr["polygon"].tolist() == [0, -1, -1, 0, 1, -1, 0, 1, 1, -1, 1, -1, 0, -1, -1, -1, 2, -1, -1, 2, 2, -1]
    ids, polys, spurs, lobes = spur_polygons(pf, XY)
    assert ids.tolist() == [1] and [g.wkt for g in polys] == ["POLYGON ((2 0, 4 0, 4 2, 2 2, 3 1, 2 2, 2 0))"]
    assert spurs.tolist() == [[4, 6, 0]] and lobes.shape == (0, 2)


def test_an_island_is_a_hole_of_the_face_around_it():
    xy = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [4, 4], [6, 4], [6, 6], [4, 6]], float)
    pf = planar_faces(xy, [0, 1, 2, 3, 4, 5, 6, 7], [1, 2, 3, 0, 5, 6, 7, 4])
    assert [g.wkt for g in pf.polygons] == [
        "POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0), (6 4, 4 4, 4 6, 6 6, 6 4))",
        "POLYGON ((4 4, 6 4, 6 6, 4 6, 4 4))",
    ]
    assert pf.counts["holes"] == 1 and pf.counts["faces"] == 2 and pf.counts["bridges"] == 0
    assert pf.edge_faces.tolist() == [[0, -1]] * 4 + [[1, 0]] * 4  # the island's outside is the big face
    assert [g.wkt for g in pf.outline] == ["POLYGON ((10 0, 10 10, 0 10, 0 0, 10 0))"]
    assert pf.walk_polygon.tolist() == [0, -1, 1, -1] and pf.walk_area.tolist() == [100, -100, 4, -4]
    assert pf.spur_trace == {}  # no bridge: no first trace kept
    none = spur_polygons(pf, xy)
    assert [len(x) for x in none] == [0, 0, 0, 0] and none[2].shape == (0, 3)


def test_degenerate_faces_and_graphs_of_bridges_only():
    # three collinear nodes joined pairwise (overlapping edges: no plane graph) and a dead end
    xy = np.array([[0, 0], [1, 0], [2, 0], [0, 1]], float)
    pf = planar_faces(xy, [0, 1, 0, 0], [1, 2, 2, 3])
    assert len(pf.polygons) == 0 and pf.counts["degenerate"] == 2 and pf.counts["bridges"] == 1
    assert pf.edge_faces.tolist() == [[-1, -1]] * 4 and pf.walk_area.tolist() == [0, 0]
    tree = planar_faces(xy, [0, 1], [1, 2])
    assert tree.bridge.tolist() == [True, True] and tree.counts["bridges"] == 2 and tree.counts["faces"] == 0
    assert tree.edge_faces.shape == (2, 2) and len(tree.polygons) == 0 and len(tree.outline) == 0
    empty = planar_faces(xy, [1, 2], [1, 2])  # self-loops only
    assert empty.counts["self_loops"] == 2 and empty.counts["bridges"] == 0 and not empty.bridge.any()
    # a face no larger than area_eps is degenerate
    tri = np.array([[0, 0], [1, 0], [0, 1]], float)
    assert len(planar_faces(tri, [0, 1, 2], [1, 2, 0]).polygons) == 1
    small = planar_faces(tri, [0, 1, 2], [1, 2, 0], area_eps=0.5)
    assert len(small.polygons) == 0 and small.counts["degenerate"] == 2


def test_duplicates_in_both_directions_count_once():
    xy = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    pf = planar_faces(xy, [0, 1, 2, 3, 1, 0], [1, 2, 3, 0, 0, 1])
    assert pf.counts["duplicates"] == 2 and len(pf.polygons) == 1
    assert pf.edge_faces.tolist() == [[0, -1], [0, -1], [0, -1], [0, -1], [-1, 0], [0, -1]]


def test_trace_and_cycle_order_by_hand():
    nxt, face, area = trace_faces(XY, U[:7], V[:7])
    assert nxt.dtype == face.dtype == np.int64
    assert face.tolist() == [0, 1, 2, 1, 2, 1, 2, 1, 0, 1, 0, 1, 0, 2] and area.tolist() == [4, -8, 4]
    assert nxt.tolist() == [12, 11, 4, 1, 6, 3, 13, 5, 10, 7, 0, 9, 8, 2]
    for low in (None, np.array([0, 1, 2, 1, 2, 1, 2, 1, 0, 1, 0, 1, 0, 2])):
        ordered, offset = _cycle_order(nxt, face, 3, low)
        assert ordered.tolist() == [0, 12, 8, 10, 1, 11, 9, 7, 5, 3, 2, 4, 6, 13] and offset.tolist() == [0, 4, 10]


def test_split_walks_and_nesting_by_hand():
    assert _split_walk([0, 1, 2, 0, 3, 4, 0, 5, 6]) == [[0, 1, 2], [0, 3, 4], [0, 5, 6]]
    assert _split_walk([0, 1, 2, 3, 1, 4]) == [[1, 2, 3], [0, 1, 4]]
    assert _split_walk([0, 1, 0, 2]) == []  # cycles of fewer than three vertices dropped
    vertex, cycle, cycle_walk = split_walks(np.array([0, 1, 2, 0, 3, 4, 0, 5, 6, 7, 8, 9]), [0] * 9 + [1] * 3, 2)
    assert vertex.tolist() == [0, 1, 2, 0, 3, 4, 0, 5, 6, 7, 8, 9]
    assert cycle.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3] and cycle_walk.tolist() == [0, 0, 0, 1]
    assert cycle.dtype == cycle_walk.dtype == np.int64
    level, nested = _nesting(np.array([0, 2]), np.array([5, 4]), 6)
    assert level.tolist() == [1, 2] and nested
    assert not _nesting(np.array([0, 2]), np.array([3, 5]), 6)[1]  # a .. b .. a .. b
    assert not _nesting(np.array([0]), np.array([1]), 2)[1]  # a vertex twice in a row
    z = split_walks(np.array([0, 1, 0, 1]), np.zeros(4, np.int64), 1)  # crossing visits, no cycle of three
    assert [len(x) for x in z] == [0, 0, 0]


def test_signed_area_and_orientation_by_hand():
    xy = np.array([[0, 0], [4, 0], [4, 4], [0, 0], [0, 4], [4, 4]], float)
    assert signed_area(xy, np.array([0, 0, 0, 1, 1, 1])).tolist() == [8, -8]
    assert signed_area(xy, np.array([0, 0, 0, 2, 2, 2]), 4).tolist() == [8, 0, -8, 0]
    assert signed_area(np.zeros((0, 2)), np.zeros(0, np.int64), 3).tolist() == [0, 0, 0]
    p = np.array([[0, 0], [0, 0], [0, 0]], float)
    q = np.array([[1, 0], [1, 0], [1, 0]], float)
    r = np.array([[1, 1], [1, -1], [2, 0]], float)
    assert _orient(p, q, r).tolist() == [1, -1, 0]


def test_star_simple_by_hand():
    sq = [[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]]
    cw = sq[::-1]
    rep = [[0, 0], [4, 0], [4, 0], [4, 4], [0, 4], [0, 0]]  # a repeated vertex
    flat = [[0, 0], [1, 0], [2, 0], [0, 0]]  # round a line: no area
    xy = np.array(sq + cw + rep + flat, float)
    assert star_simple(xy, [5, 5, 6, 4]).tolist() == [True, False, True, False]
    # rings too short to be polygons are never certified, the others as alone
    short = [[0, 0], [1, 0], [0, 0]]
    assert star_simple(np.array(short + sq + short, float), [3, 5, 3]).tolist() == [False, True, False]
    assert star_simple(np.array(short, float), [3]).tolist() == [False]
    assert star_simple(np.zeros((0, 2)), np.zeros(0, np.int64)).tolist() == []
    # a pentagram goes round its centre twice
    star = 10.0 * np.exp(1j * 4 * np.pi * np.arange(6) / 5)
    assert star_simple(np.c_[star.real, star.imag], [6]).tolist() == [False]


def test_ring_crossings_by_hand():
    assert [x.tolist() for x in ring_crossings(np.array([[0, 0], [4, 0], [0, 4], [4, 4]], float), [4])] == [[1], [3]]
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    assert [x.tolist() for x in ring_crossings(sq, [4])] == [[], []]
    # a vertex touching the first side (edges 2 and 3 meet edge 0 at (2, 0))
    touch = np.array([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]], float)
    i, j = ring_crossings(touch, [5])
    assert i.dtype == np.int64 and list(zip(i.tolist(), j.tolist())) == [(0, 2), (0, 3)]
    # a collinear overlap: edge 1 runs back over edge 0
    back = np.array([[0, 0], [4, 0], [2, 0], [2, 3]], float)
    assert [x.tolist() for x in ring_crossings(back, [4])] == [[0], [2]]
    # two rings in one call: pairs never span them, indices are global; any run length
    both = np.r_[sq + 10, np.array([[0, 0], [4, 0], [0, 4], [4, 4]], float)]
    for chain in (1, 2, 3, 5):
        assert [x.tolist() for x in ring_crossings(both, [4, 4], chain=chain)] == [[5], [7]]
    assert [x.tolist() for x in ring_crossings(np.zeros((0, 2)), np.zeros(0, np.int64))] == [[], []]
