"""sengine.geom.segments, function by function: exact values worked out by hand, and an oracle for box_closure.

Written for the mutation run of docs/mutation.md: each test pins one behaviour the demos and the
face-tracing tests (test_geometry, test_closure, test_planar) exercise only in bulk.
"""

from __future__ import annotations

import logging
import warnings

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.segments import argsort_int, box_closure, merge_points, planarize, segments_from_lines

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def seg_set(xy, u, v) -> list:
    """Undirected segments as sorted coordinate pairs (independent of node ids and direction)."""
    out = []
    for a, b in zip(u, v):
        pa, pb = tuple(map(float, xy[a])), tuple(map(float, xy[b]))
        out.append(tuple(sorted((pa, pb))))
    return sorted(out)


# --- argsort_int ---------------------------------------------------------------------------------


def test_argsort_int_two_passes_for_17_bit_keys():
    """Keys spanning exactly 17 bits need two 16-bit passes: one pass would sort the low 16 bits only."""
    rng = np.random.default_rng(1)
    k = rng.integers(0, 2**17, 6000)
    k[:2] = (0, 2**17 - 1)  # the span is 17 bits exactly
    assert np.array_equal(argsort_int(k), np.argsort(k, kind="stable"))


def test_argsort_int_wide_keys_with_ties_keep_input_order():
    """Keys wider than 48 bits fall back to numpy: still stable, ties in input order."""
    rng = np.random.default_rng(2)
    k = rng.integers(0, 4, 6000) * 2**55
    o = argsort_int(k)
    assert np.array_equal(o, np.argsort(k, kind="stable"))
    for val in np.unique(k):  # each run of equal keys is increasing in index
        run = o[k[o] == val]
        assert np.all(np.diff(run) > 0)


# --- merge_points --------------------------------------------------------------------------------


def test_merge_points_exact_when_decimals_is_none():
    xy = np.array([[0.1, 0.0], [0.2, 0.0], [1e-20, 0.0], [2e-20, 0.0], [0.1, 0.0]])
    pts, inv = merge_points(xy, None)
    assert len(pts) == 4  # 0.1 twice is one point; 1e-20 and 2e-20 stay two
    assert inv[0] == inv[4] and len(set(inv[:4].tolist())) == 4
    assert np.array_equal(pts[inv], xy)


def test_merge_points_negative_zero_is_zero():
    xy = np.array([[0.0, 0.0], [-0.0, 0.0], [0.0, -0.0]])
    pts, inv = merge_points(xy, None)
    assert len(pts) == 1 and inv.tolist() == [0, 0, 0]


def test_merge_points_rounds_and_keeps_first_coordinates():
    xy = np.array([[1.0000000003, 2.0], [1.0, 2.0], [1.001, 2.0]])
    pts, inv = merge_points(xy, 9)
    assert len(pts) == 2 and inv[0] == inv[1] != inv[2]
    assert pts[inv[0]].tolist() == [1.0000000003, 2.0]  # the first one's exact coordinates


def test_merge_points_accepts_float32():
    xy = np.array([[1.5, 2.5], [1.5, 2.5], [3.0, 4.0]], np.float32)
    pts, inv = merge_points(xy, 6)
    assert len(pts) == 2 and inv[0] == inv[1] != inv[2]


# --- segments_from_lines -------------------------------------------------------------------------


def test_segments_from_lines_empty_inputs_give_typed_empty_arrays():
    for lines in ([], [shapely.LineString()]):
        xy, u, v, src = segments_from_lines(lines)
        assert xy.shape == (0, 2) and xy.dtype == np.float64
        for a in (u, v, src):
            assert a.shape == (0,) and a.dtype == np.int64


def test_segments_from_lines_one_line():
    xy, u, v, src = segments_from_lines([shapely.LineString([(0, 0), (3, 4)])])
    assert seg_set(xy, u, v) == [((0.0, 0.0), (3.0, 4.0))]
    assert src.tolist() == [0] and u.dtype == v.dtype == src.dtype == np.int64


