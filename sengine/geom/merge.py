"""Small pieces of a partition merged into a neighbour of the same group.

A polygon partition cut by clipping or splitting (lots of a block) can leave
slivers: pieces of (nearly) zero area where a cut runs through a corner.
:func:`merge_small` gives each piece under a threshold to the neighbour of
its group with which it shares the longest boundary, so the partition keeps
its area and loses the sliver.  Only the few small pieces and their
neighbours see a GEOS overlay.
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["merge_small"]

TOUCH = 1e-6  # m: pieces closer than this share boundary


def merge_small(polys, group, min_area, *, touch: float = TOUCH):
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

    Returns
    -------
    polys : ndarray of shapely.Polygon
        The pieces left, in their original order (a neighbour that took small
        pieces is replaced by the union).
    keep : ndarray of int64
        Index of each piece left into the input.
    merged : int
        Pieces merged away.  A small piece without a neighbour in its group
        (a whole small block), or whose union with every neighbour would not
        be one polygon, stays; a piece of zero area is dropped.
    """
    polys = np.asarray(polys, dtype=object).ravel()
    group = np.asarray(group, np.int64).ravel()
    k = len(polys)
    min_area = np.broadcast_to(np.asarray(min_area, np.float64), (k,))
    keep, merged = np.arange(k), 0
    for _ in range(4):  # a sliver whose best neighbour was merging itself goes in the next pass
        polys, kept, done = _merge_pass(polys, group[keep], min_area[keep], touch)
        keep, merged = keep[kept], merged + done
        if done == 0:
            break
    return polys, keep, merged


def _merge_pass(polys, group, min_area, touch):
    """One pass of :func:`merge_small`: each small piece into its best neighbour that is not merging away."""
    k = len(polys)
    area = shapely.area(polys)
    small = np.flatnonzero(area < min_area)
    if len(small) == 0:
        return polys, np.arange(k), 0
    tree = shapely.STRtree(polys)
    si, nj = tree.query(polys[small], predicate="dwithin", distance=touch)
    i = small[si]
    ok = (group[i] == group[nj]) & (i != nj)
    i, j = i[ok], nj[ok]
    # the neighbour sharing the longest boundary; a larger piece wins a tie, small ones come last
    shared = shapely.length(shapely.intersection(shapely.boundary(polys[i]), shapely.buffer(polys[j], touch)))
    big_j = area[j] >= min_area[j]
    o = np.lexsort((-area[j], -shared, ~big_j, i))
    i, j, shared = i[o], j[o], shared[o]
    first = np.r_[True, i[1:] != i[:-1]] if len(i) else np.zeros(0, bool)
    i, j, shared = i[first], j[first], shared[first]
    # a small piece merges into a piece that is not itself merging away (no chains)
    into = np.full(k, -1, np.int64)
    sel = (shared > 0) & ~np.isin(j, i)
    into[i[sel]] = j[sel]
    drop = np.zeros(k, bool)
    drop[small[area[small] <= 0]] = True  # nothing to give: no overlay needed
    out = polys.copy()
    take = np.flatnonzero((into >= 0) & ~drop)
    for t in np.unique(into[take]):  # few: slivers are rare
        mine = take[into[take] == t]
        u = shapely.union_all(np.r_[out[t : t + 1], polys[mine]])
        if shapely.get_type_id(u) != 3:  # touching at a point only: snap the shared edges
            u = shapely.union_all(np.r_[out[t : t + 1], polys[mine]], grid_size=touch)
        if shapely.get_type_id(u) == 3 and shapely.is_valid(u):
            out[t] = u
            drop[mine] = True
    keep = np.flatnonzero(~drop)
    return out[keep], keep, int(drop.sum())
