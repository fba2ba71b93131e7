"""sengine.geom.planar: cutting closed walks into simple cycles, vectorized against the stack walk."""

from __future__ import annotations

import numpy as np
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.geom.planar import _split_walk, planar_faces, split_walks

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def face_walks(draw):
    """Closed walks like a face boundary: cycles hanging off each other's vertices (a cactus), rotated."""
    counter = [0]

    def cycle(depth):
        k = draw(st.integers(2, 4))
        verts = list(range(counter[0], counter[0] + k))
        counter[0] += k
        out = []
        for x in verts:
            out.append(x)
            for _ in range(draw(st.integers(0, 2)) if depth < 3 else 0):
                out += cycle(depth + 1) + [x]
        return out

    walks = []
    for _ in range(draw(st.integers(1, 4))):
        w = cycle(0)
        r = draw(st.integers(0, len(w) - 1))
        walks.append(w[r:] + w[:r])
    return walks


def _as_lists(vertex, cycle, cycle_walk):
    return [(int(cycle_walk[c]), vertex[cycle == c].tolist()) for c in range(len(cycle_walk))]


@SETTINGS
@given(face_walks())
def test_split_walks_is_the_stack_walk(walks):
    vid = np.concatenate([np.asarray(w) for w in walks])
    walk = np.repeat(np.arange(len(walks)), [len(w) for w in walks])
    expected = [(i, c) for i, w in enumerate(walks) for c in _split_walk(w)]
    assert _as_lists(*split_walks(vid, walk, len(walks))) == expected


def test_walks_that_do_not_nest_take_the_stack_walk():
    """a .. b .. a .. b cannot bound a face of a plane graph; the result is still the stack walk's."""
    walks = [[0, 1, 2, 0, 5, 1, 6], [7, 8, 9]]
    vid = np.concatenate([np.asarray(w) for w in walks])
    walk = np.repeat(np.arange(2), [7, 3])
    expected = [(i, c) for i, w in enumerate(walks) for c in _split_walk(w)]
    assert _as_lists(*split_walks(vid, walk, 2)) == expected


def test_pinched_faces_keep_each_lobe():
    """Two squares sharing a corner inside a big square: one face touching itself at that corner."""
    xy = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [2, 2], [5, 2], [5, 5], [2, 5], [8, 5], [8, 8], [5, 8]], float)
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (6, 8), (8, 9), (9, 10), (10, 6)]
    u, v = np.array(edges).T
    pf = planar_faces(xy, u, v)
    assert pf.counts["pinched"] == 1 and pf.counts["faces"] == 3
    assert np.isclose(sum(p.area for p in pf.polygons), 100.0)
    shells = pf.walk_polygon[pf.walk_polygon >= 0]
    assert sorted(pf.polygons[shells].tolist(), key=lambda p: p.area)[0].area == 9.0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 10**6), min_size=0, max_size=400), st.integers(0, 2**32 - 1))