def test_segments_from_lines_does_not_node_by_default():
    """Two crossing lines without node=True stay two segments on four nodes."""
    lines = [shapely.LineString([(0, 0), (10, 0)]), shapely.LineString([(5, -5), (5, 5)])]
    xy, u, v, src = segments_from_lines(lines)
    assert len(xy) == 4 and len(u) == 2 and sorted(src.tolist()) == [0, 1]
    xy, u, v, src = segments_from_lines(lines, node=True)
    assert len(xy) == 5 and len(u) == 4 and sorted(src.tolist()) == [0, 0, 1, 1]


def test_segments_from_lines_default_rounding_is_a_nanometre():
    """Ends 0.3 nm apart are one node by default (9 decimals), two with 10 or None."""
    lines = [shapely.LineString([(0, 0), (1, 0)]), shapely.LineString([(1.0000000003, 0), (1, 1)])]
    xy, u, v, _ = segments_from_lines(lines)
    assert len(xy) == 3
    assert len(segments_from_lines(lines, decimals=10)[0]) == 4
    assert len(segments_from_lines(lines, decimals=None)[0]) == 4


def test_segments_from_lines_noded_src_is_the_line_under_the_segment():
    """With node=True each segment's src is the line it lies on (short lines spread along a diagonal)."""
    lines = [shapely.LineString([(10 * i, 7 * i), (10 * i + 3, 7 * i)]) for i in range(10)]
    xy, u, v, src = segments_from_lines(lines, node=True)
    assert len(u) == 10
    for a, b, s in zip(u, v, src):
        assert shapely.distance(lines[s], shapely.LineString([xy[a], xy[b]])) == 0.0
    assert sorted(src.tolist()) == list(range(10))


def test_segments_from_lines_noded_overlap_has_one_src_per_segment():
    """Collinear overlapping lines: the shared piece is equally near both; it still gets one src."""
    lines = [shapely.LineString([(0, 0), (10, 0)]), shapely.LineString([(5, 0), (15, 0)])]
    xy, u, v, src = segments_from_lines(lines, node=True)
    assert len(src) == len(u) == 3
    assert seg_set(xy, u, v) == [((0.0, 0.0), (5.0, 0.0)), ((5.0, 0.0), (10.0, 0.0)), ((10.0, 0.0), (15.0, 0.0))]
    assert set(src.tolist()) <= {0, 1}


# --- planarize -----------------------------------------------------------------------------------


def test_planarize_empty_graph():
    xy, u, v, src, n = planarize([[0, 0], [1, 1]], [], [])
    assert n == 0 and len(u) == len(v) == len(src) == 0
    assert xy.dtype == np.float64


def test_planarize_one_crossing_splits_both():
    xy, u, v, src, n = planarize([(0, 0), (10, 0), (5, -5), (5, 5)], [0, 2], [1, 3])
    assert n == 1
    assert seg_set(xy, u, v) == [
        ((0.0, 0.0), (5.0, 0.0)),
        ((5.0, -5.0), (5.0, 0.0)),
        ((5.0, 0.0), (5.0, 5.0)),
        ((5.0, 0.0), (10.0, 0.0)),
    ]
    assert sorted(src.tolist()) == [0, 0, 1, 1]


def test_planarize_keeps_input_types_when_nothing_crosses():
    xy0 = np.array([(0, 0), (10, 10), (6, 4), (9, 1)])  # integers
    xy, u, v, src, n = planarize(xy0, np.array([0, 2], np.int32), np.array([1, 3], np.int32))
    assert n == 0 and xy.dtype == np.float64 and u.dtype == v.dtype == src.dtype == np.int64


