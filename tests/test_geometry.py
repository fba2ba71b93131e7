"""sengine.geom.planar and sengine.geom.polygons: faces of plane graphs, planarize, OBB frames, splits."""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
from _oracles import boundary_segments, split_by_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.planar import planar_faces, signed_area, trace_faces
from sengine.geom.polygons import (
    frame_boxes,
    inset,
    obb_frame,
    strtree_query,
    threaded,
)
from sengine.geom.segments import merge_points, planarize, segments_from_lines

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def euler_faces(xy, u, v) -> int:
    """Bounded faces of a plane graph by Euler's formula: E - V + C."""
    g = nx.Graph()
    g.add_edges_from((int(a), int(b)) for a, b in zip(u, v) if a != b)
    return g.number_of_edges() - g.number_of_nodes() + nx.number_connected_components(g)


coord = st.integers(0, 20).map(lambda k: k * 5.0)
segment = st.tuples(coord, coord, coord, coord).filter(lambda s: (s[0], s[1]) != (s[2], s[3]))


@SETTINGS
@given(st.lists(segment, min_size=1, max_size=25))
def test_faces_of_random_segments_match_polygonize_and_euler(segs):
    lines = shapely.linestrings(np.asarray(segs, float).reshape(-1, 2, 2))
    xy, u, v, _ = segments_from_lines(lines)
    xy, u, v, _, _ = planarize(xy, u, v)
    pf = planar_faces(xy, u, v)
    polys = pf.polygons
    assert shapely.is_valid(polys).all()
    ref = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(lines)))))
    ref = ref[shapely.area(ref) > 1e-9]
    assert len(polys) == len(ref)
    total = shapely.area(polys).sum()
    ref_total = shapely.area(ref).sum()
    assert abs(total - ref_total) <= 1e-6 * max(ref_total, 1.0)
    if len(polys):
        union = shapely.area(shapely.union_all(polys))
        assert abs(union - total) <= 1e-6 * max(total, 1.0)  # no overlaps
    a, b = np.minimum(u, v), np.maximum(u, v)
    k = np.unique(a * len(xy) + b)
    assert len(polys) + pf.counts["degenerate"] == euler_faces(xy, k // len(xy), k % len(xy))


def test_square_with_dead_end_hole_and_spike():
    lines = [
        shapely.box(0, 0, 10, 10).exterior,
        shapely.LineString([(0, 0), (-5, -5)]),
        shapely.LineString([(2, 2), (4, 4)]),
        shapely.box(6, 6, 8, 8).exterior,
    ]
    xy, u, v, _ = segments_from_lines(lines, node=True)
    pf = planar_faces(xy, u, v)
    assert pf.counts["bridges"] == 2
    assert len(pf.polygons) == 2
    big = pf.polygons[np.argmax(shapely.area(pf.polygons))]
    assert len(big.interiors) == 1
    assert abs(big.area - 96.0) < 1e-9
    assert len(pf.outline) == 1 and abs(pf.outline[0].area - 100.0) < 1e-9


def test_pinched_face_gets_touching_hole():
    # a triangle hanging from a corner of the square, inside it
    lines = [shapely.box(0, 0, 10, 10).exterior, shapely.LinearRing([(0, 0), (4, 1), (1, 4)])]
    xy, u, v, _ = segments_from_lines(lines, node=True)
    pf = planar_faces(xy, u, v)
    assert pf.counts["pinched"] == 1
    assert shapely.is_valid(pf.polygons).all()
    assert abs(shapely.area(pf.polygons).sum() - 100.0) < 1e-9
    assert sorted(len(p.interiors) for p in pf.polygons) == [0, 1]


def test_duplicates_self_loops_and_edge_faces():
    xy = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    u = np.array([0, 1, 2, 3, 1, 2])
    v = np.array([1, 2, 3, 0, 0, 2])
    pf = planar_faces(xy, u, v)
    assert pf.counts["duplicates"] == 1 and pf.counts["self_loops"] == 1
    assert len(pf.polygons) == 1
    assert pf.edge_faces[0].tolist() == [0, -1]  # face on the left of 0 -> 1
    assert pf.edge_faces[4].tolist() == [-1, 0]  # reversed duplicate
    assert pf.edge_faces[5].tolist() == [-1, -1]


def test_planarize_splits_crossings_t_junctions_and_overlaps():
    xy = np.array([[0, 0], [10, 0], [5, -5], [5, 5], [10, 10], [0, 10], [3, 0], [8, 0.0]])
    u = np.array([0, 2, 3, 6])
    v = np.array([1, 3, 4, 7])  # cross at (5, 0); collinear overlap 3..8 on 0..10
    nxy, nu, nv, src, crossings = planarize(xy, u, v)
    assert crossings >= 2
    pts = {tuple(p) for p in nxy[np.r_[nu, nv]]}
    assert (5.0, 0.0) in pts and (3.0, 0.0) in pts and (8.0, 0.0) in pts
    assert set(src.tolist()) == {0, 1, 2, 3}
    # planarized again: nothing left to split
    assert planarize(nxy, nu, nv)[4] == 0


def test_planarize_splits_a_collinear_overlap_that_shares_a_node():
    """A long way from a node along two short ones (found by hypothesis): split at the middle node."""
    xy = np.array([[0, 0], [20.1171875, 0], [40.234375, 0], [60, 0.0]])
    u, v = np.array([0, 1, 0, 2]), np.array([1, 2, 2, 3])  # 0-1, 1-2, then 0-2 over both, and 2-3 straight on
    nxy, nu, nv, src, crossings = planarize(xy, u, v)
    assert crossings == 2  # 0-2 with 0-1 and with 1-2; the straight continuation 2-3 is no overlap
    pieces = {tuple(sorted((nxy[a, 0], nxy[b, 0]))) for a, b in zip(nu, nv, strict=True)}
    assert pieces == {(0, 20.1171875), (20.1171875, 40.234375), (40.234375, 60)}  # the long way over the two
    assert sorted(src.tolist()) == [0, 1, 2, 2, 3]
    assert planarize(nxy, nu, nv)[4] == 0


def test_signed_area_and_merge_points():
    xy = np.array([[0, 0], [2, 0], [2, 1], [0, 0], [0, 1], [1, 0.0]])
    a = signed_area(xy, np.array([0, 0, 0, 1, 1, 1]))
    assert np.allclose(a, [1.0, -0.5])
    pts, inv = merge_points(np.array([[0.0, 0.0], [1e-9, 0], [1, 1]]), 6)
    assert len(pts) == 2 and inv[0] == inv[1]


@SETTINGS
@given(st.floats(1, 300), st.floats(1, 300), st.floats(-180, 180))
def test_obb_frame_and_frame_boxes_round_trip(w, h, angle):
    box = shapely.affinity.rotate(shapely.box(0, 0, w, h), angle, origin=(0, 0))
    c, ax, ln, wd = obb_frame([box])
    assert np.isclose(ln[0], max(w, h), rtol=1e-6) and np.isclose(wd[0], min(w, h), rtol=1e-6)
    back = frame_boxes(c, ax, -ln / 2, ln / 2, -wd / 2, wd / 2)[0]
    assert shapely.symmetric_difference(back, box).area < 1e-6 * box.area


def test_split_by_line_halves_partition():
    poly = shapely.Polygon([(0, 0), (10, 0), (10, 10), (5, 2), (0, 10)])
    left, right = split_by_line([poly], [[5, 5]], [[0, 1]])
    assert np.isclose(left[0].area + right[0].area, poly.area)
    assert left[0].intersection(right[0]).area < 1e-9
    p0, p1, idx, ring = boundary_segments([poly])
    assert len(p0) == 5 and (idx == 0).all()


def test_threads_give_the_one_call_results():
    rng = np.random.default_rng(5)
    c = rng.uniform(0, 1000, (3000, 2))
    polys = shapely.buffer(shapely.points(c), rng.uniform(5, 30, 3000), quad_segs=3)
    d = rng.uniform(0, 8, 3000)
    one = shapely.buffer(polys, -d, join_style="mitre", mitre_limit=3.0)
    assert shapely.equals_exact(inset(polys, d, threads=3), one, 0).all()
    assert shapely.equals_exact(inset(polys, d, threads=1), one, 0).all()
    boxes = shapely.box(*(c - 3).T, *(c + 3).T)
    diff = threaded(shapely.difference, polys, boxes, threads=2, min_size=10)
    assert shapely.equals_exact(diff, shapely.difference(polys, boxes), 0).all()
    tree = shapely.STRtree(polys)
    assert np.array_equal(np.stack(strtree_query(tree, boxes, threads=3)), tree.query(boxes))


def test_trace_with_a_filtered_order_is_the_same_trace():
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 100, (60, 2))
    tri = shapely.delaunay_triangles(shapely.multipoints(xy), only_edges=True)
    c = shapely.get_coordinates(shapely.get_parts(tri)).reshape(-1, 2, 2)
    ids = {tuple(p): k for k, p in enumerate(xy.tolist())}
    u = np.array([ids[tuple(p)] for p in c[:, 0].tolist()])
    v = np.array([ids[tuple(p)] for p in c[:, 1].tolist()])
    full = trace_faces(xy, u, v)
    keep = np.flatnonzero(rng.random(len(u)) < 0.7)
    d = xy[np.stack([v, u], 1).ravel()] - xy[np.stack([u, v], 1).ravel()]
    order = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), np.stack([u, v], 1).ravel()))
    renum = np.full(len(u), -1)
    renum[keep] = np.arange(len(keep))
    e = renum[order >> 1]
    filtered = 2 * e[e >= 0] + (order[e >= 0] & 1)
    a = trace_faces(xy, u[keep], v[keep])
    b = trace_faces(xy, u[keep], v[keep], order=filtered)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert len(full[2]) > 0