def test_permutation_cycles_are_scipys_components(keys, seed):
    """The cycles of a permutation labelled as scipy's weak components: by their lowest element."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from sengine.geom.planar import permutation_cycles

    n = len(keys)
    perm = np.argsort(np.asarray(keys, np.int64), kind="stable") if n else np.zeros(0, np.int64)
    if n and seed % 3 == 0:  # long cycles too: one n-cycle through a shuffled order
        order = np.random.default_rng(seed).permutation(n)
        perm = np.empty(n, np.int64)
        perm[order] = np.roll(order, -1)
    count, label = permutation_cycles(perm)
    graph = csr_matrix((np.ones(n, np.int8), (np.arange(n), perm)), shape=(n, n))
    want_count, want = connected_components(graph, directed=True, connection="weak")
    assert count == want_count
    assert label.dtype == np.int64 and np.array_equal(label, want)
    # a cycle's elements share its label, and following the permutation never leaves it
    assert np.array_equal(label[perm], label)


def test_permutation_cycles_of_a_long_cycle():
    from sengine.geom.planar import permutation_cycles

    n = 100_003
    perm = np.roll(np.arange(n), 1)  # one cycle through every element
    count, label = permutation_cycles(perm)
    assert count == 1 and not label.any()
    count, label = permutation_cycles(np.arange(7))
    assert count == 7 and np.array_equal(label, np.arange(7))


@settings(max_examples=150, deadline=None)
@given(st.integers(4, 80), st.floats(0.0, 1.0), st.integers(0, 2**32 - 1))
def test_removing_edges_from_a_trace_is_tracing_the_rest(npts, share, seed):
    """planar._without (the faces once bridges or any edges are gone, patched from the whole graph's trace)
    equals tracing the smaller graph afresh: same next permutation, cycle minima, labels and areas."""
    from sengine.geom.planar import _cycle_min, _labels_of_min, _trace, _without

    rng = np.random.default_rng(seed)
    xy = rng.integers(0, 40, (npts, 2)).astype(float)  # a grid: collinear and repeated points too
    xy = np.unique(xy, axis=0)
    if len(xy) < 3:
        return
    tri = shapely.delaunay_triangles(shapely.multipoints(xy), only_edges=True)
    c = shapely.get_coordinates(shapely.get_parts(tri)).reshape(-1, 2, 2)
    ids = {tuple(p): k for k, p in enumerate(xy.tolist())}
    u = np.array([ids[tuple(p)] for p in c[:, 0].tolist()], np.int64)
    v = np.array([ids[tuple(p)] for p in c[:, 1].tolist()], np.int64)
    if len(u) == 0:
        return
    nxt, face, area, low, cross = _trace(xy, u, v)
    gone = rng.random(len(u)) < share
    if seed % 2:  # the bridges of what is left, as planar_faces removes them
        keep = np.flatnonzero(~gone)
        f = _trace(xy, u[keep], v[keep])[1] if len(keep) else np.zeros(0, np.int64)
        gone[keep[f[0::2] == f[1::2]]] = True
    live, nxt2, low2 = _without(nxt, low, gone)
    keep = np.flatnonzero(~gone)
    assert np.array_equal(live >> 1, np.repeat(keep, 2))
    if len(keep) == 0:
        assert len(nxt2) == 0
        return
    want_nxt, want_face, want_area, want_low, _ = _trace(xy, u[keep], v[keep])
    assert np.array_equal(nxt2, want_nxt)
    assert np.array_equal(low2, want_low) and np.array_equal(low2, _cycle_min(nxt2))
    nf, face2 = _labels_of_min(low2)
    assert np.array_equal(face2, want_face)
    assert np.array_equal(np.bincount(face2, weights=cross[live], minlength=nf) / 2.0, want_area)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.integers(3, 12), min_size=1, max_size=12),
    st.integers(0, 2**32 - 1),
    st.sampled_from([0.0, 1e3, 5.6e6]),
)
def test_star_simple_certifies_only_valid_counter_clockwise_rings(sizes, seed, far):
    """planar.star_simple: every ring it certifies is a valid polygon (GEOS) of positive area, far from the
    origin too; convex rings (extra collinear and repeated vertices included) are certified, their mirror
    images (clockwise) and rings folded over themselves are not."""
    from sengine.geom.planar import star_simple

    rng = np.random.default_rng(seed)
    rings, want = [], []
    for k in sizes:
        kind = rng.integers(0, 4)
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        rad = rng.uniform(0.5, 30.0) * (rng.uniform(0.2, 1.0, k) if kind == 3 else np.ones(k))
        ring = np.c_[rad * np.cos(ang), rad * np.sin(ang)] + far + rng.uniform(-50, 50, 2)
        if kind == 1 and k >= 3:  # a vertex repeated and a point on an edge: still convex
            ring = np.insert(ring, 1, ring[0], axis=0)
            ring = np.insert(ring, 3, 0.5 * (ring[2] + ring[3]), axis=0)
        if kind == 2:  # folded: vertices in a random order
            ring = ring[rng.permutation(len(ring))]
        closed = np.r_[ring, ring[:1]]
        if rng.random() < 0.25:  # clockwise
            closed = closed[::-1]
        rings.append(closed)
        want.append(kind in (0, 1))
    star = 10.0 * np.exp(1j * 4 * np.pi * np.arange(6) / 5) + far  # a pentagram: round its centre twice
    rings.append(np.c_[star.real, star.imag])
    want.append(False)
    xy = np.concatenate(rings)
    n = np.array([len(r) for r in rings])
    sure = star_simple(xy, n)
    assert not sure[-1]
    polys = shapely.polygons(shapely.linearrings(xy, indices=np.repeat(np.arange(len(n)), n)))
    ccw = shapely.is_ccw(shapely.get_exterior_ring(polys))
    assert not (sure & ~(shapely.is_valid(polys) & ccw & (shapely.area(polys) > 0))).any()
    # convex counter-clockwise rings of distinct directions are certified (the test can say yes)
    distinct = np.array([len(np.unique(np.round(r[:-1], 9), axis=0)) >= 3 for r in rings])
    assert (sure[np.array(want) & ccw & distinct & shapely.is_valid(polys)]).all()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.integers(3, 40), min_size=1, max_size=6),
    st.integers(0, 2**32 - 1),
    st.sampled_from([1, 2, 3, 5]),
)
def test_ring_crossings_are_the_edge_pairs_geos_sees_meet(sizes, seed, chain):
    """planar.ring_crossings: exactly the pairs of non-consecutive edges of one ring that GEOS says intersect
    (cross, touch at a vertex, or overlap collinearly), on integer coordinates (exact predicates): smooth
    star-shaped rings (none), random walks (folds and crossings), rings with repeated vertices and collinear
    runs, several rings in one call (pairs never span two rings), any run length."""
    from sengine.geom.planar import ring_crossings

    rng = np.random.default_rng(seed)
    rings = []
    for k in sizes:
        kind = rng.integers(0, 3)
        if kind == 0:  # star-shaped round its centre: simple
            ang = np.sort(rng.choice(3600, k, replace=False)) * (2 * np.pi / 3600)
            ring = np.round(np.c_[np.cos(ang), np.sin(ang)] * rng.uniform(200, 1000, (k, 1)))
        elif kind == 1:  # a random walk on a small grid: crossings, touchings, collinear overlaps
            ring = np.cumsum(rng.integers(-3, 4, (k, 2)), axis=0).astype(float)
        else:  # a walk along the axes with repeated vertices
            ring = np.cumsum(rng.integers(-2, 3, (k, 2)) * (rng.random((k, 1)) < [0.5, 0.5]), axis=0).astype(float)
        rings.append(ring + rng.integers(-5, 5, 2) * 1000.0)
    xy = np.concatenate(rings)
    n = np.array([len(r) for r in rings])
    i, j = ring_crossings(xy, n, chain=chain)
    got = set(zip(i.tolist(), j.tolist()))
    want = set()
    start = np.cumsum(n) - n
    for s, k in zip(start, n):
        ends = [(xy[s + a], xy[s + (a + 1) % k]) for a in range(k)]
        # an edge of zero length (a repeated vertex) is its point (GEOS sees no line there)
        seg = [shapely.Point(p) if (p == q).all() else shapely.LineString([p, q]) for p, q in ends]
        for a in range(k):
            for b in range(a + 2, k):
                if a == 0 and b == k - 1:
                    continue  # consecutive round the ring's start
                if shapely.intersects(seg[a], seg[b]):
                    want.add((s + a, s + b))
    assert got == want
    assert (i < j).all()


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 40), st.integers(0, 5000), st.integers(0, 2**32 - 1))
def test_angular_order_is_the_lexsort_of_origin_and_angle(npts, nedges, seed):
    """Half-edges grouped by origin and sorted by angle per degree are np.lexsort((angle, origin)), ties included.

    Points on a 4 x 4 grid repeat directions (equal angles at one node) and
    give nodes of every degree; above 4096 half-edges the radix sort runs.
    """
    from sengine.geom.planar import _angular_order

    rng = np.random.default_rng(seed)
    xy = rng.integers(0, 4, (npts, 2)).astype(float)
    u, v = rng.integers(0, npts, nedges), rng.integers(0, npts, nedges)
    org, dst = np.stack([u, v], axis=1).ravel(), np.stack([v, u], axis=1).ravel()
    d = xy[dst] - xy[org]
    want = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), org))
    assert np.array_equal(_angular_order(xy, u, v), want)


def test_walk_edges_name_the_edge_each_walk_step_runs_along():
    """Two squares sharing an edge, given twice (a duplicate) and with a self-loop: each walk step's edge."""
    xy = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]], float)
    edges = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0), (1, 4), (4, 1), (3, 3)]
    u, v = np.array(edges).T
    pf = planar_faces(xy, u, v)
    assert pf.edge_unique[8] == -1 and pf.edge_unique[6] == pf.edge_unique[7] >= 0
    for k in range(len(pf.walk_start) - 1):
        walk = pf.walk_vertex[pf.walk_start[k] : pf.walk_start[k + 1]]
        step = pf.walk_edge[pf.walk_start[k] : pf.walk_start[k + 1]]
        for a, b, e in zip(walk, np.roll(walk, -1), step):
            ends = {(int(x), int(y)) for x, y in zip(u, v) if x != y}
            # the step a -> b runs along input edges whose distinct edge is e
            mine = [i for i in range(len(u)) if pf.edge_unique[i] == e]
            assert mine and all({int(u[i]), int(v[i])} == {int(a), int(b)} for i in mine)
            assert (int(a), int(b)) in ends or (int(b), int(a)) in ends