@pytest.mark.parametrize(
    "xy",
    [
        [(0, 0), (10, 10), (6, 4), (9, 1)],  # the lines cross at (5, 5), outside the second segment
        [(0, 0), (5, 5), (1, 0), (10, 0)],  # the first starts on the second's line, off the segment
        [(6, 4), (9, 1), (0, 0), (10, 10)],  # the same two pairs, the other segment first
        [(1, 0), (10, 0), (0, 0), (5, 5)],
        [(0, 0), (10, 10), (3, 5), (3, 5)],  # a zero-length segment inside the other's box, off it
    ],
)
def test_planarize_does_not_split_segments_whose_lines_cross_elsewhere(xy):
    out, u, v, src, n = planarize(xy, [0, 2], [1, 3])
    assert n == 0 and len(out) == 4
    assert seg_set(out, u, v) == seg_set(np.asarray(xy, float), [0, 2], [1, 3])


@pytest.mark.parametrize(
    "xy",
    [
        [(0, 0), (4, 1), (4, -1)],  # a V mirrored about the x axis
        [(0, 0), (10, 0), (5, 5)],  # first arm horizontal
        [(0, 0), (5, 5), (10, 0)],  # second arm horizontal
        [(1, 1), (11, 1), (-4, 1)],  # a straight line through a node, off the origin
        [(0, 0), (0.5, 0), (-0.4, 0)],  # the same, arms shorter than 1 m
    ],
)
def test_planarize_segments_meeting_at_a_node_do_not_cross(xy):
    out, u, v, src, n = planarize(xy, [0, 0], [1, 2])
    assert n == 0 and len(out) == 3 and len(u) == 2


def test_planarize_short_collinear_continuation_is_no_overlap():
    out, u, v, src, n = planarize([(0, 0), (0.5, 0), (0.9, 0)], [0, 1], [1, 2])
    assert n == 0 and len(u) == 2


@pytest.mark.parametrize("shared_last", [False, True])
def test_planarize_collinear_overlap_past_a_shared_node_off_the_origin(shared_last):
    """A short way along a long one from a shared node (1, 1): the long one is split at the short one's end."""
    xy = [(1, 1), (11, 1), (6, 1)]
    u, v = ([0, 2], [1, 0]) if shared_last else ([0, 0], [1, 2])
    out, u2, v2, src, n = planarize(xy, u, v)
    assert n == 1 and len(out) == 3
    assert seg_set(out, u2, v2) == [((1.0, 1.0), (6.0, 1.0)), ((1.0, 1.0), (6.0, 1.0)), ((6.0, 1.0), (11.0, 1.0))]


