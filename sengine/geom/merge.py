"""Small pieces of a partition merged into a neighbour of the same group.

A polygon partition cut by clipping or splitting (lots of a block) can leave
slivers: pieces of (nearly) zero area where a cut runs through a corner.
:func:`merge_small` gives each piece under a threshold to the neighbour of
its group with which it shares the longest boundary, so the partition keeps
its area and loses the sliver.  Shared boundaries are measured in numpy
from the pieces' segments (:func:`shared_length`); only the unions of the
few small pieces with their neighbours are GEOS overlays.
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["kept_area", "merge_small", "shared_length"]

TOUCH = 1e-6  # m: pieces closer than this share boundary
SNAP_GRIDS = (1e-9, 1e-7, 1e-6)  # m: grids a union that is not one polygon is snapped to, finest first


def merge_small(polys, group, min_area, *, touch: float = TOUCH, cell=None, drop_below: float = 1.0):
    """Merge pieces smaller than ``min_area`` into a neighbour of the same group.

    Parameters
    ----------
    polys : array_like of shapely.Polygon (k,)
        Pieces, e.g. the lots of many blocks.
    group : array_like of int (k,)
        Group of each piece (e.g. its block); pieces merge only within a group.
    min_area : float or array_like (k,)
        Pieces under this area (m2) merge.
    touch : float
        Pieces within this distance (m) count as neighbours; their shared
        boundary is measured within it.
    cell : (ndarray, ndarray) of int, optional
        Grid column and row of each piece when the pieces are cells of a grid
        per group: neighbours are then looked up among the cells next to a
        piece's own (no spatial index), which is much faster.
    drop_below : float
        A piece under this area (m2) that no neighbour can take (it touches
        them at points only) is dropped: a degenerate sliver, not a lot (so
        long as such pieces make at most 0.05 % of their group's area).

    Returns
    -------
    polys : ndarray of shapely.Polygon
        The pieces left, in their original order (a neighbour that took small
        pieces is replaced by the union).
    keep : ndarray of int64
        Index of each piece left into the input.
    grown : ndarray of bool
        Pieces left that took small ones.
    merged : int
        Pieces merged away.  A small piece without a neighbour in its group
        (a whole small block), or whose union with every neighbour would not
        be one polygon, stays, unless under ``drop_below``.
    dropped : int
        Pieces under ``drop_below`` dropped (zero-area ones included).
    """
    polys = np.asarray(polys, dtype=object).ravel()
    group = np.asarray(group, np.int64).ravel()
    k = len(polys)
    min_area = np.broadcast_to(np.asarray(min_area, np.float64), (k,))
    keep, grown, merged = np.arange(k), np.zeros(k, bool), 0
    if cell is not None:
        cell = (np.asarray(cell[0], np.int64), np.asarray(cell[1], np.int64))
    # neighbours by grid cell first; a piece that took others spans cells its own index does not name,
    # so whatever is still small then looks for its neighbours by their outlines (a spatial index)
    area = shapely.area(polys)  # kept up to date: only pieces that took others change
    for by_cell in (True, False) if cell is not None else (False,):
        if not by_cell and not (area < min_area[keep]).any():
            break
        while True:  # a sliver whose best neighbour was merging itself goes in the next pass (pieces only go)
            near = (cell[0][keep], cell[1][keep]) if by_cell else None
            polys, kept, took, done = _merge_pass(polys, group[keep], min_area[keep], touch, near, area=area)
            keep, grown, merged = keep[kept], grown[kept] | took, merged + done
            area = area[kept]
            area[took] = shapely.area(polys[took])
            if done == 0:
                break
    # what is left under drop_below touches its neighbours at points at most: degenerate, dropped
    gone = area < np.minimum(drop_below, min_area[keep])
    if gone.any():  # only where they are a hair of their group's area (a group of slivers stays whole)
        g = group[keep]
        lost = np.bincount(g, weights=np.where(gone, area, 0.0), minlength=int(g.max()) + 1)
        total = np.bincount(g, weights=area, minlength=int(g.max()) + 1)
        gone &= lost[g] <= 5e-4 * total[g]
        polys, keep, grown = polys[~gone], keep[~gone], grown[~gone]
    return polys, keep, grown, merged, int(gone.sum())


def _grid_pairs(small, group, ix, iy):
    """(small piece, piece) pairs of the same group in the same or a 4-neighbouring grid cell."""
    key = np.stack([group, ix, iy], axis=1)
    order = np.lexsort((iy, ix, group))
    sk = key[order]
    ii, jj = [], []
    for dx, dy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)):
        q = key[small] + (0, dx, dy)
        lo = _search(sk, q, "left")
        hi = _search(sk, q, "right")
        cnt = hi - lo
        ii.append(np.repeat(small, cnt))
        jj.append(order[np.repeat(lo, cnt) + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)])
    return np.concatenate(ii), np.concatenate(jj)


def _search(sorted_keys, q, side):
    """Row positions of ``q`` in lexicographically sorted integer rows ``sorted_keys``."""
    big = np.int64(1) << np.int64(20)  # columns and rows of a grid stay well under a million
    lin = (sorted_keys[:, 0] * big + sorted_keys[:, 1] + 1) * big + sorted_keys[:, 2] + 1
    return np.searchsorted(lin, (q[:, 0] * big + q[:, 1] + 1) * big + q[:, 2] + 1, side=side)


def _edges(geoms):
    """Boundary segments of each geometry: start points, end points (m, 2) and the geometry of each."""
    parts, pidx = shapely.get_parts(shapely.boundary(geoms), return_index=True)
    c, ci = shapely.get_coordinates(parts, return_index=True)
    e = np.flatnonzero(ci[1:] == ci[:-1])
    return c[e], c[e + 1], pidx[ci[e]]


def shared_length(a, b, touch: float = TOUCH) -> np.ndarray:
    """Length (m) of boundary that each geometry of ``a`` shares with the one of ``b`` beside it.

    A stretch of a segment of ``b`` counts where it runs along a segment of
    ``a`` within ``touch`` (m) of it: the overlap of their projections on the
    ``a`` segment, where ``b`` is within ``touch`` of its line at both ends of
    the overlap.  Summed over all segment pairs of the two boundaries (those
    of a partition do not overlap one another), so nearly collinear edges that
    do not share vertices count too: the length a planner would read as one
    party line.  All in numpy: only segment pairs near both boundaries' boxes
    are compared.

    Parameters
    ----------
    a, b : array_like of shapely.Geometry (k,)
        Pairs of (polygonal) geometries.
    touch : float
        Tolerance (m).

    Returns
    -------
    ndarray of float (k,)
    """
    a, b = np.asarray(a, dtype=object).ravel(), np.asarray(b, dtype=object).ravel()
    k = len(a)
    if k == 0:
        return np.zeros(0)
    p0, p1, ea = _edges(a)
    q0, q1, eb = _edges(b)
    grow = np.array([-touch, -touch, touch, touch])
    sa = np.flatnonzero(_near_box(p0, p1, shapely.bounds(b)[ea] + grow))
    sb = np.flatnonzero(_near_box(q0, q1, shapely.bounds(a)[eb] + grow))
    na, nb = np.bincount(ea[sa], minlength=k), np.bincount(eb[sb], minlength=k)
    m = na * nb
    pair = np.repeat(np.arange(k), m)
    r = np.arange(int(m.sum())) - np.repeat(np.cumsum(m) - m, m)
    ia = sa[(np.cumsum(na) - na)[pair] + r // nb[pair]]
    ib = sb[(np.cumsum(nb) - nb)[pair] + r % nb[pair]]
    d = p1[ia] - p0[ia]
    length = np.hypot(d[:, 0], d[:, 1])
    u = d / np.where(length > 0, length, 1.0)[:, None]
    w0, w1 = q0[ib] - p0[ia], q1[ib] - p0[ia]
    t0, t1 = np.einsum("ij,ij->i", u, w0), np.einsum("ij,ij->i", u, w1)  # along the a segment
    c0 = u[:, 0] * w0[:, 1] - u[:, 1] * w0[:, 0]  # across it
    c1 = u[:, 0] * w1[:, 1] - u[:, 1] * w1[:, 0]
    lo = np.maximum(0.0, np.minimum(t0, t1))
    hi = np.minimum(length, np.maximum(t0, t1))
    dt = np.where(t1 != t0, t1 - t0, 1.0)
    off_lo = c0 + (c1 - c0) * (lo - t0) / dt  # b's offset from the a segment at the overlap's ends
    off_hi = c0 + (c1 - c0) * (hi - t0) / dt
    ok = (length > 0) & (hi > lo) & (np.abs(off_lo) <= touch) & (np.abs(off_hi) <= touch)
    return np.bincount(pair[ok], weights=(hi - lo)[ok], minlength=k)


def _snapped_union(parts, area, outline, touch):
    """Union of ``parts`` on the finest of :data:`SNAP_GRIDS` (up to ``touch``) that makes one polygon of their area.

    A grid fine next to the coordinates (1 nm at 5,600 km north) can make GEOS's snap rounding fail
    (a ``TopologyException``): the next grid is tried.  The coarsest grid's union is returned whatever it is.
    """
    grids = [g for g in SNAP_GRIDS if g < touch] + [touch]
    for grid in grids:
        try:
            u = shapely.union_all(parts, grid_size=grid)
        except shapely.errors.GEOSException:
            if grid == grids[-1]:
                raise
            continue
        if shapely.get_type_id(u) == 3 and kept_area(np.array([u]), [area], [outline], grid)[0]:
            break
    return u


def kept_area(unions, area, outline, touch: float = TOUCH) -> np.ndarray:
    """Unions whose area is their parts' ``area`` (m2), to what snapping to ``touch`` (m) moves an ``outline`` (m).

    The union of pieces of a partition (which do not overlap) has their summed
    area.  GEOS's overlay can get a union of thin pieces with nearly coincident
    edges wrong (GEOS 3.14: two adjacent 85 m x 3 m lots whose shared vertex
    differs by 3e-15 m gave back one of them): such a union fails this test.
    """
    area = np.asarray(area, np.float64)
    tol = 1e-9 * area + touch * np.asarray(outline, np.float64)
    return np.abs(shapely.area(unions) - area) <= tol


def _near_box(s0, s1, box):
    """Segments whose bounding box meets ``box`` (xmin, ymin, xmax, ymax) rows."""
    lo, hi = np.minimum(s0, s1), np.maximum(s0, s1)
    return (hi[:, 0] >= box[:, 0]) & (lo[:, 0] <= box[:, 2]) & (hi[:, 1] >= box[:, 1]) & (lo[:, 1] <= box[:, 3])


def _merge_pass(polys, group, min_area, touch, cell=None, *, area=None):
    """One pass of :func:`merge_small`: each small piece into its best neighbour that is not merging away.

    ``area``: the pieces' areas (m2) when the caller knows them.
    """
    k = len(polys)
    area = shapely.area(polys) if area is None else area
    small = np.flatnonzero(area < min_area)
    if len(small) == 0:
        return polys, np.arange(k), np.zeros(k, bool), 0
    if cell is not None:
        i, j = _grid_pairs(small, group, *cell)
        ok = shapely.dwithin(polys[i], polys[j], touch)
    else:  # neighbours: pieces of the groups that have a small piece, found with a spatial index
        cand = np.flatnonzero(np.isin(group, np.unique(group[small])))
        si, nj = shapely.STRtree(polys[cand]).query(polys[small], predicate="dwithin", distance=touch)
        i, j = small[si], cand[nj]
        ok = np.ones(len(i), bool)
    ok &= (group[i] == group[j]) & (i != j)
    i, j = i[ok], j[ok]
    # the neighbour sharing the longest boundary; a larger piece wins a tie, then the first one (so the
    # choice does not depend on the order the candidates were found in); small ones come last
    shared = shared_length(polys[i], polys[j], touch)
    side = (shared > 0) & (area[i] > 0)  # a neighbour touching at a point only is none
    i, j, shared = i[side], j[side], shared[side]
    big_j = area[j] >= min_area[j]
    o = np.lexsort((j, -area[j], -shared, ~big_j, i))
    i, j = i[o], j[o]
    first = np.r_[True, i[1:] != i[:-1]] if len(i) else np.zeros(0, bool)
    i, j = i[first], j[first]
    # a small piece merges into a piece that is not itself merging away (no chains): a piece that a
    # smaller one (or an equal one before it) picked stays where it is and takes it; others wait for the next pass
    stays = np.zeros(k, bool)
    stays[j[(area[i] < area[j]) | ((area[i] == area[j]) & (i < j))]] = True  # equal ones: by order
    moving = ~stays[i]
    i, j = i[moving], j[moving]
    sel = ~np.isin(j, i)
    i, j = i[sel], j[sel]
    drop = np.zeros(k, bool)
    out = polys.copy()
    took = np.zeros(k, bool)
    if len(i):
        # a target taking one piece: one vectorized union; taking several: union_all each (rare)
        o = np.argsort(j, kind="stable")
        i, j = i[o], j[o]
        t, start, cnt = np.unique(j, return_index=True, return_counts=True)
        one = cnt == 1
        u = np.empty(len(t), dtype=object)
        u[one] = shapely.union(polys[t[one]], polys[i[start[one]]])
        for q in np.flatnonzero(~one):
            u[q] = shapely.union_all(np.r_[polys[t[q] : t[q] + 1], polys[i[start[q] : start[q] + cnt[q]]]])
        # the parts' area and outline, which their union keeps (pieces of a partition do not overlap)
        whole = area[t] + np.bincount(np.repeat(np.arange(len(t)), cnt), weights=area[i], minlength=len(t))
        outline = shapely.length(polys[t]) + np.bincount(
            np.repeat(np.arange(len(t)), cnt), weights=shapely.length(polys[i]), minlength=len(t)
        )
        # touching at a point only, or an overlay GEOS got wrong (area lost or gained): snap the shared edges
        bad = (shapely.get_type_id(u) != 3) | ~kept_area(u, whole, outline, touch)
        for q in np.flatnonzero(bad):  # the finest grid that makes one polygon moves the outline least
            parts = np.r_[polys[t[q] : t[q] + 1], polys[i[start[q] : start[q] + cnt[q]]]]
            u[q] = _snapped_union(parts, whole[q], outline[q], touch)
        good = (shapely.get_type_id(u) == 3) & shapely.is_valid(u) & kept_area(u, whole, outline, touch)
        out[t[good]] = u[good]
        took[t[good]] = True
        drop[i[np.repeat(good, cnt)]] = True
    keep = np.flatnonzero(~drop)
    return out[keep], keep, took[keep], int(drop.sum())
