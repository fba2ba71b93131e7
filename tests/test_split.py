"""sengine.geom.split: many polygons cut by lines at once, checked against GEOS."""

from __future__ import annotations

import numpy as np
import shapely
from _oracles import segments_on, split_by_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.boundary import ring_segments, segments_on_boundary
from sengine.geom.split import RingSet, cut_lengths, split

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def polygon(draw):
    """Stars (concave), holed stars, and grid polygons whose vertices sit on integer cut lines."""
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    kind = draw(st.sampled_from(["star", "holed", "grid", "notch"]))
    if kind in ("star", "holed"):
        k = int(rng.integers(4, 18))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        r = rng.uniform(2, 10, k)
        p = shapely.make_valid(shapely.Polygon(np.c_[r * np.cos(ang), r * np.sin(ang)]))
        p = max((g for g in shapely.get_parts(p) if g.geom_type == "Polygon"), key=lambda g: g.area)
        if kind == "holed" and p.contains(shapely.box(-1, -1, 1, 1)):
            p = p.difference(shapely.box(-1, -1, 1, 1))
    elif kind == "grid":
        p = shapely.box(0, 0, 4, 4).difference(shapely.box(1, 1, 2, 3)).union(shapely.box(4, 1, 6, 2))
    else:
        p = shapely.Polygon([(0, 0), (4, 0), (4, 4), (2, 1), (0, 4)])
    if draw(st.booleans()):  # a UTM-sized frame
        p = shapely.affinity.translate(p, 5e5, 5.6e6)
    return p


@st.composite
def cuts(draw):
    polys = draw(st.lists(polygon(), min_size=1, max_size=8))
    polys = np.array(
        [p for p in polys if p.geom_type == "Polygon" and p.is_valid] or [shapely.box(0, 0, 1, 1)], dtype=object
    )
    n = len(polys)
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    b = shapely.bounds(polys)
    on_grid = rng.random(n) < 0.5  # through vertices, along edges
    pt = np.where(
        on_grid[:, None],
        b[:, :2] + rng.integers(0, 4, (n, 2)),
        np.c_[rng.uniform(b[:, 0], b[:, 2]), rng.uniform(b[:, 1], b[:, 3])],
    )
    ang = np.where(on_grid, rng.integers(0, 4, n) * np.pi / 4, rng.uniform(0, np.pi, n))
    d = np.c_[np.cos(ang), np.sin(ang)]
    d[np.abs(d) < 1e-12] = 0.0
    return polys, pt, d


def test_ring_set_round_trip():
    polys = np.array(
        [
            shapely.box(0, 0, 10, 5),
            shapely.box(0, 0, 10, 10).difference(shapely.box(3, 3, 6, 6)),
            shapely.Polygon([(0, 0), (1, 0), (1, 0), (1, 1), (0, 0)]),
            shapely.Polygon(),
        ],
        dtype=object,
    )
    rs = RingSet.from_polygons(polys)
    assert rs.n == 4
    assert np.allclose(rs.areas(), shapely.area(polys))
    back = rs.polygons()
    assert all(a.equals(b) for a, b in zip(back[:3], polys[:3]))
    assert back[3].is_empty
    assert np.array_equal(rs.take([1]).polygons()[0].normalize(), polys[1].normalize())


