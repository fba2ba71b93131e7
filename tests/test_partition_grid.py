"""clip_frame_grid (sengine.geom.grid): the numpy test of which cells lie near a ring changes nothing.

Cells farther than the clearance from every ring are classified by their centre alone; the result must
be the one GEOS's box predicates give on every cell (the reference below, the function as it was):
same cells, byte for byte, same flags.  Blocks: random convex, concave and holed polygons, grids
aligned with their edges or not, cell edges through their vertices, clearances 0 to 1 mm.
"""

from __future__ import annotations

import numpy as np
import shapely
import shapely.affinity
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sengine.geom.grid import _boxes, clip_frame_grid
from sengine.geom.polygons import clip_frame_boxes, obb_frame

# a courtyard whose sides run 0.5 mm inside the 10 m grid's lines: the cells beside it are not inside by 1 mm
HOLE_NEAR_EDGE = shapely.Polygon(
    shapely.box(0, 0, 100, 100).exterior.coords, [shapely.box(40.0005, 40.0005, 59.9995, 59.9995).exterior.coords]
)


def reference(geoms, center, axis, xs, nx, ys, ny, clearance):
    """Every cell through GEOS's box predicates (clip_frame_grid before the numpy test)."""
    n = len(geoms)
    xstart = np.cumsum(nx + 1) - (nx + 1)
    ystart = np.cumsum(ny + 1) - (ny + 1)
    x_lo, x_hi, y_lo, y_hi = xs[xstart], xs[xstart + nx], ys[ystart], ys[ystart + ny]
    margin = 1.0 + 0.01 * ((x_hi - x_lo) + (y_hi - y_lo))
    own = np.repeat(np.arange(n), nx * ny)
    j = np.arange(int((nx * ny).sum())) - np.repeat(np.cumsum(nx * ny) - nx * ny, nx * ny)
    ix, iy = j // ny[own], j % ny[own]
    a0 = np.where(ix == 0, x_lo[own] - margin[own], xs[xstart[own] + ix])
    a1 = np.where(ix == nx[own] - 1, x_hi[own] + margin[own], xs[xstart[own] + ix + 1])
    b0 = np.where(iy == 0, y_lo[own] - margin[own], ys[ystart[own] + iy])
    b1 = np.where(iy == ny[own] - 1, y_hi[own] + margin[own], ys[ystart[own] + iy + 1])
    boxes = _boxes(center[own], axis[own], a0, a1, b0, b1)
    c = clearance
    inside = shapely.contains_properly(geoms[own], boxes)
    edge = np.zeros(len(own), bool)
    if c > 0:
        s = np.flatnonzero(inside)
        grown = _boxes(center[own[s]], axis[own[s]], a0[s] - c, a1[s] + c, b0[s] - c, b1[s] + c)
        inside[s] = shapely.contains_properly(geoms[own[s]], grown)
        edge[s] = ~inside[s]
    rest = np.flatnonzero(~inside & ~edge)
    edge[rest] = shapely.intersects(geoms[own[rest]], boxes[rest])
    cells = np.where(inside, boxes, None)
    e = np.flatnonzero(edge)
    strips = clip_frame_boxes(
        geoms[own[e]],
        center[own[e]],
        axis[own[e]],
        a0[e],
        a1[e],
        y_lo[own[e]] - margin[own[e]],
        y_hi[own[e]] + margin[own[e]],
    )
    cells[e] = clip_frame_boxes(strips, center[own[e]], axis[own[e]], a0[e], a1[e], b0[e], b1[e])
    return cells, own, ix, iy, inside, edge