@pytest.mark.parametrize(
    ("a", "b", "pieces"),
    [
        # overlap without a shared node: each is cut at the other's inner end, nothing grows
        ((0, 10), (5, 15), [(0, 5), (5, 10), (5, 10), (10, 15)]),
        ((0, 0.5), (0.3, 0.9), [(0, 0.3), (0.3, 0.5), (0.3, 0.5), (0.5, 0.9)]),
    ],
)
def test_planarize_collinear_overlap_pieces(a, b, pieces):
    xy = [(a[0], 0), (a[1], 0), (b[0], 0), (b[1], 0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 0 / 0 of collinear pairs stays silent
        out, u, v, src, n = planarize(xy, [0, 2], [1, 3])
    assert n == 1
    assert seg_set(out, u, v) == sorted(((float(p), 0.0), (float(q), 0.0)) for p, q in pieces)
    assert sorted(src.tolist()) == [0, 0, 1, 1]


def test_planarize_zero_length_segments_are_dropped_silently():
    """A segment whose two nodes have one position: sharing a node, or lying on another segment."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out, u, v, src, n = planarize([(0, 0), (0, 0), (10, 0), (5, -5), (5, 5)], [0, 1, 3], [1, 2, 4])
        assert n == 1 and len(u) == 4 and 0 not in src.tolist()
        out, u, v, src, n = planarize([(0, 0), (10, 0), (3, 0), (3, 0)], [0, 2], [1, 3])
        assert n == 1 and seg_set(out, u, v) == [((0.0, 0.0), (3.0, 0.0)), ((3.0, 0.0), (10.0, 0.0))]


@pytest.mark.parametrize("reverse", [False, True])
def test_planarize_t_junction_reuses_the_node_exactly(reverse):
    """The stem ends on the bar at (0.7, 0.7), where p + t r is 1 ulp off: the end node itself is used."""
    stem = [(0.7, 0.7), (0.7, 5.4)]
    xy = [(0, 0), (10, 10), *(stem[::-1] if reverse else stem)]
    out, u, v, src, n = planarize(xy, [0, 2], [1, 3], decimals=None)
    assert n == 1 and len(out) == 4  # no new node
    assert seg_set(out, u, v) == [((0.0, 0.0), (0.7, 0.7)), ((0.7, 0.7), (0.7, 5.4)), ((0.7, 0.7), (10.0, 10.0))]


def test_planarize_merges_a_crossing_with_a_node_within_a_nanometre():
    """The crossing (5, 0) lies 0.3 nm from the node (5, 3e-10): one node by default, two with decimals=10."""
    xy = [(0, 0), (10, 0), (4, -1), (6, 1), (5, 3e-10), (5, 5)]
    out, u, v, src, n = planarize(xy, [0, 2, 4], [1, 3, 5])
    assert n == 1 and len(out) == 6
    out10 = planarize(xy, [0, 2, 4], [1, 3, 5], decimals=10)[0]
    assert len(out10) == 7


pt5 = st.tuples(st.integers(-5, 5), st.integers(-5, 5)).map(lambda p: (float(p[0]), float(p[1])))


@SETTINGS
@given(pt5, pt5, pt5, pt5)
def test_planarize_two_segments_cross_as_shapely_says(a, b, c, d):
    """Two segments on four distinct nodes: one crossing pair iff shapely says they meet; same union after."""
    if a == b or c == d:
        return
    xy = [a, b, c, d]
    out, u, v, src, n = planarize(xy, [0, 2], [1, 3])
    s1, s2 = shapely.LineString([a, b]), shapely.LineString([c, d])
    assert n == int(shapely.intersects(s1, s2))
    pieces = shapely.linestrings(np.stack([out[u], out[v]], axis=1))
    # the same drawing (a crossing at a third of a metre is rounded to 9 decimals)
    assert shapely.hausdorff_distance(shapely.union_all(pieces), shapely.union_all([s1, s2])) < 1e-9
    assert abs(shapely.length(pieces).sum() - s1.length - s2.length) < 1e-9
    assert np.all(shapely.length(pieces) > 0)


def test_planarize_logs_its_counts(caplog):
    with caplog.at_level(logging.INFO, logger="sengine.geom.segments"):
        planarize([(0, 0), (10, 0), (5, -5), (5, 5), (2, -5), (2, 5)], [0, 2, 4], [1, 3, 5])
    assert caplog.messages == ["planarize: 2 crossing pairs; 3 segments split into 7"]


# --- box_closure ---------------------------------------------------------------------------------


def closure_oracle(xy, u=None, v=None, margin=0.0, box=None):
    """box_closure worked out with shapely: nodes on the box ordered by their distance along it."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    if len(xy) < 3:
        return xy, [], []
    x0, y0 = xy.min(axis=0)
    x1, y1 = xy.max(axis=0)
    if box is not None:
        x0, y0, x1, y1 = min(x0, box[0]), min(y0, box[1]), max(x1, box[2]), max(y1, box[3])
    if not (x1 > x0 and y1 > y0):
        return xy, [], []
    x0, y0, x1, y1 = x0 - margin, y0 - margin, x1 + margin, y1 + margin
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    ring = shapely.LineString([*corners, corners[0]])
    on = [i for i, (x, y) in enumerate(xy) if x in (x0, x1) or y in (y0, y1)]
    extra = [c for c in corners if not any(tuple(xy[i]) == c for i in on)]
    allxy = np.concatenate([xy, np.asarray(extra, float).reshape(-1, 2)])
    ids = on + list(range(len(xy), len(xy) + len(extra)))
    pos = {i: shapely.line_locate_point(ring, shapely.Point(allxy[i])) for i in ids}
    pos = {i: (0.0 if p == ring.length else p) for i, p in pos.items()}
    order, seen = [], set()
    for i in sorted(ids, key=lambda i: (pos[i], i)):
        if pos[i] not in seen:  # stacked nodes: the lowest id
            seen.add(pos[i])
            order.append(i)
    cu, cv = order, order[1:] + order[:1]
    have = set() if u is None else {frozenset((int(a), int(b))) for a, b in zip(u, v)}
    edges = [(a, b) for a, b in zip(cu, cv) if frozenset((a, b)) not in have]
    return allxy, [a for a, _ in edges], [b for _, b in edges]


small = st.integers(-6, 6).map(float)


@SETTINGS
@given(
    st.lists(st.tuples(small, small), min_size=0, max_size=12),
    st.sampled_from([0.0, 1.5]),
    st.one_of(st.none(), st.tuples(small, small, small, small)),
    st.booleans(),
)
def test_box_closure_matches_the_oracle(pts, margin, box, with_graph):
    xy = np.asarray(pts, float).reshape(-1, 2)
    u = v = None
    if with_graph and len(xy) >= 2:
        u, v = np.arange(len(xy) - 1), np.arange(1, len(xy))
    out, cu, cv = box_closure(xy, u, v, margin=margin, box=box)
    exy, eu, ev = closure_oracle(xy, u, v, margin=margin, box=box)
    assert out.dtype == np.float64 and np.array_equal(out, exy)
    assert cu.dtype == cv.dtype == np.int64
    assert cu.tolist() == eu and cv.tolist() == ev


def test_box_closure_by_hand_off_the_origin():
    """Box -5..5 x -2..9, one node on each side, one inside: the corners are added, CCW from (-5, -2)."""
    xy = np.array([(0, -2), (5, 4), (2, 9), (-5, 6), (0, 3)], float)
    out, cu, cv = box_closure(xy)
    assert out[5:].tolist() == [[-5, -2], [5, -2], [5, 9], [-5, 9]]
    assert cu.tolist() == [5, 0, 6, 1, 7, 2, 8, 3]
    assert cv.tolist() == [0, 6, 1, 7, 2, 8, 3, 5]


def test_box_closure_by_hand_two_nodes_a_side():
    """Each side is walked counter-clockwise: right side upwards, top leftwards, left side downwards."""
    xy = np.array([(0, -2), (3, -2), (5, 4), (5, 7), (2, 9), (-1, 9), (-5, 6), (-5, 1), (0, 3)], float)
    out, cu, cv = box_closure(xy)
    assert out[9:].tolist() == [[-5, -2], [5, -2], [5, 9], [-5, 9]]
    assert cu.tolist() == [9, 0, 1, 10, 2, 3, 11, 4, 5, 12, 6, 7]
    assert cv.tolist() == [0, 1, 10, 2, 3, 11, 4, 5, 12, 6, 7, 9]


@pytest.mark.parametrize(
    "xy",
    [[(0, 0), (1, 1)], [(0, 0), (1, 0), (3, 0)], [(2, 0), (2, 1), (2, 5)], [(1, 1), (1, 1), (1, 1)]],
)
def test_box_closure_without_area_is_empty(xy):
    out, cu, cv = box_closure(np.array(xy, dtype=np.int64))
    assert out.dtype == np.float64 and len(out) == len(xy)
    assert cu.dtype == cv.dtype == np.int64 and len(cu) == len(cv) == 0


def test_box_closure_of_a_triangle():
    out, cu, cv = box_closure([(0, 0), (4, 0), (0, 3)])
    assert len(out) == 4 and out[3].tolist() == [4, 3]
    assert cu.tolist() == [0, 1, 3, 2] and cv.tolist() == [1, 3, 2, 0]


def test_box_closure_with_a_larger_box():
    out, cu, cv = box_closure([(0, 0), (4, 0), (0, 3)], box=(-1, -2, 3, 5))
    assert out[3:].tolist() == [[-1, -2], [4, -2], [4, 5], [-1, 5]]
    assert cu.tolist() == [3, 4, 1, 5, 6]  # (4, 0) sets x max: it lies on the right side