@SETTINGS
@given(cuts())
def test_split_matches_geos_and_keeps_marks(case):
    polys, pt, d = case
    rs = RingSet.from_polygons(polys)
    pieces, parent, side, failed = split(rs, pt, d)
    out = pieces.polygons()
    assert shapely.is_valid(out).all()
    assert (shapely.area(out) > 0).all()
    left, right = split_by_line(polys, pt, d)
    a = shapely.area(polys)
    ok = ~failed
    for s, ref in ((1, left), (0, right)):
        got = np.bincount(parent[side == s], weights=shapely.area(out[side == s]), minlength=len(polys))
        assert np.allclose(got[ok], shapely.area(ref)[ok], rtol=0, atol=1e-9 * a.max())
    # a piece lies on its side of the line
    c = shapely.get_coordinates(out, return_index=True)
    xy, idx = c
    nrm = np.c_[-d[:, 1], d[:, 0]][parent[idx]]
    sgn = np.einsum("ij,ij->i", xy - pt[parent[idx]], nrm)
    scale = 1e-9 * (1 + (np.abs(xy).max() if len(xy) else 0.0))
    assert (sgn[side[idx] == 1] >= -scale).all() and (sgn[side[idx] == 0] <= scale).all()
    # marks: original edges keep theirs, the cut adds unmarked edges on the line; cut_lengths agrees
    marked = pieces.flagged_length()
    _, left_len, right_len = cut_lengths(rs, pt, d)
    for s, ref in ((1, left_len), (0, right_len)):
        got = np.bincount(parent[side == s], weights=marked[side == s], minlength=len(polys))
        assert np.allclose(got[ok], ref[ok], atol=1e-6)
    perim = np.bincount(parent, weights=shapely.length(out), minlength=len(polys))
    chords = perim - np.bincount(parent, weights=marked, minlength=len(polys))
    assert np.allclose(chords[ok] / 2, (perim - shapely.length(polys))[ok] / 2, atol=1e-6)
    # few cuts are refused, and only degenerate ones (through vertices or along edges)
    assert failed.sum() <= len(polys)


def test_cut_through_a_concave_polygon_and_a_hole():
    u = shapely.Polygon([(0, 0), (10, 0), (10, 10), (7, 10), (7, 3), (3, 3), (3, 10), (0, 10)])
    holed = shapely.box(0, 0, 10, 10).difference(shapely.box(4, 4, 6, 6))
    rs = RingSet.from_polygons([u, holed, holed])
    pieces, parent, side, failed = split(rs, [(0, 5), (0, 5), (0, 8)], [(1, 0), (1, 0), (1, 0)])
    assert not failed.any()
    assert np.bincount(parent, minlength=3).tolist() == [3, 2, 2]  # U: two arms above, base below
    out = pieces.polygons()
    assert shapely.get_num_interior_rings(out[parent == 2]).sum() == 1  # the hole stays whole, below the line
    n, left, right = cut_lengths(rs, [(0, 5), (0, 5), (0, 8)], [(1, 0)] * 3)
    assert n.tolist() == [4, 4, 2]


def test_split_of_nothing_and_missed_polygons():
    rs = RingSet.from_polygons([shapely.box(0, 0, 1, 1)])
    pieces, parent, side, failed = split(rs, [(5, 5)], [(1, 0)])
    assert parent.tolist() == [0] and side.tolist() == [0] and not failed.any()
    empty = RingSet.from_polygons([])
    assert split(empty, np.zeros((0, 2)), np.zeros((0, 2)))[0].n == 0


def test_segments_on_boundary_matches_the_geos_test():
    blocks = np.array(
        [shapely.box(0, 0, 100, 50), shapely.box(200, 0, 300, 50).difference(shapely.box(240, 10, 260, 40))]
    )
    lots = np.array(
        [
            shapely.box(0, 0, 30, 20),
            shapely.box(30, 20, 60, 30),
            shapely.box(240, 0, 260, 10),
            shapely.box(0, 30, 100, 50),
        ]
    )
    owner = np.array([0, 0, 1, 0])
    p0, p1, idx, ring, on = segments_on_boundary(lots, owner, blocks, tol=1e-6)
    q0, q1, qidx, _ = ring_segments(lots)
    assert np.array_equal(p0, q0) and np.array_equal(idx, qidx)
    ref = segments_on(p0, p1, shapely.boundary(blocks)[owner[idx]], tol=1e-6)
    assert np.array_equal(on, ref)
    assert np.bincount(idx[on], weights=np.hypot(*(p1 - p0)[on].T), minlength=4).tolist() == [50, 0, 40, 140]


@SETTINGS
@given(cuts())
def test_pieces_of_a_polygon_do_not_depend_on_its_batch(case):
    polys, pt, d = case
    rs = RingSet.from_polygons(polys)
    pieces, parent, side, failed = split(rs, pt, d)
    out = shapely.to_wkb(pieces.polygons())
    for i in range(len(polys)):
        alone, _, s1, f1 = split(rs.take([i]), pt[i : i + 1], d[i : i + 1])
        assert f1[0] == failed[i]
        assert shapely.to_wkb(alone.polygons()).tolist() == out[parent == i].tolist()
        assert s1.tolist() == side[parent == i].tolist()