@st.composite
def block(draw):
    kind = draw(st.sampled_from(["convex", "star", "holed", "rect"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    size = draw(st.floats(20.0, 300.0))
    if kind == "convex":
        poly = shapely.MultiPoint(rng.uniform(0, size, (10, 2))).convex_hull
    elif kind == "star":
        k = draw(st.integers(5, 12))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        r = rng.uniform(5, 0.5 * size + 5, k)
        poly = shapely.Polygon(np.c_[r * np.cos(ang), r * np.sin(ang)])
    elif kind == "holed":
        a, b = draw(st.floats(0.15, 0.45)), draw(st.floats(0.55, 0.85))
        poly = shapely.Polygon(
            shapely.box(0, 0, size, size).exterior.coords,
            [shapely.box(a * size, a * size, b * size, b * size).exterior.coords],
        )
    else:
        poly = shapely.box(0, 0, size, draw(st.floats(5.0, 200.0)))
    poly = shapely.make_valid(poly)
    parts = [p for p in shapely.get_parts(poly) if p.geom_type == "Polygon"]
    poly = max(parts, key=lambda p: p.area) if parts else shapely.box(0, 0, 10, 10)
    poly = shapely.affinity.rotate(poly, draw(st.floats(0, 180)), origin=(0, 0))
    return shapely.affinity.translate(poly, draw(st.floats(-1e5, 1e5)), draw(st.floats(-1e5, 1e5)))


def grid(polys, cell, aligned):
    """Each block's own frame (its oriented box) with cells ``cell`` m (edges from its box's corner)."""
    center, axis, L, W = obb_frame(polys)
    if not aligned:  # a frame turned off the box: cell edges cross the outline at a slant
        t = np.radians(7.0)
        axis = np.c_[axis[:, 0] * np.cos(t) - axis[:, 1] * np.sin(t), axis[:, 0] * np.sin(t) + axis[:, 1] * np.cos(t)]
        L = W = np.hypot(L, W)
    nx = np.maximum(1, np.ceil(L / cell[0])).astype(np.int64)
    ny = np.maximum(1, np.ceil(W / cell[1])).astype(np.int64)
    xs = np.concatenate([np.minimum(np.arange(k + 1) * cell[0], length) - length / 2 for k, length in zip(nx, L)])
    ys = np.concatenate([np.minimum(np.arange(k + 1) * cell[1], w) - w / 2 for k, w in zip(ny, W)])
    return center, axis, xs, nx, ys, ny


@settings(max_examples=60, deadline=None)
@given(
    st.lists(block(), min_size=1, max_size=4),
    st.tuples(st.floats(1.0, 60.0), st.floats(1.0, 60.0)),
    st.booleans(),
    st.sampled_from([0.0, 1e-6, 1e-3]),
)
@example([shapely.box(0, 0, 90, 60), shapely.box(1e4, 1e4, 1e4 + 30, 1e4 + 30)], (30.0, 20.0), True, 1e-6)
@example([HOLE_NEAR_EDGE], (10.0, 10.0), True, 1e-3)  # the cells beside the hole are within 0.5 mm of it: near
def test_the_numpy_classification_gives_what_geos_gives(polys, cell, aligned, clearance):
    geoms = np.array(polys, dtype=object)
    center, axis, xs, nx, ys, ny = grid(geoms, cell, aligned)
    got = clip_frame_grid(geoms, center, axis, xs, nx, ys, ny, clearance=clearance)
    cells, own, ix, iy, inside, edge = reference(geoms, center, axis, xs, nx, ys, ny, clearance)
    live = inside | edge
    live[edge] &= ~shapely.is_empty(cells[edge])
    # the function also drops whole cells lying in a hole: compare the cells it keeps with the reference's
    key = own * 10**6 + ix * 10**3 + iy
    kept = np.isin(key, got[1] * 10**6 + got[2] * 10**3 + got[3])
    assert (kept <= live).all() and (live & ~kept <= ~inside).all()
    assert np.array_equal(got[1], own[kept]) and np.array_equal(got[2], ix[kept]) and np.array_equal(got[3], iy[kept])
    assert np.array_equal(got[4], inside[kept])
    assert shapely.to_wkb(got[0]).tolist() == shapely.to_wkb(cells[kept]).tolist()
    # and the cells partition the blocks
    for b, g in enumerate(geoms):
        assert abs(shapely.area(got[0][got[1] == b]).sum() - g.area) <= 1e-6 * g.area


@settings(max_examples=60, deadline=None)
@given(
    st.lists(block(), min_size=1, max_size=4),
    st.integers(1, 12),
    st.floats(0.0, 1.0),
    st.booleans(),
    st.integers(0, 2**31),
)
def test_strips_from_fewer_vertices_are_the_same_pieces(polys, ncol, bands, aligned, seed):
    """_clip_strips leaves out vertices beyond a side of each rectangle: GEOS's pieces stay the same bytes.

    Rectangles: columns across each block's frame, some also cut short across (so that runs of
    vertices beyond their top and bottom are left out too), and a rectangle wholly off a block.
    """
    from sengine.geom.grid import _clip_strips

    geoms = np.array(polys + [shapely.MultiPolygon([polys[0], shapely.box(1e6, 1e6, 1e6 + 5, 1e6 + 5)])], object)
    center, axis, L, W = obb_frame(geoms)
    if not aligned:
        t = np.radians(11.0)
        axis = np.c_[axis[:, 0] * np.cos(t) - axis[:, 1] * np.sin(t), axis[:, 0] * np.sin(t) + axis[:, 1] * np.cos(t)]
    rng = np.random.default_rng(seed)
    which = np.repeat(np.arange(len(geoms)), ncol + 1)
    edges = np.linspace(-0.6, 0.6, ncol + 1)
    j = np.tile(np.arange(ncol + 1), len(geoms))
    span = np.maximum(L, W)[which]
    a0 = np.where(j < ncol, edges[np.minimum(j, ncol - 1)], 2.0) * span
    a1 = np.where(j < ncol, edges[np.minimum(j + 1, ncol)], 3.0) * span  # the last: off the block
    short = rng.random(len(which)) < bands
    b0 = np.where(short, rng.uniform(-0.4, 0.1, len(which)), -1.0) * span
    b1 = np.where(short, rng.uniform(-0.1, 0.4, len(which)), 1.0) * span
    b0, b1 = np.minimum(b0, b1), np.maximum(b0, b1)  # the grid's rectangles run from low to high
    got = _clip_strips(geoms, which, center, axis, a0, a1, b0, b1)
    ref = clip_frame_boxes(geoms[which], center[which], axis[which], a0, a1, b0, b1)
    assert shapely.to_wkb(got).tolist() == shapely.to_wkb(ref).tolist()


def test_strips_keep_the_vertices_where_geos_orients_a_ring():
    """GEOS orients a ring by the turn at its highest vertex: here (3, 8), its first, then (0, 2).

    (0, 2) lies inside a run of vertices left of the column: left out, the turn at (3, 8) would go on to
    (2, 2), clockwise, and GEOS would give the column's complement (three pieces) instead of its two.
    """
    from sengine.geom.grid import _clip_strips

    poly = shapely.Polygon([(3, 8), (0, 2), (2, 2), (6, 3), (6, 4), (4, 3), (8, 8), (2, 3), (3, 8)])
    geoms, c, ax = np.array([poly], object), np.zeros((1, 2)), np.array([[1.0, 0.0]])
    lims = (np.array([4.5]), np.array([5.5]), np.array([-20.0]), np.array([30.0]))
    got = _clip_strips(geoms, np.array([0]), c, ax, *lims)[0]
    ref = clip_frame_boxes(geoms, c, ax, *lims)[0]
    assert shapely.to_wkb(got) == shapely.to_wkb(ref)
    assert abs(got.area - shapely.clip_by_rect(poly, 4.5, -20, 5.5, 30).area) < 1e-9


@settings(max_examples=150, deadline=None)
@given(
    st.integers(0, 60),
    st.integers(0, 60),
    st.sampled_from([0.5, 3.0, 40.0, None]),
    st.integers(1, 4),
    st.integers(0, 2**32 - 1),
)
def test_box_pairs_are_the_strtree_query(na, nb, cell, ngroups, seed):
    """grid.box_pairs: the pairs of boxes that meet (touching counts), of the same group, as an STRtree query
    of the boxes gives them (as a set, each once), for any cell size; boxes flat, tiny, long and shared."""
    from sengine.geom.grid import box_pairs

    rng = np.random.default_rng(seed)

    def boxes(n):
        lo = rng.integers(-20, 20, (n, 2)).astype(float) * rng.choice([1.0, 0.37], (n, 1))
        ext = rng.choice([0.0, 0.5, 3.0, 25.0], (n, 2))  # flat boxes (segments along an axis) too
        return lo, lo + ext

    lo_a, hi_a = boxes(na)
    lo_b, hi_b = boxes(nb)
    ga, gb = rng.integers(0, ngroups, na), rng.integers(0, ngroups, nb)
    ea, eb = rng.random(na) < 0.1, rng.random(nb) < 0.1  # empty geometries: NaN bounds, in no pair
    lo_a[ea], hi_a[ea], lo_b[eb], hi_b[eb] = np.nan, np.nan, np.nan, np.nan
    ia, ib = box_pairs(lo_a, hi_a, lo_b, hi_b, group_a=ga, group_b=gb, cell=cell)
    if na and nb:
        ba = np.where(ea, shapely.Polygon(), shapely.box(lo_a[:, 0], lo_a[:, 1], hi_a[:, 0], hi_a[:, 1]))
        bb = np.where(eb, shapely.Polygon(), shapely.box(lo_b[:, 0], lo_b[:, 1], hi_b[:, 0], hi_b[:, 1]))
        qa, qb = shapely.STRtree(bb).query(ba)
        same = ga[qa] == gb[qb]
        want = sorted(zip(qa[same].tolist(), qb[same].tolist()))
    else:
        want = []
    assert np.all(np.diff(ia) >= 0)
    assert sorted(zip(ia.tolist(), ib.tolist())) == want


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 80), st.sampled_from([0.5, 3.0, 40.0, None]), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_box_self_pairs_are_box_pairs_one_way_round(n, cell, ngroups, seed):
    """grid.box_self_pairs: box_pairs of a set with itself, the pairs i < j only, in the very same order
    (which crossing of several rays at one point names the node depends on it); boxes flat, shared, empty."""
    from sengine.geom.grid import box_pairs, box_self_pairs

    rng = np.random.default_rng(seed)
    lo = rng.integers(-20, 20, (n, 2)).astype(float) * rng.choice([1.0, 0.37], (n, 1))
    hi = lo + rng.choice([0.0, 0.5, 3.0, 25.0], (n, 2))
    lo[rng.random(n) < 0.1] = np.nan
    g = rng.integers(0, ngroups, n)
    i, j = box_pairs(lo, hi, lo, hi, group_a=g, group_b=g, cell=cell)
    si, sj = box_self_pairs(lo, hi, group=g, cell=cell)
    assert (si < sj).all()
    assert np.array_equal(si, i[i < j]) and np.array_equal(sj, j[i < j])
