"""Semi-detached pairs: two houses on neighbouring plots sharing one party wall.

Belgium's cadastre types its houses by how many of their sides stand free:
"open" (detached, four façades), "semi-closed" (semi-detached, three) and
"closed" (terraced, two).  In Wallonia's building stock of 2018, 38 % of
the buildings were detached houses, 28 % semi-detached and 31 % terraced
(Statbel [1]_): where houses stand on their own plots, nearly half of them
are built in pairs.

So the houses along a street are paired off: each plot's neighbours on
its left and right (across its side lot lines, seen from the street) are
found (:func:`side_neighbours`); neighbours that see each other so form a
chain along the street, ranked from its first plot by pointer jumping [2]_;
and the plots at even ranks pair with their right-hand neighbour, each pair
built semi-detached with a chance drawn from (seed, node id, the left plot's
id) (:func:`semi_pairs`).  A house of a pair stands on the side lot line it
shares with its partner and keeps its side setback on the other; corner
plots, which face two streets, stand alone.  ``buildings.massing`` pairs
its detached houses so with a chance of 0.7 (``semi_detached``): on whole
Liège's houses (``blocks.grain``'s ``rural`` and ``houses`` fabrics) 0.5
built 31 % of them in pairs, since the last plot of an odd chain, corner
plots and plots too narrow for a house stay single; Wallonia's 28 %
semi-detached against 38 % detached is 42 %.

References
----------
.. [1] Statbel (Belgian statistical office), "Building stock" (Parc des
   bâtiments), 1 January 2018, buildings by type for the Walloon Region.
.. [2] J. C. Wyllie, "The complexity of parallel computations", PhD thesis,
   Cornell University, 1979 (list ranking by pointer jumping).
"""

from __future__ import annotations

import numpy as np
import shapely

from .edges import SIDE, LotEdges
from .siting import left_hand

__all__ = ["side_neighbours", "semi_pairs"]

TOL = 0.01  #: m: a side line's midpoint this close to another lot lies on their common line


def side_neighbours(lots, edges: LotEdges) -> tuple[np.ndarray, np.ndarray]:
    """The lot across each lot's left and right side line (the longest one on that hand).

    Parameters
    ----------
    lots : array_like of shapely.Polygon (n,)
        Lots (m).
    edges : LotEdges
        Their tagged boundary segments (:func:`.edges.lot_edges`).

    Returns
    -------
    left, right : numpy.ndarray of int64 (n,)
        Row of the neighbouring lot on each hand, ``-1`` where there is none.
    """
    lots = np.asarray(lots, dtype=object)
    n = len(lots)
    left, right = np.full(n, -1, np.int64), np.full(n, -1, np.int64)
    side = np.flatnonzero(edges.kind == SIDE)
    if not len(side):
        return left, right
    hand = left_hand(edges, n)[side]
    mid = shapely.points(0.5 * (edges.p0[side] + edges.p1[side]))
    seg, other = shapely.STRtree(lots).query(mid, predicate="dwithin", distance=TOL)
    own = edges.lot[side][seg]
    keep = other != own
    seg, other, own = seg[keep], other[keep], own[keep]
    length = np.hypot(*(edges.p1[side] - edges.p0[side])[seg].T)
    for out, on_hand in ((left, hand[seg]), (right, ~hand[seg])):
        s = np.flatnonzero(on_hand)
        o = np.lexsort((-length[s], own[s]))  # per lot, its longest side segment on that hand first
        s = s[o]
        first = np.r_[True, own[s][1:] != own[s][:-1]] if len(s) else np.zeros(0, bool)
        out[own[s][first]] = other[s][first]
    return left, right


def semi_pairs(left, right, candidate, u_pair, chance: float) -> np.ndarray:
    """Which side line each house of a semi-detached pair stands on.

    Parameters
    ----------
    left, right : numpy.ndarray of int64 (n,)
        Neighbours across each lot's side lines (:func:`side_neighbours`).
    candidate : numpy.ndarray of bool (n,)
        Lots that may hold one house of a pair.
    u_pair : numpy.ndarray (n,)
        A uniform draw per lot, read at the left lot of each pair.
    chance : float
        The chance a pair is built semi-detached.

    Returns
    -------
    numpy.ndarray of str (n,)
        ``"right"`` for the left house of a pair (it stands on its right side
        line), ``"left"`` for its partner, ``""`` elsewhere.
    """
    n = len(left)
    idx = np.arange(n)
    right = np.asarray(right, np.int64)
    # a link i -> right[i] where both are candidates and see each other
    j = np.where(right >= 0, right, 0)
    linked = candidate & (right >= 0) & candidate[j] & (np.asarray(left)[j] == idx)
    pred = np.full(n, -1, np.int64)
    pred[right[linked]] = idx[linked]
    # rank along each chain from its first lot (list ranking by pointer jumping)
    rank = (pred >= 0).astype(np.int64)
    up = pred.copy()
    for _ in range(max(1, int(np.ceil(np.log2(max(n, 2))))) + 1):
        live = up >= 0
        if not live.any():
            break
        rank[live] += rank[up[live]]
        up[live] = up[up[live]]
    in_chain = up < 0  # a closed ring of neighbours (round a small block) never reaches a first lot
    first = linked & in_chain & (rank % 2 == 0) & (np.asarray(u_pair) < chance)
    out = np.full(n, "", dtype="<U5")
    out[first] = "right"
    out[right[first]] = "left"
    return out