def test_argsort_int_is_a_stable_argsort():
    from sengine.geom.segments import argsort_int

    rng = np.random.default_rng(0)
    for span in (3, 1000, 70_000, 2**31, 2**47, 2**60):
        k = rng.integers(-span, span, 20_000)
        assert np.array_equal(argsort_int(k), np.argsort(k, kind="stable"))


def test_shared_areas_and_largest_share():
    from sengine.geom.polygons import largest_share, shared_areas

    lots = np.array([shapely.box(0, 0, 10, 10), shapely.box(10, 0, 20, 10), shapely.box(20, 0, 30, 10)])
    things = np.array(
        [
            shapely.box(8, 2, 12, 4),  # 4 m2 on each of lots 0 and 1: the lower wins the tie
            shapely.box(15, 2, 27, 4),  # 10 m2 on lot 1, 14 m2 on lot 2
            shapely.box(30, 0, 31, 1),  # touches lot 2 only along an edge: on none
            shapely.box(50, 0, 51, 1),
        ]
    )  # far away
    gi, li, area = shared_areas(things, lots)
    got = {(int(g), int(k)): round(float(a), 9) for g, k, a in zip(gi, li, area, strict=True)}
    assert got == {(0, 0): 4.0, (0, 1): 4.0, (1, 1): 10.0, (1, 2): 14.0, (2, 2): 0.0}
    assert largest_share(things, lots).tolist() == [0, 2, -1, -1]
    assert largest_share(things[:0], lots).tolist() == [] and largest_share(things, lots[:0]).tolist() == [-1] * 4
